"""Simulated against real footage: the shipped detector's scatter on a recording and its twin.

Real footage has no 2D truth, so both are measured the same way: each camera's detection of
each joint against the joint triangulated from the other cameras and projected into it
(the held-out-view error, :mod:`rmpl.evaluate.heldout`, median pixels, one person per view:
the most confident). On the real recording this includes the calibration's own error; on
the twin, the same rig (the recording's calibration, ``rmpl simulate --rig``) at the same
frame rate films one walking body, and the detector's true 2D error is measured too.

Example::

    rmpl benchmark simulate_realism --recording ../shared/data/pose2sim_videos/Demo_SinglePerson \\
        --out realism/
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rmpl.benchmarks._common import run_main


def _calibration(recording: Path) -> Path:
    from rmpl.errors import InputError

    found = sorted((recording / "calibration").glob("*.toml")) + sorted(
        (recording / "calibration").glob("*.qca.txt")
    )
    if not found:
        raise InputError(recording / "calibration", None, "a calibration file (.toml, .qca.txt)")
    return found[0]


def _one_person(kp) -> tuple[np.ndarray, np.ndarray]:
    """The most confident person of each view and frame: (T, V, J, 2), (T, V, J)."""
    mean = kp.scores.mean(-1)  # (T, V, P)
    best = np.argmax(mean, axis=-1)  # (T, V)
    T, V = best.shape
    t, v = np.meshgrid(np.arange(T), np.arange(V), indexing="ij")
    return kp.keypoints[t, v, best][..., :17, :], kp.scores[t, v, best][..., :17]


def heldout_px(kp, rig) -> float:
    """Median held-out-view error, pixels, of triangulation from all the other views."""
    from rmpl.evaluate.heldout import heldout_view_errors
    from rmpl.geometry.triangulate import triangulate

    x, s = _one_person(kp)
    ok = (s > 0).sum(-1) >= 8  # (T, V) the person is there
    x, s = np.where(ok[..., None, None], x, np.nan), np.where(ok[..., None], s, 0.0)

    def dlt(k, c, r):
        return triangulate(k, c, r, min_score=0.3).points

    ev = heldout_view_errors(x, s, rig, {"triangulation": dlt}, [len(rig) - 1])
    e = ev.px[len(rig) - 1]["triangulation"]
    return float(np.nanmedian(e))


def _twin(calib: Path, fps: float, seconds: str, sim: Path) -> tuple[float, dict]:
    """The recording's simulated twin: its held-out error and its true 2D scores."""
    from rmpl.cli import main as rmpl
    from rmpl.io.calibration import load_rig
    from rmpl.io.keypoints import load_keypoints
    from rmpl.pipeline.inputs import InputSpec, load_inputs
    from rmpl.simulate.scoring import _detection

    argv = ["simulate", "--rig", str(calib), "--people", "1", "--seconds", seconds]
    argv += ["--fps", f"{fps:g}", "--out", str(sim), "--no-progress"]
    print("rmpl " + " ".join(argv), flush=True)
    if rmpl(argv) != 0:
        raise SystemExit(f"the simulation {sim} failed")
    twin = load_rig(sim / "truth" / "calibration.toml")
    videos = [str(sim / "videos" / f"{n}.mp4") for n in twin.names]
    (sim / "chain").mkdir(exist_ok=True)
    load_inputs(InputSpec(str(sim / "truth" / "calibration.toml"), None, videos),
                sim / "chain" / "keypoints2d.npz")  # fmt: skip
    px = heldout_px(load_keypoints(sim / "chain" / "keypoints2d.npz"), twin)
    return px, _detection(sim, sim / "chain", list(twin.names))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="rmpl benchmark simulate_realism",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--recording", required=True, help="a folder with calibration/ and videos/")
    p.add_argument("--out", required=True, help="folder for the detections and the twin")
    p.add_argument("--seconds", default="5", help="length of the simulated twin (5)")
    args = p.parse_args(argv)
    from rmpl.io.keypoints import load_keypoints
    from rmpl.pipeline.detect2d import probe_video
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    recording, out = Path(args.recording), Path(args.out)
    calib = _calibration(recording)
    videos = sorted(str(v) for v in (recording / "videos").glob("*.mp4"))
    out.mkdir(parents=True, exist_ok=True)
    real = load_inputs(InputSpec(str(calib), None, videos), out / "real_keypoints2d.npz")
    rig = real.rig
    real_px = heldout_px(load_keypoints(out / "real_keypoints2d.npz"), rig)
    fps = probe_video(videos[0]).fps
    twin_px, true = _twin(calib, fps, args.seconds, out / "twin")
    print(f"\nrecording: {recording.name}, {len(rig)} cameras at {fps:g} frames/s\n")
    print("| footage | held-out-view error, median px | true 2D error, median px |")
    print("|---|---:|---:|")
    print(f"| real | {real_px:.1f} | unknown |")
    e = true["error_px"]
    print(
        f"| simulated twin | {twin_px:.1f} | {e['median']:.1f} (90th percentile "
        f"{e['p90']:.1f}; recall {100 * true['recall']:.0f}%) |"
    )
    print(f"\nsimulated / real held-out error: {twin_px / real_px:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
