"""Real motion on anny bodies: retarget mocap (CMU ASF/AMC, BVH) onto anny's skeleton.

The method is bone-direction alignment. For every *driven* anny bone (:data:`DRIVEN`) a
mocap segment drives it (:data:`RIG_DRIVERS`): the bone's world rotation at frame ``t`` is

    G = R_mocap(t) @ C,    C = the smallest rotation taking the anny bone's reference
                               direction onto the mocap segment's rest direction,

where ``R_mocap(t)`` is the mocap segment's rest-relative global rotation
(:attr:`rmpl.synth.motion.Motion.rotations`). Then ``G`` maps the anny bone's direction
exactly onto the mocap bone's direction at frame ``t`` (parent to child), and the twist about
the bone comes from the mocap segment's own rotation. Bones without a direction (the root,
the head) take ``C = I``: both rigs stand upright facing -y in their rest poses. Undriven
bones (twist bones, fingers, toes, eyes) keep the identity relative to their parent.
anny's ``"local-ref"`` deltas are then ``D = G_parent^T G`` (the root's delta is ``G``),
because in that parameterisation a bone's world rotation is its parent's times its delta.

Note the *reference* pose of anny (identity deltas) differs from its ``rest_bone_heads``
by up to ~1 cm per bone; bone directions are taken from the reference pose
(:func:`reference_heads`), which makes the alignment exact.

Augmentations: :func:`mirror_pose` (swap .L/.R bones, reflect x) and :func:`perturb_pose`
(small random rotations of the driven bones). :func:`implausible` flags poses whose legs or
forearms pass through each other (a cheap self-intersection test on the regressed joints).

Shape glossary: ``B`` bodies, ``T`` frames, ``N`` poses, ``P`` anny bones (104),
``K`` driven bones (``len(DRIVEN)``).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17

__all__ = [
    "DRIVEN",
    "RIG_DRIVERS",
    "PoseBank",
    "mocap_drivers",
    "min_rotation",
    "anny_deltas",
    "reference_heads",
    "mirror_pose",
    "perturb_pose",
    "implausible",
    "build_pose_bank",
    "load_pose_bank",
    "save_pose_bank",
    "anny_pose_set",
]

_log = logging.getLogger(__name__)


def _sides(items: list[tuple[str, str | None]]) -> list[tuple[str, str | None]]:
    out = []
    for side in (".L", ".R"):
        out += [(b + side, None if t is None else t + side) for b, t in items]
    return out


#: Driven anny bones and the anny bone whose head gives their direction (None: no direction).
DRIVEN: tuple[tuple[str, str | None], ...] = tuple(
    [("root", None)]
    + _sides(
        [
            ("upperleg01", "lowerleg01"),
            ("lowerleg01", "foot"),
            ("foot", "toe3-1"),
            ("clavicle", "upperarm01"),
            ("upperarm01", "lowerarm01"),
            ("lowerarm01", "wrist"),
            ("wrist", "finger3-1"),
        ]
    )
    + [
        ("spine05", "spine04"),
        ("spine04", "spine03"),
        ("spine03", "spine02"),
        ("spine02", "spine01"),
        ("spine01", "neck01"),
        ("neck01", "neck02"),
        ("neck02", "neck03"),
        ("neck03", "head"),
        ("head", None),
    ]
)


def _rig(limbs: dict[str, tuple[str, str]], trunk: dict[str, tuple[str, str | None]]):
    """Driver table of a rig: anny bone -> (mocap joint, mocap tip joint or None)."""
    out: dict[str, tuple[str, str | None]] = dict(trunk)
    for bone, (joint, tip) in limbs.items():
        for side, prefix in ((".L", "l"), (".R", "r")):
            out[bone + side] = (joint.format(s=prefix), tip.format(s=prefix))
    return out


#: anny bone -> (mocap segment joint, joint at the segment's far end or None), per rig of
#: :data:`rmpl.synth.motion.COCO_MAPS`. ``{s}`` is "l" or "r".
RIG_DRIVERS: dict[str, dict[str, tuple[str, str | None]]] = {
    "cmu": _rig(
        {
            "upperleg01": ("{s}femur", "{s}tibia"),
            "lowerleg01": ("{s}tibia", "{s}foot"),
            "foot": ("{s}foot", "{s}toes"),
            "clavicle": ("{s}clavicle", "{s}humerus"),
            "upperarm01": ("{s}humerus", "{s}radius"),
            "lowerarm01": ("{s}radius", "{s}hand"),
            "wrist": ("{s}hand", "{s}fingers"),
        },
        {
            "root": ("root", None),  # joint 0, "root" in ASF, "hip" in the CMU BVH
            "spine05": ("lowerback", "upperback"),
            "spine04": ("lowerback", "upperback"),
            "spine03": ("upperback", "thorax"),
            "spine02": ("upperback", "thorax"),
            "spine01": ("thorax", "lowerneck"),
            "neck01": ("lowerneck", "upperneck"),
            "neck02": ("upperneck", "head"),
            "neck03": ("upperneck", "head"),
            "head": ("head", None),
        },
    ),
    "daz": _rig(
        {
            "upperleg01": ("{s}Thigh", "{s}Shin"),
            "lowerleg01": ("{s}Shin", "{s}Foot"),
            "foot": ("{s}Foot", "{s}Foot_end"),
            "clavicle": ("{s}Collar", "{s}Shldr"),
            "upperarm01": ("{s}Shldr", "{s}ForeArm"),
            "lowerarm01": ("{s}ForeArm", "{s}Hand"),
            "wrist": ("{s}Hand", "{s}Mid1"),
        },
        {
            "root": ("hip", None),
            "spine05": ("abdomen", "chest"),
            "spine04": ("abdomen", "chest"),
            "spine03": ("abdomen", "chest"),
            "spine02": ("chest", "neck"),
            "spine01": ("chest", "neck"),
            "neck01": ("neck", "head"),
            "neck02": ("neck", "head"),
            "neck03": ("neck", "head"),
            "head": ("head", None),
        },
    ),
}


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit direction ``a`` onto unit direction ``b``.

    Args:
        a, b: unit vectors, shape (*, 3).

    Returns:
        Rotations, shape (*, 3, 3); opposite directions turn by 180 degrees about an axis
        perpendicular to ``a``.

    >>> R = min_rotation(np.array([1.0, 0, 0]), np.array([0.0, 1, 0]))
    >>> np.round(R @ [1.0, 0, 0], 6).tolist()
    [0.0, 1.0, 0.0]
    """
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1)[..., None, None]
    vx = np.zeros((*v.shape[:-1], 3, 3))
    vx[..., 0, 1], vx[..., 0, 2], vx[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    vx[..., 1, 0], vx[..., 2, 0], vx[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    eye = np.eye(3)
    R = eye + vx + vx @ vx / np.maximum(1.0 + c, 1e-12)
    opposite = c[..., 0, 0] < -1.0 + 1e-9
    if np.any(opposite):
        ao = a[opposite]
        helper = np.where(np.abs(ao[:, :1]) < 0.9, [[1.0, 0, 0]], [[0.0, 1, 0]])
        axis = _unit(np.cross(ao, helper))
        R[opposite] = 2 * axis[:, :, None] * axis[:, None, :] - eye  # 180 degrees
    return R


def mocap_drivers(motion, rig: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The mocap rotations that drive anny's :data:`DRIVEN` bones.

    Args:
        motion: a :class:`rmpl.synth.motion.Motion`.
        rig: key of :data:`RIG_DRIVERS`; default from the joint names.

    Returns:
        rotations (T, K, 3, 3): rest-relative global rotations of the driving segments;
        rest directions (K, 3): unit direction of each driving segment in the mocap rest
        pose, zero for bones without a direction.
    """
    from rmpl.synth.motion import detect_rig

    rig = rig or detect_rig(motion.names)
    if rig not in RIG_DRIVERS:
        raise ValueError(f"{motion.source}: no anny retargeting for rig {rig!r}")
    table = RIG_DRIVERS[rig]
    rots, dirs = [], []
    for bone, _ in DRIVEN:
        joint, tip = table[bone]
        j = 0 if bone == "root" else motion.index(joint)  # the root is joint 0, any name
        rots.append(motion.rotations[:, j])
        if tip is None:
            dirs.append(np.zeros(3))
        else:
            dirs.append(_unit(motion.rest[motion.index(tip)] - motion.rest[j]))
    return np.stack(rots, axis=1), np.stack(dirs)


def reference_heads(body_model, phenotypes: np.ndarray) -> np.ndarray:
    """Bone heads of anny's reference pose (identity deltas), shape (B, P, 3), metres.

    Args:
        body_model: a :class:`rmpl.synth.body.BodyModel`.
        phenotypes: shape (B, 6).
    """
    import torch

    model = body_model._model
    B = len(phenotypes)
    as_t = dict(device=body_model._device, dtype=body_model._dtype)
    with torch.no_grad():
        out = model(
            torch.as_tensor(body_model.identity_pose(B), **as_t),
            torch.as_tensor(np.asarray(phenotypes, float), **as_t),
        )
    return out["bone_poses"][..., :3, 3].double().cpu().numpy()


def _bone_tables(bone_names: Sequence[str], parents: Sequence[int]):
    index = {n: i for i, n in enumerate(bone_names)}
    missing = [b for b, t in DRIVEN if b not in index or (t is not None and t not in index)]
    if missing:
        raise ValueError(f"anny skeleton lacks bones {missing}")
    parents = np.asarray(parents)
    if parents[0] != -1 or np.any(parents[1:] >= np.arange(1, len(parents))):
        raise ValueError("anny bones must list parents before children, root first")
    return index, parents


def anny_deltas(
    rotations: np.ndarray,
    rest_dirs: np.ndarray,
    ref_heads: np.ndarray,
    bone_names: Sequence[str],
    parents: Sequence[int],
) -> np.ndarray:
    """anny ``"local-ref"`` rotation deltas that put each driven bone along its mocap bone.

    Args:
        rotations: mocap driver rotations, shape (B, K, 3, 3) (see :func:`mocap_drivers`).
        rest_dirs: mocap rest directions, shape (B, K, 3) or (K, 3); zero rows mean
            "no direction" (the correction is the identity).
        ref_heads: anny reference-pose bone heads, shape (B, P, 3) (:func:`reference_heads`).
        bone_names: anny bone names, length P. parents: parent index per bone, root -1.

    Returns:
        Deltas, shape (B, P, 3, 3).
    """
    index, parents = _bone_tables(bone_names, parents)
    B, P = ref_heads.shape[:2]
    rest_dirs = np.broadcast_to(rest_dirs, (B, len(DRIVEN), 3))
    G = np.broadcast_to(np.eye(3), (B, P, 3, 3)).copy()
    driven = np.zeros(P, bool)
    for k, (bone, tip) in enumerate(DRIVEN):
        i = index[bone]
        C = np.broadcast_to(np.eye(3), (B, 3, 3))
        if tip is not None:
            a = _unit(ref_heads[:, index[tip]] - ref_heads[:, i])
            b = rest_dirs[:, k]
            has = np.linalg.norm(b, axis=-1) > 0.5
            C = np.where(has[:, None, None], min_rotation(a, np.where(has[:, None], b, a)), C)
        G[:, i] = rotations[:, k] @ C
        driven[i] = True
    for i in range(1, P):  # parents come first: undriven bones follow their parent
        if not driven[i]:
            G[:, i] = G[:, parents[i]]
    D = np.swapaxes(G[:, parents[1:]], -1, -2) @ G[:, 1:]
    return np.concatenate([G[:, :1], D], axis=1)


def mirror_pose(pose: np.ndarray, bone_names: Sequence[str]) -> np.ndarray:
    """Left/right mirror of anny deltas: swap ``.L``/``.R`` bones and reflect in x.

    anny's rest skeleton is symmetric about x = 0 and its deltas are in world-aligned axes,
    so the mirrored delta of bone ``b`` is ``S D_b' S`` with ``b'`` its other-side twin and
    ``S = diag(-1, 1, 1)``.

    Args:
        pose: deltas, shape (B, P, 3, 3).

    Returns:
        Same shape; ``mirror_pose(mirror_pose(p)) == p``.
    """
    index = {n: i for i, n in enumerate(bone_names)}
    perm = np.arange(len(bone_names))
    for i, n in enumerate(bone_names):
        for a, b in ((".L", ".R"), (".R", ".L")):
            if n.endswith(a) and n[: -len(a)] + b in index:
                perm[i] = index[n[: -len(a)] + b]
    S = np.diag([-1.0, 1.0, 1.0])
    return S @ pose[:, perm] @ S


def perturb_pose(
    pose: np.ndarray,
    bone_names: Sequence[str],
    rng: np.random.Generator,
    degrees: float,
) -> np.ndarray:
    """Small random rotations (axis uniform, angle ~ N(0, degrees)) of the driven bones.

    Args:
        pose: deltas, shape (B, P, 3, 3).

    Returns:
        Perturbed deltas, same shape. The root is left alone (its turn is random anyway).
    """
    from rmpl.geometry.camera import rodrigues

    if degrees <= 0:
        return pose
    pose = pose.copy()
    idx = [bone_names.index(b) for b, _ in DRIVEN if b != "root"]
    axis = _unit(rng.standard_normal((len(pose), len(idx), 3)))
    angle = np.radians(degrees) * rng.standard_normal((len(pose), len(idx), 1))
    pose[:, idx] = rodrigues(axis * angle) @ pose[:, idx]
    return pose


# COCO-17 segments for the self-intersection test, and the pairs that must not cross.
_SEGMENTS = {
    "l_thigh": (11, 13),
    "r_thigh": (12, 14),
    "l_shank": (13, 15),
    "r_shank": (14, 16),
    "l_forearm": (7, 9),
    "r_forearm": (8, 10),
}
_CROSSING = [
    ("l_thigh", "r_thigh", 0.08),
    ("l_shank", "r_shank", 0.06),
    ("l_thigh", "r_shank", 0.07),
    ("r_thigh", "l_shank", 0.07),
    ("l_forearm", "r_forearm", 0.04),
]


def _segment_distance(a0, a1, b0, b1) -> np.ndarray:
    """Closest distance between segments a0-a1 and b0-b1, shapes (B, 3) -> (B,)."""
    u, v, w = a1 - a0, b1 - b0, a0 - b0
    a, b, c = (u * u).sum(-1), (u * v).sum(-1), (v * v).sum(-1)
    d, e = (u * w).sum(-1), (v * w).sum(-1)
    den = np.maximum(a * c - b * b, 1e-12)
    s = np.clip((b * e - c * d) / den, 0, 1)
    t = np.clip((b * s + e) / np.maximum(c, 1e-12), 0, 1)
    s = np.clip((b * t - d) / np.maximum(a, 1e-12), 0, 1)
    return np.linalg.norm(w + s[:, None] * u - t[:, None] * v, axis=-1)


def implausible(keypoints: np.ndarray) -> np.ndarray:
    """Poses whose legs or forearms pass through each other, or with non-finite joints.

    A cheap self-intersection test on the regressed COCO-17 joints: the centre lines of the
    left and right thighs/shanks (and forearms) must stay further apart than about two limb
    radii.

    Args:
        keypoints: COCO-17 joints, shape (B, 17, 3), metres.

    Returns:
        Bool, shape (B,): True = reject.
    """
    bad = ~np.isfinite(keypoints).all(axis=(1, 2))
    k = np.nan_to_num(keypoints)
    for a, b, limit in _CROSSING:
        (i0, i1), (j0, j1) = _SEGMENTS[a], _SEGMENTS[b]
        bad |= _segment_distance(k[:, i0], k[:, i1], k[:, j0], k[:, j1]) < limit
    return bad


# ----------------------------------------------------------------------------- pose bank

_BANK_FORMAT = "rmpl.anny_pose_bank.v1"


@dataclass(frozen=True, eq=False)
class PoseBank:
    """Mocap frames ready to retarget onto anny.

    Attributes:
        rotations: driver rotations, shape (N, K, 3, 3), float32.
        rest_dirs: driver rest directions, shape (N, K, 3), float32.
        joints: the mocap's own COCO-17 joints, metres, z up, shape (N, 17, 3).
        subject, clip: ids per pose, shape (N,) str. frame: source frame, shape (N,) int.
    """

    rotations: np.ndarray
    rest_dirs: np.ndarray
    joints: np.ndarray
    subject: np.ndarray
    clip: np.ndarray
    frame: np.ndarray

    def __len__(self) -> int:
        return len(self.rotations)


def build_pose_bank(
    root: str | Path,
    subjects: Sequence[str] | None = None,
    exclude_subjects: Sequence[str] = (),
    fps: float = 10.0,
    min_move: float = 0.05,
) -> PoseBank:
    """Read every clip under ``root`` (ASF/AMC and BVH) into a :class:`PoseBank`.

    Frames are the clean ones (:func:`rmpl.synth.motion.usable_frames`), on a grid of
    ``fps`` per second, and a frame is kept only when some joint (pelvis-centred) moved at
    least ``min_move`` metres since the previous kept frame, so consecutive samples are not
    near-duplicates.

    Args:
        root: folder of motion files. subjects: keep only these subject ids (None = all).
        exclude_subjects: drop these subject ids (e.g. the held-out ``"03"``).
    """
    from rmpl.synth.motion import BROKEN_CLIPS, find_clips, to_coco17, usable_frames
    from rmpl.synth.motion.bank import _load_clip, _matches, _sample

    clips = [
        c
        for c in find_clips(root, subjects)
        if c.subject not in set(exclude_subjects) and not _matches(c.clip, BROKEN_CLIPS)
    ]
    if not clips:
        raise InputError(root, "poses", "motion clips of the selected subjects", "none")
    parts, skeletons = [], {}
    for c in clips:
        motion = _load_clip(c, skeletons)
        keep = usable_frames(motion)
        if not keep.any():
            continue
        coco = to_coco17(motion)
        idx = _sample(coco, keep, motion.fps, fps, min_move)
        if not len(idx):
            continue
        rot, dirs = mocap_drivers(motion)
        n = len(idx)
        parts.append(
            (
                rot[idx].astype(np.float32),
                np.broadcast_to(dirs, (n, *dirs.shape)).astype(np.float32),
                coco[idx].astype(np.float32),
                np.full(n, c.subject),
                np.full(n, c.clip),
                idx.astype(np.int64),
            )
        )
    if not parts:
        raise InputError(root, "poses", "clips with usable frames", "none")
    bank = PoseBank(*(np.concatenate(a) for a in zip(*parts, strict=True)))
    _log.info("pose bank %s: %d poses from %d clips", root, len(bank), len(parts))
    return bank


def save_pose_bank(path: str | Path, bank: PoseBank) -> Path:
    """Write a :class:`PoseBank` to ``.npz`` atomically."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(
            f,
            format=np.array(_BANK_FORMAT),
            rotations=bank.rotations,
            rest_dirs=bank.rest_dirs,
            joints=bank.joints,
            subject=bank.subject.astype(str),
            clip=bank.clip.astype(str),
            frame=bank.frame,
        )
    return path


def load_pose_bank(path: str | Path) -> PoseBank:
    """Read a bank written by :func:`save_pose_bank`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["format"]) != _BANK_FORMAT:
                raise InputError(path, "format", repr(_BANK_FORMAT), z["format"])
            return PoseBank(
                *(z[k] for k in ("rotations", "rest_dirs", "joints", "subject", "clip", "frame"))
            )
    except (OSError, KeyError, ValueError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(path, None, "an anny pose bank .npz", e) from None


def bone_parents(body_model) -> list[int]:
    """anny's parent index per bone (root -1) of a :class:`rmpl.synth.body.BodyModel`."""
    return [int(p) for p in body_model._model.bone_parents]


def retarget(
    body_model,
    bank: PoseBank,
    idx: np.ndarray,
    phenotypes: np.ndarray,
) -> np.ndarray:
    """anny deltas (B, P, 3, 3) for bank poses ``idx`` (B,) on bodies of ``phenotypes``."""
    ref = reference_heads(body_model, phenotypes)
    return anny_deltas(
        bank.rotations[idx].astype(float),
        bank.rest_dirs[idx].astype(float),
        ref,
        body_model.bone_names,
        bone_parents(body_model),
    )


COCO_LIMBS: tuple[tuple[int, int], ...] = tuple(
    (COCO17.index(a), COCO17.index(b))
    for a, b in (
        ("left_shoulder", "left_elbow"),
        ("left_elbow", "left_wrist"),
        ("right_shoulder", "right_elbow"),
        ("right_elbow", "right_wrist"),
        ("left_hip", "left_knee"),
        ("left_knee", "left_ankle"),
        ("right_hip", "right_knee"),
        ("right_knee", "right_ankle"),
    )
)
"""COCO-17 limb bones (parent, child) on which retargeting is checked."""


def limb_angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between the limb directions (:data:`COCO_LIMBS`) of two COCO-17
    pose arrays, shapes (B, 17, 3) -> (B, 8)."""
    da = _unit(np.stack([a[:, j] - a[:, i] for i, j in COCO_LIMBS], 1))
    db = _unit(np.stack([b[:, j] - b[:, i] for i, j in COCO_LIMBS], 1))
    return np.degrees(np.arccos(np.clip((da * db).sum(-1), -1, 1)))


def anny_pose_set(
    bank: PoseBank, body_model, seed: int = 0, batch: int = 256, progress: bool = False
):
    """Every pose of ``bank`` on a random anny body: a :class:`~rmpl.synth.motion.PoseSet`
    of ``body_model``'s joints (HALPE-26 with ``BodyModel(joints="halpe26")``), so that
    the parametric training source's 3D targets come from the same mesh definitions as the
    MHP renders'. Bodies are adult to old phenotypes (:func:`rmpl.synth.body
    .sample_phenotypes`), one per pose; joints in anny's frame (z up, metres), which
    :func:`rmpl.data.synthetic.place_poses` stands on the floor.
    """
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.motion import PoseSet

    rng = np.random.default_rng(seed)
    phen = sample_phenotypes(len(bank), rng)
    out = []
    starts = range(0, len(bank), batch)
    if progress:
        from tqdm import tqdm

        starts = tqdm(starts, desc="anny", unit="batch")
    for i in starts:
        idx = np.arange(i, min(i + batch, len(bank)))
        deltas = retarget(body_model, bank, idx, phen[idx])
        out.append(body_model(deltas, phen[idx]).keypoints.astype(np.float32))
    return PoseSet(np.concatenate(out), bank.subject, bank.clip, bank.frame)
