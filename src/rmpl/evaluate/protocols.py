"""The runs of ``rmpl evaluate`` on real data, each ending in a report (:mod:`.tables`).

- :func:`run_benchmark`: methods on a dataset with 3D ground truth (Shelf, Campus,
  Panoptic, H36M), loaded by :func:`rmpl.evaluate.evalset.load_eval_set`;
- :func:`score_results`: finished 3D results (``rmpl run`` output, a TRC) on such a dataset;
- :func:`run_recording`: a recording without ground truth, by held-out views
  (:mod:`rmpl.evaluate.heldout`).

The synthetic experiments are in :mod:`rmpl.evaluate.experiments`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.evaluate.evalset import EvalSet
from rmpl.evaluate.harness import EvalConfig, Evaluation, evaluate, evaluate_poses, view_subsets
from rmpl.evaluate.methods import Method
from rmpl.evaluate.tables import Report, benchmark_files, markdown_table
from rmpl.geometry import Rig
from rmpl.io.poses import Poses3D

__all__ = [
    "load_results",
    "recording_view_counts",
    "run_benchmark",
    "run_recording",
    "score_results",
]

HELDOUT_COLUMNS = [
    "views",
    "method",
    "subsets",
    "references",
    "coverage",
    "px_all",
    "px_common",
    "px_median_common",
    "mm_common",
    "mm_median_common",
]

# --------------------------------------------------------------------------- ground truth


def _report(ev: Evaluation, command: str) -> Report:
    from rmpl.evaluate.plots import benchmark_plots

    files = benchmark_files(ev, command)
    return Report(files["results.md"], files, lambda out: benchmark_plots(out, ev))


def run_benchmark(
    evset: EvalSet,
    methods: dict[str, Method],
    config: EvalConfig,
    views: str | None,
    command: str,
) -> Report:
    """Every method on every view subset (``views``: e.g. "all,pairs", the default) and
    condition of a dataset; ``command`` is quoted in results.md."""
    view_sets = view_subsets(evset.num_views, views or "all,pairs")
    return _report(evaluate(evset, methods, view_sets, config), command)


def score_results(
    evset: EvalSet, results: dict[str, Poses3D], config: EvalConfig, command: str
) -> Report:
    """Finished 3D results (name -> poses) scored against the dataset's ground truth."""
    return _report(evaluate_poses(evset, results, config), command)


def load_results(specs: list[str]) -> dict[str, Poses3D]:
    """``--poses [NAME=]FILE ...`` -> name -> poses; NAME defaults to the file's folder name."""
    from rmpl.io.poses import load_poses

    out = {}
    for item in specs:
        name, sep, path = item.partition("=")
        if not sep:
            path = item
            name = Path(item).parent.name or Path(item).stem
        if name in out:
            raise InputError(item, "--poses", "a distinct name per result (NAME=FILE)", name)
        out[name] = load_poses(path)
    return out


# --------------------------------------------------------------------------- recordings


def recording_view_counts(spec: str | None, num_views: int) -> list[int]:
    """``--views`` for a recording: view counts in 1..V-1 (default: all of them)."""
    V = num_views
    spec = spec or ",".join(str(k) for k in range(1, V))
    try:
        sizes = sorted({int(x) for x in spec.split(",") if x.strip()})
    except ValueError:
        raise InputError(None, "--views", f"view counts in 1..{V - 1}", spec) from None
    if not sizes or not all(1 <= k <= V - 1 for k in sizes):
        raise InputError(None, "--views", f"view counts in 1..{V - 1}", spec)
    return sizes


def _people(keypoints: np.ndarray, scores: np.ndarray, rig: Rig, sources: list[str]):
    """Every associated person of every frame: keypoints (N, V, J, 2), scores (N, V, J)."""
    from rmpl.pipeline.runner import associate_frames

    people = associate_frames(keypoints, scores, rig, progress=True)
    people = [a for a in people if len(a)]
    if not people:
        raise InputError(", ".join(sources), "people", "a person seen in 2+ views", "none")
    return np.concatenate([a.keypoints for a in people]), np.concatenate([a.scores for a in people])


def _recording_text(command, n, frames, rig: Rig, min_score: float, rows, notes=()) -> str:
    text = [
        "# rmpl evaluate: recording (held-out views, no ground truth)",
        "",
        f"`{command}`",
        "",
        f"{n} person-frames from {frames} frames, cameras "
        f"{', '.join(rig.names)}. Each camera in turn is held out; each method "
        "estimates from k of the others, and its estimate is projected into the held-out "
        f"camera and compared with that camera's detections of confidence >= {min_score:g}."
        " px: pixels in the held-out image; mm: the same error across the held-out camera's "
        "ray at the joint's depth. _common: on the detections every method estimated. People "
        "are associated across all cameras, the held-out one included (to know which of its "
        "detections to compare), so the association step has seen it.",
        "",
        *(f"- {note}" for note in notes),
        *([""] if notes else []),
        markdown_table(rows, HELDOUT_COLUMNS),
    ]
    return "\n".join(text)


def run_recording(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    methods: dict[str, Method],
    *,
    views: str | None,
    min_score: float,
    command: str,
    calib: str,
    sources: list[str],
    notes: tuple[str, ...] = (),
) -> Report:
    """Held-out-view reprojection errors on a recording without 3D ground truth.

    Args:
        keypoints: (T, V, N, J, 2) pixels per frame, view and 2D person; scores (T, V, N, J).
        rig: the V cameras, in the order of the views.
        methods: name -> method.
        views: ``--views`` (view counts k in 1..V-1), None for all.
        min_score: the confidence of a held-out detection used as the reference.
        command: the command line, quoted in results.md.
        calib, sources: the calibration and 2D files, for the messages.
        notes: lines for results.md's header (e.g. the floor of ``rmpl+floor``).
    """
    from rmpl.evaluate.heldout import heldout_rows, heldout_view_errors

    V = len(rig)
    if V < 2:
        raise InputError(calib, "cameras", "at least 2 (one is held out)", V)
    sizes = recording_view_counts(views, V)
    kp, sc = _people(keypoints, scores, rig, sources)
    ev = heldout_view_errors(kp, sc, rig, methods, sizes, min_score=min_score, progress=True)
    rows = heldout_rows(ev)
    text = _recording_text(command, len(kp), len(keypoints), rig, min_score, rows, notes)
    return Report(text, {"results.md": text, "results.csv": rows})
