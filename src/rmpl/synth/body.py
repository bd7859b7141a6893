"""Posed human bodies for MHP, from the Anny parametric body model.

Anny (``pip install anny==0.6.2``, Apache-2.0 code, CC0 MakeHuman assets) is a PyTorch body
model with MakeHuman's phenotypes and rig. What rmpl relies on, checked on anny 0.6.2:

- Units and axes: metres, **z up**, right-handed, the same as rmpl's world. The body faces
  **-y**, its left side is **+x**. The origin is the ``root`` bone (the pelvis, ~0.9 m above
  the soles for an average adult); :func:`place_bodies` puts bodies on the floor (z = 0).
- Mesh: 13,718 vertices and 27,420 triangles (``faces``, shared by all bodies).
- Rig: 104 bones (``BodyModel.bone_names``): ``root``; per side (``.L``/``.R``) ``pelvis``,
  ``upperleg01/02`` (hip; 02 is a twist bone), ``lowerleg01/02`` (knee), ``foot`` (ankle),
  toes ``toe1-1`` .. ``toe5-3``, ``clavicle``, ``shoulder01``, ``upperarm01/02`` (shoulder),
  ``lowerarm01/02`` (elbow), ``wrist``, ``metacarpal1-4``, ``finger1-1`` .. ``finger5-3``;
  the spine ``spine05`` (lowest) .. ``spine01``, ``neck01`` .. ``neck03``, ``head``,
  ``eye.L``, ``eye.R``. The rest pose is an A-pose (arms ~45 degrees down).
- Pose parameters: a (B, 104, 4, 4) stack of homogeneous **delta** transforms, one per
  bone, in anny's default ``"local-ref"`` parameterisation: each bone's rotation is relative
  to its parent and expressed in **world-aligned axes of the rest pose** (so "rotate the left
  knee by +a about +x" flexes it whatever the bone's own axes), about the bone's head. The
  root's delta is its world pose. Identity deltas give the rest pose.
- Phenotypes, each in [0, 1] (:data:`PHENOTYPES`): gender (0 male, 1 female), age (0 baby,
  1/3 child, 2/3 young adult, 1 old), muscle, weight, height, proportions.
- Keypoints: ``anny.KeypointsRegressor.coco`` regresses 23 keypoints linearly from the
  vertices; the first 17 are COCO-17 in rmpl's order, then the big toe, small toe and heel
  of each foot (left, right), HALPE-26's order. :class:`BodyModel` with
  ``joints="halpe26"`` adds HALPE-26's other three points, defined on the mesh and rig:

  - ``head_top``: the top of the skull, the head vertex highest above the eyes in the
    rest pose (:attr:`BodyModel.head_top_vertex`, a fixed vertex index: anny's topology
    is shared by every body), posed with the mesh;
  - ``neck``: the head of anny's ``neck01`` bone, the base of the neck (about C7),
    posed with the rig;
  - ``mid_hip``: the midpoint of the two regressed hip keypoints (the pelvis, as HALPE's
    Hip and BODY_25's MidHip are annotated).

The first ``anny.Anny()`` builds a ~790 MB cache (about 1-4 minutes); point
``ANNY_CACHE_DIR`` (or ``cache_dir``) somewhere persistent.

Shape glossary: ``B`` bodies, ``N`` vertices (13,718), ``F`` faces, ``J`` joints, ``P`` bones.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.geometry.camera import rodrigues
from rmpl.skeleton import HALPE26

__all__ = [
    "PHENOTYPES",
    "PARTS",
    "JOINT_SETS",
    "Bodies",
    "BodyModel",
    "sample_phenotypes",
    "place_bodies",
]

#: Anny's phenotype parameters, in the column order :class:`BodyModel` expects.
PHENOTYPES: tuple[str, ...] = ("gender", "age", "muscle", "weight", "height", "proportions")

#: Body parts of :attr:`BodyModel.vertex_parts`, for clothing and skin colours.
PARTS: tuple[str, ...] = (
    "face",
    "hair",
    "eye",
    "neck",
    "torso",
    "upper_arm",
    "lower_arm",
    "hand",
    "upper_leg",
    "lower_leg",
    "foot",
)

_NUM_COCO = 17
#: Joint sets :class:`BodyModel` returns.
JOINT_SETS = ("coco17", "halpe26")


@dataclass(frozen=True)
class Bodies:
    """A batch of posed bodies.

    Attributes:
        vertices: shape (B, N, 3), float32, metres.
        faces: triangle vertex indices, shape (F, 3), int32, shared by the batch.
        keypoints: the model's joints (``BodyModel.joints``: COCO-17, or HALPE-26 whose
            first 17 are COCO-17), shape (B, J, 3), metres.
    """

    vertices: np.ndarray
    faces: np.ndarray
    keypoints: np.ndarray


def sample_phenotypes(
    num: int, rng: np.random.Generator | int | None = None, min_age: float = 0.5
) -> np.ndarray:
    """Random adult-to-old phenotypes, shape (num, 6), columns in :data:`PHENOTYPES` order.

    Gender and proportions are uniform; age is uniform in ``[min_age, 1]`` (0.5 is a
    teenager, 2/3 a young adult); muscle, weight and height are Beta(2, 2) so extremes are
    rarer than average builds.

    >>> p = sample_phenotypes(5, rng=0)
    >>> p.shape, bool(((p >= 0) & (p <= 1)).all())
    ((5, 6), True)
    """
    if not 0.0 <= min_age <= 1.0:
        raise ValueError(f"min_age must be in [0, 1], got {min_age}")
    rng = np.random.default_rng(rng)
    out = np.empty((num, len(PHENOTYPES)))
    out[:, 0] = rng.uniform(0, 1, num)  # gender
    out[:, 1] = rng.uniform(min_age, 1, num)  # age
    out[:, 2:5] = rng.beta(2, 2, (num, 3))  # muscle, weight, height
    out[:, 5] = rng.uniform(0, 1, num)  # proportions
    return out


def place_bodies(
    vertices: np.ndarray,
    keypoints: np.ndarray,
    yaw: np.ndarray,
    position: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Turn bodies about the vertical, stand them on the floor and move them.

    Args:
        vertices: shape (B, N, 3), metres, anny's frame (z up).
        keypoints: COCO-17, shape (B, 17, 3), same frame.
        yaw: rotation about +z, shape (B,), radians.
        position: where the mid-hip lands on the floor plane, shape (B, 2), metres.

    Returns:
        vertices (B, N, 3) and keypoints (B, 17, 3) with the lowest vertex at z = 0.

    >>> v = np.array([[[0.0, 0, -1], [0, 0, 1]]]); k = np.zeros((1, 17, 3))
    >>> v2, k2 = place_bodies(v, k, np.zeros(1), np.array([[2.0, 3.0]]))
    >>> v2[0, :, 2].tolist(), k2[0, 0].tolist()
    ([0.0, 2.0], [2.0, 3.0, 1.0])
    """
    yaw = np.asarray(yaw, dtype=float)
    c, s = np.cos(yaw), np.sin(yaw)
    zero, one = np.zeros_like(yaw), np.ones_like(yaw)
    Rz = np.stack(
        [np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)],
        -2,
    )  # (B, 3, 3)
    v = np.einsum("bij,bnj->bni", Rz, vertices)
    k = np.einsum("bij,bnj->bni", Rz, keypoints)
    mid_hip = k[:, 11:13].mean(axis=1)  # (B, 3) COCO hips
    shift = np.zeros((len(v), 1, 3))
    shift[:, 0, :2] = np.asarray(position, dtype=float) - mid_hip[:, :2]
    shift[:, 0, 2] = -v[..., 2].min(axis=1)
    return (v + shift).astype(vertices.dtype), (k + shift).astype(keypoints.dtype)


# A random-pose degree of freedom: a hinge turning the bone's rest direction towards a world
# direction, by an angle drawn in [lo, hi] degrees.
_FORWARD, _BACK, _UP, _LEFT = (0, -1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0)
_RIGHT = (-1, 0, 0)
_SPINE = ("spine05", "spine04", "spine03", "spine02", "spine01")
_NECK = ("neck01", "neck02", "neck03", "head")


def _limb_dofs() -> list[tuple[str, str, tuple[int, int, int], float, float]]:
    """(bone, child bone giving its direction, towards, lo, hi) per hinge."""
    dofs = []
    for side, out in ((".L", _LEFT), (".R", _RIGHT)):
        dofs += [
            (f"upperleg01{side}", f"lowerleg01{side}", _FORWARD, -25, 100),  # hip flexion
            (f"upperleg01{side}", f"lowerleg01{side}", out, -15, 45),  # hip abduction
            (f"lowerleg01{side}", f"foot{side}", _BACK, 0, 130),  # knee
            (f"foot{side}", f"toe3-1{side}", _UP, -25, 25),  # ankle
            (f"clavicle{side}", f"shoulder01{side}", _UP, -5, 20),
            (f"upperarm01{side}", f"lowerarm01{side}", _UP, -40, 130),  # shoulder abduction
            (f"upperarm01{side}", f"lowerarm01{side}", _FORWARD, -40, 110),  # shoulder flexion
            (f"lowerarm01{side}", f"wrist{side}", _FORWARD, 0, 140),  # elbow
            (f"wrist{side}", f"finger3-1{side}", _FORWARD, -40, 40),
        ]
    return dofs


def _twist_dofs() -> list[tuple[str, str, float]]:
    """(bone, child bone giving the twist axis, max |angle| in degrees)."""
    out = []
    for side in (".L", ".R"):
        out += [
            (f"upperleg01{side}", f"lowerleg01{side}", 30),
            (f"upperarm01{side}", f"lowerarm01{side}", 45),
        ]
    return out


# Trunk rotations about world axes, (lo, hi) degrees in total, shared over the bones:
# +x bends forward, +y bends to the body's left side (+x) and +z turns it to its left.
_TRUNK = {"spine": ((-20, 60), (-25, 25), (-35, 35)), "neck": ((-35, 45), (-25, 25), (-60, 60))}


def _quiet_warp() -> None:
    """Keep anny's skinning library (NVIDIA Warp) from printing its start-up banner and
    "no CUDA driver" (from its C library, to the process's stderr) on every CPU run: it
    logs errors only, and starts here with the stderr file descriptor silenced. anny's own
    log says warnings only."""
    import logging
    import os

    logging.getLogger("anny").setLevel(logging.WARNING)  # "Loading cached model data ..."
    try:
        import warp
        import warp.config
    except ImportError:
        return
    warp.config.log_level = 40
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            warp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)


class BodyModel:
    """Anny bodies: random phenotypes and poses in, vertices and COCO-17 keypoints out.

    Holds the (heavy) anny model; build it once and call it on batches.

    Args:
        cache_dir: anny's cache directory (else ``$ANNY_CACHE_DIR``, else ``~/.cache/anny``).
        device: torch device.
        dtype: ``"float32"`` or ``"float64"``.
        joints: the keypoints' joint set, one of :data:`JOINT_SETS` (see the module
            docstring for HALPE-26's definitions on the mesh).

    Example (not run here, needs ``rmpl[synth]``)::

        model = BodyModel(cache_dir=Path.home() / ".cache/rmpl/anny")
        pose = model.sample_poses(8, rng=0)
        bodies = model(pose, sample_phenotypes(8, rng=0))
    """

    def __init__(
        self,
        cache_dir: str | Path | None = None,
        device: str = "cpu",
        dtype: str = "float32",
        joints: str = "coco17",
    ) -> None:
        _quiet_warp()
        import anny
        import anny.paths
        import torch

        if cache_dir is not None:
            anny.paths.set_anny_cache_path(cache_dir)
        self._torch = torch
        if joints not in JOINT_SETS:
            raise ValueError(f"joints must be one of {JOINT_SETS}, got {joints!r}")
        self.joints = joints
        dtypes = {"float32": torch.float32, "float64": torch.float64}
        if dtype not in dtypes:
            raise ValueError(f"dtype must be one of {sorted(dtypes)}, got {dtype!r}")
        self._dtype = dtypes[dtype]
        self._device = torch.device(device)
        model = anny.Anny(phenotypes="default", pose_parameterization="local-ref")
        self._model = model.to(device=self._device, dtype=self._dtype).eval()
        labels = list(anny.KeypointsRegressor.coco(self._model).labels)
        feet = [n for n in HALPE26.joints[_NUM_COCO:] if n.endswith(("toe", "heel"))]
        if labels[_NUM_COCO:] != feet:  # _halpe26 joins them by position
            raise RuntimeError(f"unexpected anny keypoint labels {labels[_NUM_COCO:]}")
        labels = labels[:_NUM_COCO] if joints == "coco17" else labels
        self._regressor = anny.KeypointsRegressor.coco(self._model, labels=labels).to(
            device=self._device, dtype=self._dtype
        )
        if list(self._model.phenotype_labels) != list(PHENOTYPES):
            raise RuntimeError(f"unexpected anny phenotypes {self._model.phenotype_labels}")
        self.bone_names: tuple[str, ...] = tuple(self._model.bone_labels)
        self.faces: np.ndarray = self._model.get_triangular_faces().cpu().numpy().astype(np.int32)
        with torch.no_grad():
            rest = self._model()
        self._rest_heads = rest["rest_bone_heads"][0].double().cpu().numpy()  # (P, 3)
        self._rest_vertices = rest["rest_vertices"][0].double().cpu().numpy()  # (N, 3)
        self.vertex_parts: np.ndarray = self._segment()
        self.head_top_vertex: int = self._head_top()
        self._neck = self.bone_index("neck01")

    @property
    def num_bones(self) -> int:
        return len(self.bone_names)

    @property
    def num_vertices(self) -> int:
        return len(self.vertex_parts)

    def bone_index(self, name: str) -> int:
        try:
            return self.bone_names.index(name)
        except ValueError:
            raise KeyError(f"anny has no bone {name!r}") from None

    def __call__(self, pose: np.ndarray, phenotypes: np.ndarray) -> Bodies:
        """Pose bodies.

        Args:
            pose: anny ``"local-ref"`` delta transforms, shape (B, P, 4, 4) (see the module
                docstring), or rotations only, shape (B, P, 3, 3).
            phenotypes: shape (B, 6) in [0, 1], columns in :data:`PHENOTYPES` order.

        Returns:
            :class:`Bodies` in anny's frame (z up, metres, root at the origin unless the
            root delta moves it).
        """
        torch = self._torch
        pose = np.asarray(pose)
        phenotypes = np.asarray(phenotypes, dtype=float)
        if (
            pose.ndim != 4
            or pose.shape[1] != self.num_bones
            or pose.shape[2:]
            not in (
                (4, 4),
                (3, 3),
            )
        ):
            raise ValueError(
                f"pose must have shape (B, {self.num_bones}, 4, 4) or (B, {self.num_bones}, 3, 3)"
                f", got {pose.shape}"
            )
        if phenotypes.shape != (pose.shape[0], len(PHENOTYPES)):
            raise ValueError(
                f"phenotypes must have shape ({pose.shape[0]}, {len(PHENOTYPES)}), "
                f"got {phenotypes.shape}"
            )
        if pose.shape[2] == 3:
            full = np.zeros((*pose.shape[:2], 4, 4))
            full[..., :3, :3], full[..., 3, 3] = pose, 1.0
            pose = full
        as_t = dict(device=self._device, dtype=self._dtype)
        with torch.no_grad():
            out = self._model(torch.as_tensor(pose, **as_t), torch.as_tensor(phenotypes, **as_t))
            keypoints = self._regressor(out).float().cpu().numpy()
        vertices = out["vertices"].float().cpu().numpy()
        if self.joints == "halpe26":
            keypoints = self._halpe26(keypoints, vertices, out["bone_poses"])
        return Bodies(vertices=vertices, faces=self.faces, keypoints=keypoints)

    def _halpe26(self, regressed: np.ndarray, vertices: np.ndarray, bone_poses) -> np.ndarray:
        """HALPE-26 (B, 26, 3) from the regressor's 23 points, the mesh and the rig."""
        head_top = vertices[:, self.head_top_vertex]
        neck = bone_poses[:, self._neck, :3, 3].float().cpu().numpy()
        mid_hip = regressed[:, 11:13].mean(axis=1)
        extra = np.stack([head_top, neck, mid_hip], axis=1)
        return np.concatenate([regressed[:, :_NUM_COCO], extra, regressed[:, _NUM_COCO:]], 1)

    def _head_top(self) -> int:
        """The head vertex highest in the rest pose (the body is upright, z up)."""
        head = np.flatnonzero(
            np.isin(self.vertex_parts, [PARTS.index("face"), PARTS.index("hair")])
        )
        return int(head[np.argmax(self._rest_vertices[head, 2])])

    def identity_pose(self, num: int) -> np.ndarray:
        """The rest pose (identity deltas), shape (num, P, 4, 4)."""
        return np.broadcast_to(np.eye(4), (num, self.num_bones, 4, 4)).copy()

    def sample_poses(
        self,
        num: int,
        rng: np.random.Generator | int | None = None,
        activity: tuple[float, float] = (0.25, 1.0),
        support_leg: float = 0.7,
    ) -> np.ndarray:
        """Random plausible poses, a stand-in until mocap is retargeted onto anny.

        Each hinge (hips, knees, ankles, shoulders, elbows, wrists, clavicles) and the trunk
        and neck get an angle inside a range of motion; all angles of a body are scaled by
        one ``activity`` factor, so bodies range from nearly standing to extreme poses.
        With probability ``support_leg`` one leg is kept nearly straight (a standing or
        walking body); otherwise both legs are free. Joint limits are independent, so some
        poses interpenetrate.

        Returns:
            anny ``"local-ref"`` delta transforms, shape (num, P, 4, 4), float64.
        """
        rng = np.random.default_rng(rng)
        rot = np.broadcast_to(np.eye(3), (num, self.num_bones, 3, 3)).copy()
        scale = rng.uniform(*activity, (num, 1))
        heads = self._rest_heads

        def direction(bone: str, child: str) -> np.ndarray:
            d = heads[self.bone_index(child)] - heads[self.bone_index(bone)]
            return d / np.linalg.norm(d)

        def turn(bone: str, axis: np.ndarray, degrees: np.ndarray) -> None:
            axis = axis / np.linalg.norm(axis)
            R = rodrigues(np.radians(degrees)[:, None] * axis)  # (num, 3, 3)
            i = self.bone_index(bone)
            rot[:, i] = R @ rot[:, i]

        for bone, child, lim in _twist_dofs():
            turn(bone, direction(bone, child), scale[:, 0] * rng.uniform(-lim, lim, num))
        # Most bodies stand on one nearly straight leg; the others may crouch, kneel or jump.
        support = np.where(rng.uniform(size=num) < support_leg, rng.integers(0, 2, num), -1)
        for bone, child, towards, lo, hi in _limb_dofs():
            d = direction(bone, child)
            # Rotating about d x g by +a turns d towards g.
            axis = np.cross(d, np.asarray(towards, float))
            angle = scale[:, 0] * (lo + (hi - lo) * rng.beta(1.3, 1.3, num))
            if bone.startswith(("upperleg", "lowerleg")):
                side = 0 if bone.endswith(".L") else 1
                angle = np.where(support == side, 0.2 * angle, angle)
            turn(bone, axis, angle)
        for group, bones in (("spine", _SPINE), ("neck", _NECK)):
            for axis, (lo, hi) in zip(np.eye(3), _TRUNK[group], strict=True):
                total = scale[:, 0] * rng.uniform(lo, hi, num)
                for bone in bones:
                    turn(bone, axis, total / len(bones))
        pose = np.zeros((num, self.num_bones, 4, 4))
        pose[..., :3, :3], pose[..., 3, 3] = rot, 1.0
        return pose

    def _segment(self) -> np.ndarray:
        """Part index (into :data:`PARTS`) of every vertex, from its dominant bone."""
        w = self._model.vertex_bone_weights.cpu().numpy()
        idx = self._model.vertex_bone_indices.cpu().numpy()
        dominant = idx[np.arange(len(idx)), w.argmax(axis=1)]  # (N,)
        names = np.array(self.bone_names)[dominant]

        def has(*prefixes: str) -> np.ndarray:
            return np.array([n.startswith(prefixes) for n in names])

        parts = np.full(len(names), PARTS.index("torso"))
        parts[has("upperleg", "pelvis")] = PARTS.index("upper_leg")
        parts[has("lowerleg")] = PARTS.index("lower_leg")
        parts[has("foot", "toe")] = PARTS.index("foot")
        parts[has("upperarm", "shoulder")] = PARTS.index("upper_arm")
        parts[has("lowerarm")] = PARTS.index("lower_arm")
        parts[has("wrist", "finger", "metacarpal")] = PARTS.index("hand")
        parts[has("neck")] = PARTS.index("neck")
        head = has("head")
        parts[head] = PARTS.index("face")
        parts[has("eye")] = PARTS.index("eye")
        # Hair: head vertices above the brow, or behind the ears and above the nape.
        v = self._rest_vertices
        eye_z = self._rest_heads[self.bone_index("eye.L"), 2]
        back_y = v[head, 1].max() - 0.1  # ~10 cm in front of the back of the head
        hair = head & ((v[:, 2] > eye_z + 0.035) | ((v[:, 1] > back_y) & (v[:, 2] > eye_z - 0.05)))
        parts[hair] = PARTS.index("hair")
        return parts.astype(np.int8)
