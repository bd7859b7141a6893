"""Reading an MHP shard set (:mod:`rmpl.synth.shards`): its manifest checked, its shards'
arrays concatenated, subjects selected, in the joint set asked for. Shared by the
single-frame and sequence readers (:mod:`rmpl.data.mhp`) and the scene reader
(:mod:`rmpl.data.scenes`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.skeleton import SKELETONS, embed, embed_scores

__all__ = ["in_joint_set", "load_arrays", "manifest_and_shards", "selected"]

_JOINT_SETS = ("coco17", "halpe26")
#: Arrays with a joint axis (the one before last for points, the last for scores).
_JOINT_POINTS, _JOINT_VALUES = ("joints3d", "keypoints", "projected"), ("scores",)


def in_joint_set(d: dict, stored: str, joints: str) -> dict:
    """A set's arrays in another joint set: HALPE-26 -> COCO-17 keeps the first 17 joints;
    COCO-17 -> HALPE-26 leaves the nine others missing (NaN targets, score 0)."""
    if joints not in _JOINT_SETS:
        raise ValueError(f"joints must be one of {_JOINT_SETS}, got {joints!r}")
    out = dict(d)
    for k in _JOINT_POINTS:
        if k in d:
            out[k] = embed(d[k], stored, joints).astype(d[k].dtype)
    for k in _JOINT_VALUES:
        if k in d:
            out[k] = embed_scores(d[k], stored, joints).astype(d[k].dtype)
    return out


def manifest_and_shards(root: Path, fmt: str) -> tuple[str, list[Path]]:
    """The joint set the manifest of ``root`` names and its finished shards, checked: a
    manifest of format ``fmt`` (a wrong one names the reader to use), COCO-17 or HALPE-26,
    at least one shard."""
    from rmpl.synth.shards import FORMAT, SCENE_FORMAT, SEQUENCE_FORMAT, list_shards

    manifest = root / "manifest.json"
    if not manifest.is_file():
        raise InputError(root, "manifest.json", "an MHP directory made by rmpl generate", "none")
    try:
        meta = json.loads(manifest.read_text())
    except json.JSONDecodeError as e:
        raise InputError(manifest, None, "JSON", e) from None
    got = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
    if got != fmt:
        hint = {
            FORMAT: " (a single-frame, single-body set: read it with load_mhp)",
            SEQUENCE_FORMAT: " (a sequence set: read it with load_mhp_sequences)",
            SCENE_FORMAT: " (a scene set: read it with load_mhp or load_scene_pairs)",
        }.get(got, "")
        raise InputError(manifest, "format", repr(fmt), f"{got!r}{hint}")
    stored = next((k for k in _JOINT_SETS if meta.get("joints") == list(SKELETONS[k].joints)), None)
    if stored is None:
        raise InputError(manifest, "joints", "COCO-17 or HALPE-26", meta.get("joints"))
    shards = list_shards(root)
    if not shards:
        raise InputError(root, None, "finished shards (shard_*.npz)", "none")
    return stored, shards


def load_arrays(
    root, fmt: str, keys, optional, subjects, exclude_subjects, what: str, joints=None
) -> dict:
    """The arrays ``keys`` of every finished shard of ``root`` (manifest format ``fmt``),
    concatenated, the subject selection applied, in joint set ``joints`` (None: as stored),
    keypoints NaN where the score is 0."""
    root = Path(root)
    stored, shards = manifest_and_shards(root, fmt)
    parts: dict[str, list] = {}
    for p in shards:
        with np.load(p, allow_pickle=False) as z:
            for k in keys:
                if k in z.files:
                    parts.setdefault(k, []).append(z[k])
                elif k not in optional:
                    raise InputError(p, k, "the array", "missing")
    d = {k: np.concatenate(v) for k, v in parts.items()}
    return selected(d, root, subjects, exclude_subjects, joints, stored, what)


def selected(d, root, subjects, exclude_subjects, joints, stored: str, what: str) -> dict:
    """The entries of the selected subjects, in the joint set asked for, keypoints NaN where
    the score is 0 (shared by the single-frame, sequence and scene readers)."""
    keep = np.ones(len(d["joints3d"]), bool)
    if subjects is not None:
        keep &= np.isin(d["subject"], list(subjects))
    keep &= ~np.isin(d["subject"], list(exclude_subjects))
    if not keep.any():
        raise InputError(
            root,
            "subject",
            f"{what} of subjects {subjects} not in {list(exclude_subjects)}",
            sorted(set(d["subject"].tolist())),
        )
    d = {k: v[keep] for k, v in d.items()}
    if joints is not None and joints != stored:
        d = in_joint_set(d, stored, joints)
    missed = d["scores"] <= 0
    d["keypoints"] = np.where(missed[..., None], np.nan, d["keypoints"]).astype(np.float32)
    return d
