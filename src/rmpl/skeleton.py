"""Joint sets as data: names, bones, left/right pairs, and conversions between them.

Every joint set is a :class:`Skeleton`. Conversions are linear maps (each output joint is a
weighted mean of input joints) so they broadcast over any leading dimensions and carry NaN
through: a derived joint is missing when any of its sources is missing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Skeleton",
    "COCO17",
    "H36M17",
    "SHELF14",
    "BODY25",
    "BODY25B",
    "BLAZEPOSE33",
    "HALPE26",
    "SKELETONS",
    "KP_STAR",
    "SHELF_LIMB_JOINTS",
    "convert",
    "conversion_matrix",
    "embed",
    "embed_scores",
    "EMBED_ALIASES",
    "skeleton_for",
    "to_model_joints",
    "to_joint_set",
    "BY_COUNT",
    "ANCHOR_PARENTS",
    "anchor_parents",
    "flip_left_right",
]


@dataclass(frozen=True)
class Skeleton:
    """A named joint set.

    Attributes:
        name: short identifier, the key in :data:`SKELETONS`.
        joints: joint names in order.
        bones: pairs of joint indices drawn as limbs.
        flip_pairs: pairs of (left, right) joint indices swapped by a mirror.
    """

    name: str
    joints: tuple[str, ...]
    bones: tuple[tuple[int, int], ...] = ()
    flip_pairs: tuple[tuple[int, int], ...] = ()
    _index: dict[str, int] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        self._index.update({n: i for i, n in enumerate(self.joints)})

    @property
    def num_joints(self) -> int:
        return len(self.joints)

    def index(self, name: str) -> int:
        """Index of the joint called ``name``."""
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"skeleton {self.name!r} has no joint {name!r}") from None

    def indices(self, names: tuple[str, ...] | list[str]) -> list[int]:
        return [self.index(n) for n in names]

    def flip_permutation(self) -> np.ndarray:
        """Index permutation that swaps left and right joints, shape (J,)."""
        perm = np.arange(self.num_joints)
        for a, b in self.flip_pairs:
            perm[a], perm[b] = b, a
        return perm


def _pairs(joints: tuple[str, ...], prefix_l: str = "left_", prefix_r: str = "right_"):
    out = []
    for i, n in enumerate(joints):
        if n.startswith(prefix_l):
            j = joints.index(prefix_r + n[len(prefix_l) :])
            out.append((i, j))
    return tuple(out)


def _bones(joints: tuple[str, ...], names: list[tuple[str, str]]):
    return tuple((joints.index(a), joints.index(b)) for a, b in names)


_COCO_NAMES = (
    "nose",
    "left_eye",
    "right_eye",
    "left_ear",
    "right_ear",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
COCO17 = Skeleton(
    "coco17",
    _COCO_NAMES,
    _bones(
        _COCO_NAMES,
        [
            ("left_ankle", "left_knee"),
            ("left_knee", "left_hip"),
            ("right_ankle", "right_knee"),
            ("right_knee", "right_hip"),
            ("left_hip", "right_hip"),
            ("left_shoulder", "left_hip"),
            ("right_shoulder", "right_hip"),
            ("left_shoulder", "right_shoulder"),
            ("left_shoulder", "left_elbow"),
            ("right_shoulder", "right_elbow"),
            ("left_elbow", "left_wrist"),
            ("right_elbow", "right_wrist"),
            ("left_eye", "right_eye"),
            ("nose", "left_eye"),
            ("nose", "right_eye"),
            ("left_eye", "left_ear"),
            ("right_eye", "right_ear"),
            ("left_ear", "left_shoulder"),
            ("right_ear", "right_shoulder"),
        ],
    ),
    _pairs(_COCO_NAMES),
)

_H36M_NAMES = (
    "pelvis",
    "right_hip",
    "right_knee",
    "right_ankle",
    "left_hip",
    "left_knee",
    "left_ankle",
    "torso",
    "neck",
    "nose",
    "head",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
)
H36M17 = Skeleton(
    "h36m17",
    _H36M_NAMES,
    _bones(
        _H36M_NAMES,
        [
            ("pelvis", "right_hip"),
            ("right_hip", "right_knee"),
            ("right_knee", "right_ankle"),
            ("pelvis", "left_hip"),
            ("left_hip", "left_knee"),
            ("left_knee", "left_ankle"),
            ("pelvis", "torso"),
            ("torso", "neck"),
            ("neck", "nose"),
            ("nose", "head"),
            ("neck", "left_shoulder"),
            ("left_shoulder", "left_elbow"),
            ("left_elbow", "left_wrist"),
            ("neck", "right_shoulder"),
            ("right_shoulder", "right_elbow"),
            ("right_elbow", "right_wrist"),
        ],
    ),
    _pairs(_H36M_NAMES),
)

_SHELF_NAMES = (
    "right_ankle",
    "right_knee",
    "right_hip",
    "left_hip",
    "left_knee",
    "left_ankle",
    "right_wrist",
    "right_elbow",
    "right_shoulder",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "neck",
    "head_top",
)
SHELF14 = Skeleton(
    "shelf14",
    _SHELF_NAMES,
    # The ten parts scored by PCP on Shelf/Campus, in the customary order.
    _bones(
        _SHELF_NAMES,
        [
            ("head_top", "neck"),
            ("right_shoulder", "right_elbow"),
            ("right_elbow", "right_wrist"),
            ("left_shoulder", "left_elbow"),
            ("left_elbow", "left_wrist"),
            ("right_hip", "right_knee"),
            ("right_knee", "right_ankle"),
            ("left_hip", "left_knee"),
            ("left_knee", "left_ankle"),
            ("neck", "right_hip"),
            ("neck", "left_hip"),
        ],
    ),
    _pairs(_SHELF_NAMES),
)

_BODY25_NAMES = (
    "nose",
    "neck",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "mid_hip",
    "right_hip",
    "right_knee",
    "right_ankle",
    "left_hip",
    "left_knee",
    "left_ankle",
    "right_eye",
    "left_eye",
    "right_ear",
    "left_ear",
    "left_big_toe",
    "left_small_toe",
    "left_heel",
    "right_big_toe",
    "right_small_toe",
    "right_heel",
)
BODY25 = Skeleton(
    "body25",
    _BODY25_NAMES,
    _bones(
        _BODY25_NAMES,
        [
            ("neck", "mid_hip"),
            ("neck", "right_shoulder"),
            ("right_shoulder", "right_elbow"),
            ("right_elbow", "right_wrist"),
            ("neck", "left_shoulder"),
            ("left_shoulder", "left_elbow"),
            ("left_elbow", "left_wrist"),
            ("mid_hip", "right_hip"),
            ("right_hip", "right_knee"),
            ("right_knee", "right_ankle"),
            ("mid_hip", "left_hip"),
            ("left_hip", "left_knee"),
            ("left_knee", "left_ankle"),
            ("neck", "nose"),
            ("nose", "right_eye"),
            ("nose", "left_eye"),
            ("right_eye", "right_ear"),
            ("left_eye", "left_ear"),
            ("left_ankle", "left_big_toe"),
            ("left_ankle", "left_heel"),
            ("right_ankle", "right_big_toe"),
            ("right_ankle", "right_heel"),
        ],
    ),
    _pairs(_BODY25_NAMES),
)

# OpenPose BODY_25B (the Pose2Sim default): COCO-17 order first, then the upper neck (just
# under the head: OpenPose's "UpperNeck", not HALPE-26's neck at the base of the neck, so it
# is not placed in that slot), the head top and the feet.
_BODY25B_NAMES = _COCO_NAMES + (
    "upper_neck",
    "head_top",
    "left_big_toe",
    "left_small_toe",
    "left_heel",
    "right_big_toe",
    "right_small_toe",
    "right_heel",
)
BODY25B = Skeleton("body25b", _BODY25B_NAMES, COCO17.bones, _pairs(_BODY25B_NAMES))

_BLAZE_NAMES = (
    "nose",
    "left_eye_inner",
    "left_eye",
    "left_eye_outer",
    "right_eye_inner",
    "right_eye",
    "right_eye_outer",
    "left_ear",
    "right_ear",
    "mouth_left",
    "mouth_right",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_pinky",
    "right_pinky",
    "left_index",
    "right_index",
    "left_thumb",
    "right_thumb",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
    "left_heel",
    "right_heel",
    "left_foot_index",
    "right_foot_index",
)
BLAZEPOSE33 = Skeleton("blazepose33", _BLAZE_NAMES, (), _pairs(_BLAZE_NAMES))

# HALPE-26 (AlphaPose; the Pose2Sim default with RTMPose): COCO-17 in COCO's order, then
# HALPE's Head (the top of the head), Neck and Hip (the pelvis, between the hips), then the
# feet. rmpl's lifter outputs this set; its first 17 joints are COCO-17, so ``[..., :17, :]``
# is the COCO-17 subset. Definitions on the body mesh: ``rmpl.synth.body``.
_HALPE_NAMES = _COCO_NAMES + (
    "head_top",
    "neck",
    "mid_hip",
    "left_big_toe",
    "right_big_toe",
    "left_small_toe",
    "right_small_toe",
    "left_heel",
    "right_heel",
)
HALPE26 = Skeleton(
    "halpe26",
    _HALPE_NAMES,
    COCO17.bones
    + _bones(
        _HALPE_NAMES,
        [
            ("head_top", "neck"),
            ("neck", "mid_hip"),
            ("left_ankle", "left_heel"),
            ("left_heel", "left_big_toe"),
            ("left_big_toe", "left_small_toe"),
            ("left_small_toe", "left_ankle"),
            ("right_ankle", "right_heel"),
            ("right_heel", "right_big_toe"),
            ("right_big_toe", "right_small_toe"),
            ("right_small_toe", "right_ankle"),
        ],
    ),
    _pairs(_HALPE_NAMES),
)

SKELETONS: dict[str, Skeleton] = {
    s.name: s for s in (COCO17, H36M17, SHELF14, BODY25, BODY25B, BLAZEPOSE33, HALPE26)
}

#: COCO-17 indices of the joints defined alike in COCO, Human3.6M and Shelf (thesis 6.2.1):
#: shoulders, elbows, wrists, hips, knees, ankles.
KP_STAR: tuple[int, ...] = tuple(range(5, 17))
#: Shelf-14 indices of the same twelve limb joints.
SHELF_LIMB_JOINTS: tuple[int, ...] = tuple(range(12))


def _by_name(src: Skeleton, dst: Skeleton, derived: dict[str, dict[str, float]]) -> np.ndarray:
    """Conversion matrix, shape (J_dst, J_src): same-name joints copied, others derived."""
    W = np.zeros((dst.num_joints, src.num_joints))
    for i, name in enumerate(dst.joints):
        if name in derived:
            for s, w in derived[name].items():
                W[i, src.index(s)] = w
        else:
            W[i, src.index(name)] = 1.0
    return W


_MID_SHOULDER = {"left_shoulder": 0.5, "right_shoulder": 0.5}
_MID_HIP = {"left_hip": 0.5, "right_hip": 0.5}
_HEAD = {"left_eye": 0.25, "right_eye": 0.25, "left_ear": 0.25, "right_ear": 0.25}

_CONVERSIONS: dict[tuple[str, str], np.ndarray] = {
    # Thesis 6.2.1: head = mean(eyes, ears), pelvis = mean(hips), neck = mean(shoulders),
    # torso = mean(neck, pelvis).
    ("coco17", "h36m17"): _by_name(
        COCO17,
        H36M17,
        {
            "pelvis": _MID_HIP,
            "neck": _MID_SHOULDER,
            "torso": {k: v / 2 for k, v in (_MID_HIP | _MID_SHOULDER).items()},
            "head": _HEAD,
        },
    ),
    # Shelf neck = "bottom of head": between the shoulders' midpoint and the ears.
    # Head top: the ear midpoint pushed up by the ear-to-shoulder-midpoint offset.
    ("coco17", "shelf14"): _by_name(
        COCO17,
        SHELF14,
        {
            "neck": {
                "left_shoulder": 0.35,
                "right_shoulder": 0.35,
                "left_ear": 0.15,
                "right_ear": 0.15,
            },
            "head_top": {
                "left_ear": 1.0,
                "right_ear": 1.0,
                "left_shoulder": -0.5,
                "right_shoulder": -0.5,
            },
        },
    ),
    # The lifter's own head top and neck (HALPE-26) give Shelf's directly.
    ("halpe26", "shelf14"): _by_name(HALPE26, SHELF14, {}),
    ("halpe26", "coco17"): _by_name(HALPE26, COCO17, {}),
    ("halpe26", "h36m17"): _by_name(
        HALPE26,
        H36M17,
        {
            "pelvis": {"mid_hip": 1.0},
            "torso": {"neck": 0.5, "mid_hip": 0.5},
            "head": _HEAD,
        },
    ),
    ("body25", "coco17"): _by_name(BODY25, COCO17, {}),
    ("body25b", "coco17"): _by_name(BODY25B, COCO17, {}),
    ("blazepose33", "coco17"): _by_name(BLAZEPOSE33, COCO17, {}),
}


def conversion_matrix(src: str | Skeleton, dst: str | Skeleton) -> np.ndarray:
    """Linear map from joint set ``src`` to ``dst``, shape (J_dst, J_src).

    Raises:
        ValueError: when no conversion between the two joint sets is known.
    """
    s = src.name if isinstance(src, Skeleton) else src
    d = dst.name if isinstance(dst, Skeleton) else dst
    if s == d:
        return np.eye(SKELETONS[s].num_joints)
    if (s, d) not in _CONVERSIONS:
        known = ", ".join(f"{a}->{b}" for a, b in _CONVERSIONS)
        raise ValueError(f"no conversion from {s!r} to {d!r}; known: {known}")
    return _CONVERSIONS[(s, d)]


def convert(points: np.ndarray, src: str | Skeleton, dst: str | Skeleton) -> np.ndarray:
    """Convert joints between joint sets.

    Args:
        points: joint values, shape (*, J_src, C) (C = 2 or 3 coordinates, or more).
        src: source joint set (name or :class:`Skeleton`).
        dst: target joint set.

    Returns:
        Converted joints, shape (*, J_dst, C). A derived joint is NaN when any of its
        sources is NaN.

    >>> import numpy as np
    >>> x = np.arange(17 * 3, dtype=float).reshape(17, 3)
    >>> convert(x, "coco17", "h36m17")[0].tolist()  # pelvis = mean of the hips
    [34.5, 35.5, 36.5]
    """
    W = conversion_matrix(src, dst)
    points = np.asarray(points, dtype=float)
    if points.shape[-2] != W.shape[1]:
        raise ValueError(
            f"points must have {W.shape[1]} joints on axis -2 for {src!r}, got shape {points.shape}"
        )
    used = W != 0
    nan = np.isnan(points).any(axis=-1)  # (*, J_src)
    out = np.einsum("ds,...sc->...dc", W, np.nan_to_num(points))
    missing = (nan[..., None, :] & used).any(axis=-1)  # (*, J_dst)
    out[missing] = np.nan
    return out


def convert_scores(scores: np.ndarray, src: str | Skeleton, dst: str | Skeleton) -> np.ndarray:
    """Convert per-joint confidences: a derived joint takes the minimum of its sources.

    Args:
        scores: shape (*, J_src). Returns shape (*, J_dst).
    """
    W = conversion_matrix(src, dst)
    scores = np.asarray(scores, dtype=float)
    big = np.where(W[None] != 0, scores.reshape(-1, 1, W.shape[1]), np.inf)
    return big.min(axis=-1).reshape(*scores.shape[:-1], W.shape[0])


#: For :func:`embed`: per source joint set, the joint that fills a slot of another name.
#: BlazePose's foot index is the tip of the second toe, about 2 cm from the big toe's tip;
#: the lifter is trained with it in the big-toe slot on BlazePose renders.
EMBED_ALIASES: dict[str, dict[str, str]] = {
    "blazepose33": {"left_big_toe": "left_foot_index", "right_big_toe": "right_foot_index"},
}


def embed(points: np.ndarray, src: str | Skeleton, dst: str | Skeleton) -> np.ndarray:
    """Place joints into another joint set by name; joints ``src`` lacks are NaN.

    Unlike :func:`convert`, nothing is derived: a detector that gives no neck leaves the
    neck missing, for the lifter to infer. :data:`EMBED_ALIASES` names the few joints that
    stand in for another (BlazePose's foot index for the big toe).

    Args:
        points: shape (*, J_src, C). Returns shape (*, J_dst, C).

    >>> import numpy as np
    >>> x = np.ones((17, 2))
    >>> y = embed(x, "coco17", "halpe26")
    >>> y.shape, bool(np.isnan(y[17:]).all()), bool((y[:17] == 1).all())
    ((26, 2), True, True)
    """
    s, d = skeleton_for(src), skeleton_for(dst)
    points = np.asarray(points, dtype=float)
    if points.shape[-2] != s.num_joints:
        raise ValueError(
            f"points must have {s.num_joints} joints for {s.name!r}, got {points.shape}"
        )
    out = np.full((*points.shape[:-2], d.num_joints, points.shape[-1]), np.nan)
    alias = EMBED_ALIASES.get(s.name, {})
    for i, name in enumerate(d.joints):
        source = alias.get(name, name)
        if source in s._index:
            out[..., i, :] = points[..., s._index[source], :]
    return out


def embed_scores(scores: np.ndarray, src: str | Skeleton, dst: str | Skeleton) -> np.ndarray:
    """:func:`embed` for confidences (*, J_src) -> (*, J_dst); joints ``src`` lacks are 0."""
    out = embed(np.asarray(scores, dtype=float)[..., None], src, dst)[..., 0]
    return np.nan_to_num(out, nan=0.0)


def to_model_joints(
    keypoints: np.ndarray, scores: np.ndarray, model: str | Skeleton, joints: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Put a detector's keypoints (*, J, 2) and scores (*, J) into a model's joint set.

    ``joints`` names the input's joint set; None: the model's own when the joint count
    matches, else COCO-17 for 17 joints and HALPE-26 for 26. Joints the input lacks are
    missing (NaN / 0); joints the model lacks are dropped.

    Raises:
        ValueError: an unknown joint set, or a joint count that matches neither.
    """
    dst = skeleton_for(model)
    J = np.shape(keypoints)[-2]
    if joints is None:
        joints = dst.name if J == dst.num_joints else BY_COUNT.get(J)
        if joints is None:
            raise ValueError(
                f"keypoints with {J} joints: name their joint set (one of {', '.join(SKELETONS)})"
            )
    src = skeleton_for(joints)
    if J != src.num_joints:
        raise ValueError(f"joint set {src.name!r} has {src.num_joints} joints, keypoints have {J}")
    if src.name == dst.name:
        return np.asarray(keypoints, float), np.asarray(scores, float)
    return embed(keypoints, src, dst), embed_scores(scores, src, dst)


#: Where a joint no two views locate starts from (the lifter's ``anchor_parents``): the
#: nearest joint on the way to the trunk. Joints not named here (nose, shoulders, hips)
#: start from the person's anchor, as before.
ANCHOR_PARENTS: dict[str, str] = {
    "left_eye": "nose",
    "right_eye": "nose",
    "left_ear": "left_eye",
    "right_ear": "right_eye",
    "left_elbow": "left_shoulder",
    "right_elbow": "right_shoulder",
    "left_wrist": "left_elbow",
    "right_wrist": "right_elbow",
    "left_knee": "left_hip",
    "right_knee": "right_hip",
    "left_ankle": "left_knee",
    "right_ankle": "right_knee",
    "head_top": "nose",
    "neck": "left_shoulder",
    "mid_hip": "left_hip",
    "left_big_toe": "left_ankle",
    "right_big_toe": "right_ankle",
    "left_small_toe": "left_big_toe",
    "right_small_toe": "right_big_toe",
    "left_heel": "left_ankle",
    "right_heel": "right_ankle",
}


def anchor_parents(skeleton: str | Skeleton) -> list[int]:
    """:data:`ANCHOR_PARENTS` as indices into ``skeleton`` (-1 = none), shape (J,).

    >>> anchor_parents("coco17")[15] == COCO17.index("left_knee")
    True
    """
    s = skeleton_for(skeleton)
    return [s._index.get(ANCHOR_PARENTS.get(n, ""), -1) for n in s.joints]


def to_joint_set(
    keypoints: np.ndarray, scores: np.ndarray, src: str | Skeleton, dst: str | Skeleton
) -> tuple[np.ndarray, np.ndarray]:
    """2D keypoints (*, J_src, 2) and scores (*, J_src) in joint set ``dst``: as they are when
    the sets agree, by name into HALPE-26 (:func:`embed`; joints ``src`` lacks are missing),
    else by :func:`convert` (a derived joint is missing, score 0, when a source is)."""
    s, d = skeleton_for(src), skeleton_for(dst)
    if s.name == d.name:
        return np.asarray(keypoints), np.asarray(scores)
    if d.name == "halpe26":
        return embed(keypoints, s, d), embed_scores(scores, s, d)
    kp, sc = convert(keypoints, s, d), convert_scores(scores, s, d)
    return kp, np.where(np.isnan(kp).any(-1), 0.0, sc)


#: The two joint sets rmpl reads 2D in and answers in, by their joint count; both begin with
#: COCO-17.
BY_COUNT: dict[int, str] = {17: "coco17", 26: "halpe26"}


def skeleton_for(name_or_skeleton: str | Skeleton) -> Skeleton:
    """The :class:`Skeleton` named ``name_or_skeleton`` (or the skeleton itself)."""
    if isinstance(name_or_skeleton, Skeleton):
        return name_or_skeleton
    try:
        return SKELETONS[name_or_skeleton]
    except KeyError:
        raise ValueError(
            f"unknown joint set {name_or_skeleton!r}; known: {', '.join(SKELETONS)}"
        ) from None


def flip_left_right(points: np.ndarray, skeleton: Skeleton = COCO17) -> np.ndarray:
    """Swap the left and right joints, shape (*, J, C) -> (*, J, C)."""
    return np.asarray(points)[..., skeleton.flip_permutation(), :]
