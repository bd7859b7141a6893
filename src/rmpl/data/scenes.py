"""Multi-person MHP scene sets (``rmpl generate`` with ``people = [low, high]``, high >= 2)
as lifter training pairs, one pair per body.

A scene shard holds, per image, every person the detector found (``N`` slots, unassociated)
and ``match``: the body each slot is of, by the bodies' projected joints (see
:data:`rmpl.synth.shards.SCENE_ARRAYS`). A body's pair is its 3D joints and, in each view
of its scene, the 2D of the slot matched to it, or nothing (score 0, NaN) when no slot is.
:func:`load_scene_pairs` returns the arrays :func:`rmpl.data.mhp.load_mhp` returns for a
one-body set, so :func:`~rmpl.data.mhp.load_mhp` reads scene sets through it and
:class:`rmpl.data.mhp.ShardSource` (``TrainConfig.mhp``) trains on them unchanged.

Shape glossary: ``M`` bodies (pairs), ``S`` scenes, ``P`` body slots per scene, ``N``
detector slots per image, ``V`` views, ``J`` joints (17 or 26).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rmpl.errors import InputError

__all__ = ["load_scene_pairs", "is_scene_set", "matched_detections"]

#: Scene-shard arrays the pairs are made of.
_SCENE_KEYS = ("joints3d", "present", "keypoints", "scores", "match", "projected",
               "K", "R", "t", "size", "subject", "clip", "frame")  # fmt: skip
#: Per-scene arrays every body of the scene shares (its cameras).
_CAMERA_KEYS = ("K", "R", "t", "size")
#: Per-body arrays (a scene's body-slot axis first).
_BODY_KEYS = ("joints3d", "subject", "clip", "frame")


def is_scene_set(root: str | Path) -> bool:
    """Whether ``root`` holds a manifest of a multi-person scene set (``rmpl.mhp.scenes.v1``)."""
    from rmpl.synth.shards import SCENE_FORMAT

    manifest = Path(root) / "manifest.json"
    if not manifest.is_file():
        return False
    try:
        return json.loads(manifest.read_text()).get("format") == SCENE_FORMAT
    except (json.JSONDecodeError, AttributeError):
        return False


def matched_detections(
    keypoints: np.ndarray, scores: np.ndarray, match: np.ndarray, num_bodies: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each body's detection in each image: the slot ``match`` gives it, else none.

    Args:
        keypoints: (*, N, J, 2) pixels; scores: (*, N, J); match: (*, N) body index of each
            slot, -1 = none (at most one slot per body; with several the first is taken).
        num_bodies: P, the body slots.

    Returns:
        keypoints (*, P, J, 2), NaN where the body has no slot, and scores (*, P, J), 0 there.

    >>> kp = np.arange(12.0).reshape(2, 3, 2)  # N = 2 slots, J = 3
    >>> k, s = matched_detections(kp, np.ones((2, 3)), np.array([1, -1], np.int8), 2)
    >>> s.tolist(), k[1, 0].tolist(), bool(np.isnan(k[0]).all())
    ([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], [0.0, 1.0], True)
    """
    hit = match[..., :, None] == np.arange(num_bodies)  # (*, N, P)
    found = hit.any(-2)  # (*, P)
    slot = hit.argmax(-2)  # (*, P): the first slot of each body (0 when none)
    kp = np.take_along_axis(keypoints, slot[..., None, None], axis=-3)  # (*, P, J, 2)
    sc = np.take_along_axis(scores, slot[..., None], axis=-2)  # (*, P, J)
    kp = np.where(found[..., None, None], kp, np.nan).astype(keypoints.dtype)
    sc = np.where(found[..., None], sc, 0).astype(scores.dtype)
    return kp, sc


def load_scene_pairs(
    root: str | Path,
    subjects: Sequence[str] | None = None,
    exclude_subjects: Sequence[str] = (),
    joints: str | None = None,
) -> dict[str, np.ndarray]:
    """Read a scene set (every finished shard) as one training pair per body.

    Args:
        root: a directory written by ``rmpl generate`` with ``people = [low, high]``,
            high >= 2 (``manifest.json`` of format ``rmpl.mhp.scenes.v1`` + shards).
        subjects: keep only bodies posed from these motion subjects (None = all).
        exclude_subjects: drop bodies of these subjects (a held-out split).
        joints: the joint set to return (``"coco17"`` or ``"halpe26"``; None: as the set
            was made). COCO-17 sets read as HALPE-26 have the other nine joints missing.

    Returns:
        As :func:`rmpl.data.mhp.load_mhp`, with M = the bodies of every scene (scene by
        scene, body slot by slot): ``joints3d`` (M, J, 3) metres, ``keypoints``
        (M, V, J, 2) pixels, the detection matched to the body (NaN where the score is 0
        and in views where no detection is the body's), ``scores`` (M, V, J) (0 there),
        ``K`` (M, V, 3, 3), ``R`` (M, V, 3, 3), ``t`` (M, V, 3), ``size`` (M, V, 2) of the
        body's scene, ``subject``, ``clip``, ``frame`` (M,), ``projected`` (M, V, J, 2).

    Raises:
        InputError: not a scene directory, another joint set, no shards, a missing or
            malformed array, or no body selected.
    """
    from rmpl.data.shards import manifest_and_shards, selected
    from rmpl.synth.shards import SCENE_FORMAT

    root = Path(root)
    stored, shards = manifest_and_shards(root, SCENE_FORMAT)
    parts: dict[str, list] = {}
    for path in shards:
        for k, v in _shard_pairs(path).items():
            parts.setdefault(k, []).append(v)
    views = sorted({v.shape[1] for v in parts["scores"]})
    if len(views) > 1:
        raise InputError(root, "views", "one number of views in every shard", views)
    d = {k: np.concatenate(v) for k, v in parts.items()}
    return selected(d, root, subjects, exclude_subjects, joints, stored, "bodies")


def _shard_pairs(path: Path) -> dict[str, np.ndarray]:
    """One scene shard's bodies as pairs (the present body slots, scene by scene)."""
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in _SCENE_KEYS if k not in z.files]
        if missing:
            raise InputError(path, missing[0], "the scene array", "missing")
        s = {k: z[k] for k in _SCENE_KEYS}
    S, P = s["present"].shape if s["present"].ndim == 2 else (None, None)
    V, N = s["match"].shape[1:] if s["match"].ndim == 3 else (None, None)
    if S is None or s["match"].shape != (S, V, N) or s["scores"].shape[:3] != (S, V, N):
        raise InputError(path, "match", "(scenes, views, detector slots) beside present "
                         f"(scenes, bodies) {s['present'].shape} and scores (S, V, N, J) "
                         f"{s['scores'].shape}", s["match"].shape)  # fmt: skip
    if s["match"].size and not (-1 <= s["match"].min() and s["match"].max() < P):
        raise InputError(path, "match", f"body indices in [-1, {P - 1}]",
                         f"[{s['match'].min()}, {s['match'].max()}]")  # fmt: skip
    kp, sc = matched_detections(s["keypoints"], s["scores"], s["match"], P)  # (S, V, P, ...)
    scene, body = np.nonzero(s["present"])  # (M,) each: the pairs, scene by scene
    out = {k: s[k][scene, body] for k in _BODY_KEYS}
    out |= {k: s[k][scene] for k in _CAMERA_KEYS}
    out["keypoints"] = kp[scene, :, body]  # (M, V, J, 2)
    out["scores"] = sc[scene, :, body]
    out["projected"] = s["projected"][scene, :, body]
    return out
