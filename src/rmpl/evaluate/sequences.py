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
The predictions have the joints of the per-frame method or temporal model (COCO-17 or
HALPE-26, :mod:`rmpl.evaluate.methods`); with nothing to estimate, none (0, 17, 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rmpl.evaluate.methods import fit_input, make_method, stretches
from rmpl.geometry import Rig

__all__ = [
    "SEQUENCE_METHODS",
    "SequenceMethod",
    "is_sequence_method",
    "make_sequence_method",
    "stretches",
]

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
    from rmpl.inference_temporal import is_temporal_checkpoint

    if spec in SEQUENCE_METHODS[:3] or spec.startswith("rmpl:temporal"):
        return True
    name, _, arg = spec.partition(":")
    return name == "rmpl" and bool(arg) and is_temporal_checkpoint(arg)


def needs_time(spec: str) -> bool:
    """Whether the method ``spec`` needs frames in time: a sequence method
    (:func:`is_sequence_method`) or ``rmpl+floor[:CUES]@MODEL`` with a temporal MODEL (whole
    one-view tracks, :class:`rmpl.evaluate.methods.MonocularMethod`)."""
    from rmpl.inference_temporal import is_temporal_checkpoint

    if spec.startswith("rmpl+floor") and "@" in spec:
        return is_temporal_checkpoint(spec.rpartition("@")[2])
    return is_sequence_method(spec)


@dataclass
class SequenceMethod:
    """``__call__(kp (M, V, J, 2), sc (M, V, J), frame (M,), num_frames, rig, fps,
    frame_numbers, clips)`` -> predictions (M', J, 3) and their frame indices (M',).

    ``frame`` indexes the part's frames; ``frame_numbers`` (T,) and ``clips`` (T,) say where
    time jumps (a new clip, a gap in the numbering): each continuous stretch is tracked and
    filtered or lifted on its own, at ``fps`` divided by the stretch's frame step.
    """

    base: str  # the per-frame method that feeds the tracker
    temporal: object | None = None  # a TemporalLifter for rmpl:temporal
    sequence: bool = True

    def __post_init__(self) -> None:
        if self.temporal is None:
            self._frame = make_method(self.base)
        else:  # track with the temporal model's own per-frame model, as rmpl run does
            from rmpl.inference import Lifter

            lifter = Lifter(self.temporal.model.frame_model)
            self._frame = lambda kp, sc, rig: (
                lifter.lift(*fit_input(kp, sc, lifter.num_joints), rig).points
            )

    def __call__(self, kp, sc, frame, num_frames: int, rig: Rig, fps: float,
                 frame_numbers=None, clips=None):  # fmt: skip
        preds, at = [], [np.zeros(0, int)]
        for a, b, step in stretches(num_frames, frame_numbers, clips):
            rows = (frame >= a) & (frame < b)
            if rows.any():
                p, t = self._stretch(kp[rows], sc[rows], frame[rows] - a, b - a, rig, fps / step)
                if len(p):
                    preds.append(p)
                    at.append(t + a)
        if not preds:
            return np.zeros((0, 17, 3)), np.zeros(0, int)
        return np.concatenate(preds), np.concatenate(at)

    def _stretch(self, kp, sc, frame, num_frames: int, rig: Rig, fps: float):
        """One continuous stretch: estimate, track, then filter or lift each track."""
        from rmpl.pipeline.association import Association
        from rmpl.pipeline.runner import RunConfig, smooth, track_index

        pts = self._frame(kp, sc, rig)  # (M, J, 3), the method's joints
        J = pts.shape[-2]
        cfg = RunConfig()
        rows = [np.flatnonzero(frame == t) for t in range(num_frames)]
        per_frame = [pts[r] for r in rows]
        if not any(np.isfinite(p).any() for p in per_frame):
            return np.zeros((0, J, 3)), np.zeros(0, int)
        index, _ = track_index(per_frame, cfg)  # (T, P), rmpl run's tracker and its rules
        if self.temporal is None:
            tracks = np.full((num_frames, index.shape[1], J, 3), np.nan)
            for t, p in zip(*np.nonzero(index >= 0), strict=True):
                tracks[t, p] = per_frame[t][index[t, p]]
            out, _ = smooth(tracks, fps, RunConfig(cutoff=min(cfg.cutoff, 0.45 * fps)))
        else:
            from rmpl.pipeline.tracklift import lift_tracks, tracks_2d

            kp, sc = fit_input(kp, sc, self.temporal.num_joints)
            people = [Association(kp[r], sc[r], np.zeros((len(r), kp.shape[1]), int)) for r in rows]
            k2, s2 = tracks_2d(people, index)
            out, _, _ = lift_tracks(k2, s2, rig, self.temporal, fps, cfg.max_gap)
        t_idx, p_idx = np.nonzero(np.isfinite(out).all(-1).any(-1))
        return out[t_idx, p_idx], t_idx


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
