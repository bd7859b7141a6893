"""Synchronisation from motion with known offsets put in.

Real 2D (``--shelf`` or ``--calib`` + ``--keypoints``): each camera but the first keeps a
window of ``--window`` frames shifted by a random whole number of frames up to
``--max-shift`` (different per camera); :func:`rmpl.calibration.sync.find_sync` with the
reference calibration must find every shift exactly, measured against the offsets it finds
on the whole unshifted recording (whose own cameras need not be in step). The first camera
is the reference. A trial whose motion does not decide is counted as refused (never as
found).

``--synthetic``: random rigs, two people, offsets of seconds with fractions of a frame,
cameras at 30, 30, 25 and 60 fps; the error of the offsets, frames (target 0.25); and
static scenes, which must be refused.

Example::

    python -m rmpl.benchmarks.sync --shelf ../shared/data/shelf_dev --fps 25
    python -m rmpl.benchmarks.sync --synthetic --trials 5
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _real(args):
    from rmpl.io.calibration import load_rig

    if args.shelf:
        from rmpl.pipeline.inputs import _shelf4d_keypoints

        kp = _shelf4d_keypoints(Path(args.shelf))
        return kp.keypoints, load_rig(Path(args.shelf) / "calibration.json"), args.fps or 25.0
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    inp = load_inputs(InputSpec(args.calib, args.keypoints))
    return inp.keypoints, inp.rig, args.fps or inp.fps


def _find(x, fps, rig, max_offset):
    from rmpl.calibration.sync import find_sync
    from rmpl.errors import InputError

    try:
        sync = find_sync(x, fps, rig.names, rig, max_offset)
    except InputError as e:
        return None, str(e)
    return sync.offset_frames, np.round(sync.uncertainty, 2).tolist()


def real_trials(keypoints, rig, fps, trials, max_shift, window, seed=0) -> dict:
    """Known whole-frame shifts put into a real recording, found again.

    The recording's own offsets are not known to be zero (cameras drift, a view may be
    out of step), so each trial's found offsets are compared with those found on the
    whole unshifted recording (``base``): a camera is exact when found - base rounds to
    the shift put in (against zero when the whole recording is refused: ``base`` then
    states the refusal). ``exact_vs_zero`` counts against the shifts alone.
    """
    T, V = keypoints.shape[:2]
    window = min(window, T - 2 * max_shift)
    base, why = _find(keypoints, fps, rig, 1.2 * max_shift / fps)
    if base is None:  # measured against zero then, and said so
        base, why_base = np.zeros(V), why
    else:
        why_base, base_err = None, why
    max_offset = (1.2 * max_shift + np.ceil(np.abs(base).max())) / fps
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(trials):
        shift = np.r_[0, rng.integers(-max_shift, max_shift + 1, V - 1)]
        x = np.stack([keypoints[max_shift - shift[v] : max_shift - shift[v] + window, v]
                      for v in range(V)], 1)  # fmt: skip
        found, why = _find(x, fps, rig, max_offset)
        row = {"put_in": shift.tolist(), "found": why}
        if found is not None:
            rel = found - base
            row.update(found=np.round(found, 2).tolist(), minus_base=np.round(rel, 2).tolist(),
                       uncertainty_frames=why,
                       exact=int((np.round(rel) == shift)[1:].sum()),
                       exact_vs_zero=int((np.round(found) == shift)[1:].sum()))  # fmt: skip
        rows.append(row)
    done = [r for r in rows if "exact" in r]
    return {
        "base": np.round(base, 2).tolist() if why_base is None else why_base,
        "base_uncertainty_frames": None if why_base else base_err,
        "trials": rows,
        "cameras": trials * (V - 1),
        "cameras_exact": sum(r["exact"] for r in done),
        "cameras_exact_vs_zero": sum(r["exact_vs_zero"] for r in done),
        "trials_refused": len(rows) - len(done),
        "trials_all_exact": sum(r["exact"] == V - 1 for r in done),
        "window": window,
        "max_shift": max_shift,
    }


def _synthetic(off, fps, n, rng, still=False):
    from rmpl.calibration.people_synth import moving_people, observe, ring_rig

    rig = ring_rig(len(fps), rng=rng)
    views = []
    for v in range(len(fps)):
        times = off.max() + 0.5 - off[v] + np.arange(n[v]) / fps[v]
        X = moving_people(np.zeros_like(times) if still else times, (1.75, 1.62), rng=rng + 100)
        views.append(observe(X, rig[[v]], noise=1.0, rng=rng + v)[0][:, 0])
    T = max(n)
    kp = np.full((T, len(fps)) + views[0].shape[1:], np.nan)
    for v, x in enumerate(views):
        kp[: len(x), v] = x
    return kp, rig


def synthetic_trials(trials: int, max_seconds: float = 2.5, seed: int = 0) -> dict:
    """Synthetic rigs (4 cameras: 30, 30, 25 and 60 fps), two people, offsets of up to
    ``max_seconds`` with fractions of a frame, 8 s per camera: the error of the found
    offsets in frames of each camera; and as many static scenes, which must be refused."""
    from rmpl.calibration.sync import find_sync
    from rmpl.errors import InputError

    rng = np.random.default_rng(seed)
    fps = np.array([30.0, 30.0, 25.0, 60.0])
    n = (8.0 * fps).astype(int)
    errors, refused = [], []
    for k in range(trials):
        off = np.r_[0.0, rng.uniform(-max_seconds, max_seconds, len(fps) - 1)]
        kp, rig = _synthetic(off, fps, n, seed + k)
        try:
            sync = find_sync(kp, fps, rig.names, rig, max_offset=max_seconds + 0.2)
            errors.append(((sync.offsets - off) * fps)[1:].tolist())
        except InputError as e:
            errors.append(str(e))
        kp, rig = _synthetic(np.zeros(len(fps)), fps, n, seed + k, still=True)
        try:
            find_sync(kp, fps, rig.names, rig, max_offset=max_seconds + 0.2)
            refused.append(False)
        except InputError:
            refused.append(True)
    e = np.array([x for x in errors if not isinstance(x, str)])
    return {
        "errors_frames": [
            np.round(x, 3).tolist() if not isinstance(x, str) else x for x in errors
        ],  # fmt: skip
        "max_abs_error_frames": round(float(np.abs(e).max()), 3) if len(e) else None,
        "moving_refused": sum(isinstance(x, str) for x in errors),
        "static_refused": f"{sum(refused)} of {len(refused)}",
    }


def main(argv: list[str] | None = None) -> int:
    from rmpl.benchmarks._common import emit_json

    p = argparse.ArgumentParser(prog="python -m rmpl.benchmarks.sync",
                                description=__doc__.splitlines()[0])  # fmt: skip
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--shelf")
    src.add_argument("--calib")
    src.add_argument("--synthetic", action="store_true")
    p.add_argument("--keypoints", nargs="+")
    p.add_argument("--fps", type=float, default=None)
    p.add_argument("--trials", type=int, default=5)
    p.add_argument("--max-shift", type=int, default=25, help="frames")
    p.add_argument("--window", type=int, default=100, help="frames kept per camera")
    p.add_argument("--max-seconds", type=float, default=2.5, help="synthetic: largest offset")
    p.add_argument(
        "--min-z",
        type=float,
        default=None,
        help="measure with another decision bar (default: the shipped one)",
    )
    p.add_argument(
        "--bias-free",
        action="store_true",
        help="measure with each joint's constant epipolar disagreement removed",
    )
    p.add_argument("--json")
    args = p.parse_args(argv)
    from rmpl.calibration import sync_3d

    sync_3d.BIAS_FREE = args.bias_free or sync_3d.BIAS_FREE
    sync_3d.MIN_Z = sync_3d.MIN_Z if args.min_z is None else args.min_z
    if args.synthetic:
        out = synthetic_trials(args.trials, args.max_seconds)
    else:
        keypoints, rig, fps = _real(args)
        out = real_trials(keypoints, rig, fps, args.trials, args.max_shift, args.window)
    emit_json(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
