"""Synchronisation from motion with known offsets put in.

Real 2D (``--shelf`` or ``--calib`` + ``--keypoints``): each camera but the first keeps a
window of ``--window`` frames shifted by a random whole number of frames up to
``--max-shift`` (different per camera); :func:`rmpl.calibration.sync.find_sync` with the
reference calibration must find every shift exactly. The first camera is the reference.
A trial whose motion does not decide is counted as refused (never as found).

``--synthetic``: random rigs, people and offsets with fractions of a frame (one camera at
25 fps, the others at 30); the error of the fine offsets, frames (target 0.25).

Example::

    python -m rmpl.benchmarks.sync --shelf ../shared/data/shelf_dev --fps 25
    python -m rmpl.benchmarks.sync --synthetic --trials 5
"""

from __future__ import annotations

import argparse
import json
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


def real_trials(keypoints, rig, fps, trials, max_shift, window, seed=0) -> dict:
    from rmpl.calibration.sync import find_sync
    from rmpl.errors import InputError

    T, V = keypoints.shape[:2]
    window = min(window, T - 2 * max_shift)
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(trials):
        shift = np.r_[0, rng.integers(-max_shift, max_shift + 1, V - 1)]
        x = np.stack([keypoints[max_shift - shift[v] : max_shift - shift[v] + window, v]
                      for v in range(V)], 1)  # fmt: skip
        try:
            sync = find_sync(x, fps, rig.names, rig, 1.2 * max_shift / fps, fine=False)
            found = np.round(sync.offset_frames).astype(int).tolist()
        except InputError as e:
            found = str(e)
        rows.append({"put_in": shift.tolist(), "found": found})
    exact = sum(r["found"] == r["put_in"] for r in rows)
    cams = sum(V - 1 for r in rows)
    cams_ok = sum(sum(a == b for a, b in zip(r["put_in"][1:], r["found"][1:], strict=True))
                  for r in rows if isinstance(r["found"], list))  # fmt: skip
    return {"trials": rows, "all_exact": exact, "of": trials, "cameras_exact": cams_ok,
            "cameras": cams, "window": window, "max_shift": max_shift}  # fmt: skip


def synthetic_trials(trials: int, seed: int = 0) -> dict:
    from rmpl.calibration.people_synth import moving_people, observe, ring_rig
    from rmpl.calibration.sync import find_sync

    rng = np.random.default_rng(seed)
    errors = []
    for k in range(trials):
        V = 4
        fps = np.array([30.0, 30.0, 25.0, 30.0])
        rig = ring_rig(V, rng=seed + k)
        off = np.r_[0.0, rng.uniform(-1.5, 1.5, V - 1)]
        views = []
        for v in range(V):
            times = 3.0 - off[v] + np.arange(150) / fps[v]
            X = moving_people(times, (1.75, 1.62), rng=seed + 100 + k)
            views.append(observe(X, rig[[v]], noise=1.0, rng=v)[0][:, 0])
        sync = find_sync(np.stack(views, 1), fps, rig.names, rig, max_offset=2.0)
        errors.append((np.abs(sync.offsets - off) * fps)[1:].tolist())
    e = np.array(errors)
    return {"errors_frames": np.round(e, 3).tolist(), "max_error_frames": round(float(e.max()), 3)}


def main(argv: list[str] | None = None) -> int:
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
    p.add_argument("--json")
    args = p.parse_args(argv)
    if args.synthetic:
        out = synthetic_trials(args.trials)
    else:
        keypoints, rig, fps = _real(args)
        out = real_trials(keypoints, rig, fps, args.trials, args.max_shift, args.window)
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
