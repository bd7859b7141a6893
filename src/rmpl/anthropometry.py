"""A participant's height from the bone lengths of one 3D track.

Body segment lengths scale with stature: Drillis and Contini (1966), as reproduced in Winter,
*Biomechanics and Motor Control of Human Movement* (4th ed., 2009, Fig. 4.1), give each
segment as a fraction of the standing height H. The heights above the floor of the landmarks
rmpl's joints stand for are

====================================  ========
landmark                              height
====================================  ========
shoulder (acromion)                   0.818 H
hip (greater trochanter)              0.530 H
knee                                  0.285 H
ankle (lateral malleolus)             0.039 H
====================================  ========

so the shank (knee to ankle) is 0.246 H, the thigh (hip to knee) 0.245 H and the trunk
(mid-hip to mid-shoulder) 0.288 H. Their sum, one leg and the trunk, spans 0.779 H; the rest
is the ankle's height above the floor (0.039 H) and the shoulder to the crown (0.182 H).

:func:`estimate_height` measures each of the five bones (both shanks, both thighs, the
trunk) in every frame where both its ends are present, takes the median over the frames
(robust to a minority of bad frames; a bone's length does not change with pose), averages
left and right, and returns ``(shank + thigh + trunk) / 0.779``. The chain's segments are
long and seen by most detectors, which is why it is used rather than the head (COCO-17 has
no crown) or the arms.

Accuracy: the proportions are population means; individuals vary by a few per cent, and the
COCO-17 hip and shoulder keypoints of a detector are not exactly the trochanter and the
acromion. Read the value as an estimate to +-5%, not a measurement.

With HALPE-26 joints (the lifter's head top and feet) two more spans are measured instead of
taken from the proportions, each only when seen in ``min_frames`` frames:

- **crown**: mid-shoulder to ``head_top``, standing for the shoulder-to-vertex span (0.182 H);
- **ankle height**: the distance of the ankle from the plane through the same foot's heel,
  big toe and small toe (the sole, flat on the floor when standing), per side, standing for
  the ankle's height above the floor (0.039 H). Both are posture-independent (rigid head
  and foot), as the bone lengths are.

The height is then the measured spans over the fraction of H they cover: ``(shank + thigh +
trunk + crown + ankle) / 1.0`` with both, ``/ 0.961`` with the crown alone, ``/ 0.818`` with
the ankle alone, ``/ 0.779`` with neither (COCO-17). :func:`bone_lengths` lists them as
``crown``, ``left_ankle_height`` and ``right_ankle_height``.

Shape glossary: ``T`` frames, ``J`` joints. Metres.
"""

from __future__ import annotations

import numpy as np

from rmpl.errors import InputError
from rmpl.skeleton import SKELETONS

__all__ = [
    "HEIGHT_FRACTIONS",
    "CHAIN_FRACTION",
    "EXTRA_FRACTIONS",
    "BODY_SEGMENTS",
    "bone_lengths",
    "body_segments",
    "estimate_height",
]

#: Segment lengths as fractions of standing height (Drillis & Contini 1966, in Winter 2009,
#: Fig. 4.1): shank = knee 0.285 - ankle 0.039, thigh = hip 0.530 - knee 0.285,
#: trunk = shoulder 0.818 - hip 0.530.
HEIGHT_FRACTIONS: dict[str, float] = {
    "shank": 0.285 - 0.039,
    "thigh": 0.530 - 0.285,
    "trunk": 0.818 - 0.530,
}
#: The fraction of the height spanned by shank + thigh + trunk (0.779).
CHAIN_FRACTION = sum(HEIGHT_FRACTIONS.values())
#: The spans measured when the joints are there (HALPE-26): shoulder (0.818) to the vertex
#: (1.0), and the ankle's height (0.039).
EXTRA_FRACTIONS: dict[str, float] = {"crown": 1.0 - 0.818, "ankle": 0.039}

# Each measured bone: (segment, ends). An end is one joint name or a pair whose midpoint
# is used (the trunk runs from mid-hip to mid-shoulder).
_BONES: dict[str, tuple[str, tuple, tuple]] = {
    "left_shank": ("shank", ("left_knee",), ("left_ankle",)),
    "right_shank": ("shank", ("right_knee",), ("right_ankle",)),
    "left_thigh": ("thigh", ("left_hip",), ("left_knee",)),
    "right_thigh": ("thigh", ("right_hip",), ("right_knee",)),
    "trunk": ("trunk", ("left_hip", "right_hip"), ("left_shoulder", "right_shoulder")),
}
_CROWN = ("crown", ("left_shoulder", "right_shoulder"), ("head_top",))
_FEET = {side: (f"{side}_ankle", f"{side}_heel", f"{side}_big_toe", f"{side}_small_toe")
         for side in ("left", "right")}  # fmt: skip


def _checked(points, skeleton: str) -> np.ndarray:
    if skeleton not in SKELETONS:
        raise InputError(None, "skeleton", f"one of {sorted(SKELETONS)}", skeleton)
    try:
        x = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise InputError(None, "points", "an array of numbers (T, J, 3)", "other") from None
    J = SKELETONS[skeleton].num_joints
    if x.ndim != 3 or x.shape[1:] != (J, 3):
        raise InputError(None, "points", f"shape (T, {J}, 3) for {skeleton}", x.shape)
    return x


def _end(points: np.ndarray, names: tuple[str, ...], skeleton: str) -> np.ndarray:
    """One end of a bone, (T, 3): a joint or the midpoint of two (NaN if either is)."""
    skel = SKELETONS[skeleton]
    try:
        idx = skel.indices(names)
    except KeyError:
        raise InputError(
            None, "skeleton", f"a joint set with {', '.join(names)} (e.g. coco17)", skeleton
        ) from None
    return points[:, idx].mean(1)


def bone_lengths(points: np.ndarray, skeleton: str = "coco17") -> dict[str, tuple[float, int]]:
    """The median length of each bone of the height chain over a track.

    Args:
        points: one person's joints, shape (T, J, 3), metres; NaN = missing.
        skeleton: the joint set (its joint names must include COCO-17's legs, hips and
            shoulders).

    Returns:
        ``{bone: (median length in metres, number of frames with both ends)}`` for
        left_shank, right_shank, left_thigh, right_thigh and trunk, and, when the joint set
        has them (HALPE-26), crown (mid-shoulder to head top) and left/right_ankle_height
        (the ankle's distance from the plane of heel, big toe and small toe); the length is
        NaN when no frame has both ends.

    >>> pts = np.full((2, 17, 3), np.nan)
    >>> pts[:, 13], pts[:, 15] = [0, 0, 0.5], [0, 0, 0.1]  # left knee, left ankle
    >>> length, frames = bone_lengths(pts)["left_shank"]
    >>> round(length, 3), frames
    (0.4, 2)
    """
    x = _checked(points, skeleton)
    out = {}
    for bone, (_, a, b) in _BONES.items():
        d = np.linalg.norm(_end(x, a, skeleton) - _end(x, b, skeleton), axis=-1)
        ok = np.isfinite(d)
        out[bone] = (float(np.median(d[ok])) if ok.any() else float("nan"), int(ok.sum()))
    names = set(SKELETONS[skeleton].joints)
    if set(_CROWN[2]) <= names:
        out["crown"] = _median(
            np.linalg.norm(_end(x, _CROWN[2], skeleton) - _end(x, _CROWN[1], skeleton), axis=-1)
        )
    for side, joints in _FEET.items():
        if set(joints) <= names:
            ankle, heel, big, small = (_end(x, (j,), skeleton) for j in joints)
            normal = np.cross(big - heel, small - heel)
            with np.errstate(invalid="ignore", divide="ignore"):
                normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
            out[f"{side}_ankle_height"] = _median(np.abs(((ankle - heel) * normal).sum(-1)))
    return out


def _median(d: np.ndarray) -> tuple[float, int]:
    ok = np.isfinite(d)
    return (float(np.median(d[ok])) if ok.any() else float("nan"), int(ok.sum()))


def estimate_height(points: np.ndarray, skeleton: str = "coco17", min_frames: int = 5) -> float:
    """Standing height of one tracked person from its bone lengths (see the module docstring).

    Args:
        points: one person's joints over time, shape (T, J, 3), metres; NaN = missing.
        skeleton: the joint set of ``points``.
        min_frames: a bone counts only when both its ends are present in at least this
            many frames.

    Returns:
        The estimated height in metres, ``(shank + thigh + trunk) / 0.779`` with each
        segment's median length over the track (shank and thigh: the mean of the sides
        that count); with HALPE-26's head top and feet seen, the crown and the ankle height
        are measured too (see the module docstring).

    Raises:
        InputError: ``points`` is not (T, J, 3) for ``skeleton``, or the track has too
            little data: the trunk, or both shanks, or both thighs, are seen in fewer than
            ``min_frames`` frames.

    >>> H = 1.80  # a person standing upright, built from the same proportions
    >>> pts = np.full((6, 17, 3), np.nan)
    >>> for side, x in ((0, 0.1), (1, -0.1)):  # COCO-17: left/right hip 11/12, knee 13/14,
    ...     pts[:, 11 + side] = [x, 0, 0.530 * H]  # ankle 15/16, shoulder 5/6
    ...     pts[:, 13 + side] = [x, 0, 0.285 * H]
    ...     pts[:, 15 + side] = [x, 0, 0.039 * H]
    ...     pts[:, 5 + side] = [1.5 * x, 0, 0.818 * H]
    >>> round(estimate_height(pts), 3)
    1.8
    """
    lengths = bone_lengths(points, skeleton)
    segment: dict[str, list[float]] = {s: [] for s in HEIGHT_FRACTIONS}
    for bone, (seg, _, _) in _BONES.items():
        length, frames = lengths[bone]
        if frames >= min_frames:
            segment[seg].append(length)
    lacking = [s for s, v in segment.items() if not v]
    if lacking:
        seen = ", ".join(f"{b} {n}" for b, (_, n) in lengths.items())
        raise InputError(
            None,
            "points",
            f"a track in which the {', '.join(lacking)} (both ends) "
            f"{'is' if len(lacking) == 1 else 'are'} seen in at least {min_frames} frames, "
            "for a height",
            f"frames per bone: {seen}",
        )
    total = sum(float(np.mean(v)) for v in segment.values())
    fraction = CHAIN_FRACTION
    extra = {"crown": ["crown"], "ankle": ["left_ankle_height", "right_ankle_height"]}
    for part, bones in extra.items():
        seen = [lengths[b][0] for b in bones if b in lengths and lengths[b][1] >= min_frames]
        if seen:
            total += float(np.mean(seen))
            fraction += EXTRA_FRACTIONS[part]
    return total / fraction


#: The segments of :func:`body_segments`, as pairs of COCO-17 joints per side (both sides'
#: lengths are averaged) or across the body (shoulder and hip width, trunk).
BODY_SEGMENTS: dict[str, tuple[tuple[tuple[str, ...], tuple[str, ...]], ...]] = {
    "upper_arm": ((("left_shoulder",), ("left_elbow",)), (("right_shoulder",), ("right_elbow",))),
    "forearm": ((("left_elbow",), ("left_wrist",)), (("right_elbow",), ("right_wrist",))),
    "thigh": ((("left_hip",), ("left_knee",)), (("right_hip",), ("right_knee",))),
    "shank": ((("left_knee",), ("left_ankle",)), (("right_knee",), ("right_ankle",))),
    "shoulder_width": ((("left_shoulder",), ("right_shoulder",)),),
    "hip_width": ((("left_hip",), ("right_hip",)),),
    "trunk": ((("left_hip", "right_hip"), ("left_shoulder", "right_shoulder")),),
}


def body_segments(
    points: np.ndarray, skeleton: str = "coco17", min_frames: int = 3
) -> dict[str, float]:
    """A person's build from one track: the median length of each of
    :data:`BODY_SEGMENTS` over the frames where both its ends are present (left and right
    averaged), for telling two people apart by their bodies (a bone's length does not
    change with pose).

    Args:
        points: one person's joints, shape (T, J, 3), metres; NaN = missing.
        skeleton: the joint set (its names must include COCO-17's).
        min_frames: a segment (side) counts only when seen in at least this many frames.

    Returns:
        ``{segment: metres}`` for the segments seen often enough (others left out).

    >>> pts = np.full((3, 17, 3), np.nan)
    >>> pts[:, 11], pts[:, 12] = [0.1, 0, 1.0], [-0.1, 0, 1.0]  # left and right hip
    >>> body_segments(pts)
    {'hip_width': 0.2}
    """
    x = _checked(points, skeleton)
    out = {}
    for name, sides in BODY_SEGMENTS.items():
        found = []
        for a, b in sides:
            d = np.linalg.norm(_end(x, a, skeleton) - _end(x, b, skeleton), axis=-1)
            d = d[np.isfinite(d)]
            if len(d) >= min_frames:
                found.append(float(np.median(d)))
        if found:
            out[name] = round(float(np.mean(found)), 6)
    return out
