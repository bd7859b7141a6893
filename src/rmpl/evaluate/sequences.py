"""Sequence methods: per-frame estimates linked into tracks, then filtered or lifted in time.

A sequence method sees what ``rmpl run`` sees: the associated 2D people of every frame of
one view subset, with no ground-truth identity. It estimates each person per frame, links
them over time with :func:`rmpl.pipeline.tracking.track_indices` (the ``rmpl run`` tracker
and its settings), then

- ``triangulate+filter``, ``robust+filter``, ``rmpl+filter``: the per-frame triangulation
  or lifter, then the gap filling and filtering of ``rmpl run``
  (:func:`rmpl.pipeline.runner.smooth`: Hampel, gaps up to 20 frames, 6 Hz Butterworth);
- ``rmpl:temporal`` (or ``rmpl:temporal:MODEL``): each track's 2D through the temporal
  lifter (:func:`rmpl.pipeline.tracklift.lift_tracks`).

It returns one prediction per track and frame, which the harness matches to the ground
truth frame by frame like any other prediction, so the tables and CSV columns are the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.geometry import Rig

__all__ = ["SEQUENCE_METHODS", "SequenceMethod", "is_sequence_method", "make_sequence_method"]

SEQUENCE_METHODS = ("triangulate+filter", "robust+filter", "rmpl+filter", "rmpl:temporal")
#: Frame rates of the datasets; Shelf and Campus state none (25 frames/s is assumed).
DATASET_FPS = {"shelf": 25.0, "campus": 25.0, "panoptic": 29.97, "h36m": 50.0}


def dataset_fps(dataset: str, given: float | None) -> float:
    """``--fps`` if given, else the dataset's rate (25 where it states none)."""
    return float(given) if given is not None else DATASET_FPS.get(dataset, 25.0)


def sequence_note(dataset: str, given: float | None) -> str:
    """The results.md header line saying how the sequence methods ran."""
    fps = dataset_fps(dataset, given)
    how = (
        "given by --fps"
        if given is not None
        else (
            "assumed: the dataset states none"
            if dataset in ("shelf", "campus")
            else "the dataset's"
        )
    )
    return (
        f"sequence methods (+filter, rmpl:temporal): people associated per frame, tracked "
        f"over time as rmpl run does (no ground-truth identity), at {fps:g} frames/s ({how}); "
        "scored per frame like the other methods"
    )


def is_sequence_method(spec: str) -> bool:
    """Whether ``spec`` names a sequence method: a ``+filter`` method, ``rmpl:temporal[:MODEL]``
    or ``rmpl:PATH`` with a temporal checkpoint at PATH."""
    import json
    from pathlib import Path

    if spec in SEQUENCE_METHODS[:3] or spec.startswith("rmpl:temporal"):
        return True
    name, _, arg = spec.partition(":")
    cfg = Path(arg) / "config.json"
    if name != "rmpl" or not arg or not cfg.is_file():
        return False
    try:
        return json.loads(cfg.read_text()).get("format") == "rmpl-temporal-checkpoint-1"
    except (OSError, ValueError):
        return False


@dataclass
class SequenceMethod:
    """``__call__(kp (M, V, J, 2), sc (M, V, J), frame (M,), num_frames, rig, fps)`` ->
    predictions (M', J, 3) and their frames (M',)."""

    base: str  # the per-frame method that feeds the tracker
    temporal: object | None = None  # a TemporalLifter for rmpl:temporal
    sequence: bool = True

    def __post_init__(self) -> None:
        from rmpl.evaluate.methods import make_method

        self._frame = make_method(self.base)

    def __call__(self, kp, sc, frame, num_frames: int, rig: Rig, fps: float):
        from rmpl.pipeline.association import Association
        from rmpl.pipeline.runner import RunConfig, smooth

        J = kp.shape[-2]
        if not len(kp):
            return np.zeros((0, J, 3)), np.zeros(0, int)
        pts = self._frame(kp, sc, rig)  # (M, J, 3)
        cfg = RunConfig()
        rows = [np.flatnonzero(frame == t) for t in range(num_frames)]
        per_frame = [pts[r] for r in rows]
        if not any(np.isfinite(p).any() for p in per_frame):
            return np.zeros((0, J, 3)), np.zeros(0, int)
        index = _tracks(per_frame, cfg)  # (T, P)
        if self.temporal is None:
            tracks = np.full((num_frames, index.shape[1], J, 3), np.nan)
            for t, p in zip(*np.nonzero(index >= 0), strict=True):
                tracks[t, p] = per_frame[t][index[t, p]]
            out, _ = smooth(tracks, fps, cfg)
        else:
            from rmpl.pipeline.tracklift import lift_tracks, tracks_2d

            people = [Association(kp[r], sc[r], np.zeros((len(r), kp.shape[1]), int)) for r in rows]
            k2, s2 = tracks_2d(people, index)
            out, _, _ = lift_tracks(k2, s2, rig, self.temporal, fps, cfg.max_gap)
        t_idx, p_idx = np.nonzero(np.isfinite(out).all(-1).any(-1))
        return out[t_idx, p_idx], t_idx


def _tracks(per_frame: list[np.ndarray], cfg) -> np.ndarray:
    """(T, P) index of each kept track's person per frame (tracks shorter than
    ``cfg.min_track_frames`` dropped, as ``rmpl run`` does)."""
    from rmpl.pipeline.tracking import track_indices

    index = track_indices(per_frame, max_distance=cfg.track_distance, max_missed=cfg.max_missed)
    keep = (index >= 0).sum(0) >= cfg.min_track_frames
    return index[:, keep] if keep.any() else index


def make_sequence_method(spec: str) -> SequenceMethod:
    """A sequence method from its name (see :data:`SEQUENCE_METHODS`)."""
    if spec.endswith("+filter"):
        return SequenceMethod(spec[: -len("+filter")])
    from rmpl.inference_temporal import TemporalLifter

    if spec.startswith("rmpl:temporal"):
        model = spec[len("rmpl:temporal") :].lstrip(":") or "temporal"
    else:
        model = spec.partition(":")[2]
    return SequenceMethod("rmpl", TemporalLifter.from_pretrained(model))
