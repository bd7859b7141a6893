"""Speed of one trial: ``rmpl run``'s whole chain, stage by stage, beside another version.

Each case is one ``rmpl run`` (its options as typed, e.g. ``--method robust``) on the same
calibration and 2D. Every run is a fresh Python process; the heavy libraries (torch,
onnxruntime, scipy, ...) are imported first and timed apart ("imports"): the chain's
frames/s is the number of frames divided by the time from reading the inputs to the last
file written, which is what a long recording converges to. The whole command's time
(imports included) is reported beside it.

``--baseline SRC`` runs a second source tree (a folder holding ``rmpl/``, e.g. another
commit's ``src/`` from ``git archive``) on the same cases in the same benchmark, the two
alternating run by run so that both see the same load on the machine. ``--compare`` checks
each case's outputs against the baseline's (or against ``--reference DIR/<case>``): every
array of poses.npz to ``--tolerance`` metres (integer and text arrays exactly, NaN where
NaN), and report.json's figures to the same tolerance.

Example (the side-by-side measurement of docs/results.md)::

    mkdir -p /tmp/base && git archive 9db8ae6 src | tar -x -C /tmp/base
    python -m rmpl.benchmarks.speed --calib ../shared/data/shelf_dev/calibration.json \\
        --keypoints ../shared/data/shelf_dev --baseline /tmp/base/src --repeat 3 --compare

The same is ``rmpl bench --run ...`` with these options.

``--detect VIDEO ...`` times 2D detection instead: the first ``--frames`` frames of each
video (decoding included), with the videos shared out among 1, 2, ... worker processes
(``--workers``) running at once: frames/s per camera and for all cameras together::

    python -m rmpl.benchmarks.speed --detect DEMO/videos/cam01.mp4 DEMO/videos/cam02.mp4 \\
        --frames 100 --workers 1,2
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["CASES", "compare_outputs", "main", "markdown"]

#: The three paths of ``rmpl run`` on a recording without a frame rate (Shelf): robust
#: triangulation, the per-frame lifter, and the temporal model (which needs a frame rate).
CASES = {
    "robust": "--method robust",
    "per-frame": "--method rmpl",
    "temporal": "--method rmpl --fps 25",
}

#: Stages timed in each run, (label, dotted function): wrapped wherever the function is
#: bound in a loaded rmpl module. Nested stages count within their parent.
STAGES = (
    ("read", "rmpl.cli._common.load_calibration_and_2d"),
    ("3D", "rmpl.pipeline.runner.run_with_floor"),
    ("  associate", "rmpl.pipeline.runner.associate_frames"),
    ("  floor", "rmpl.pipeline.runner.estimate_floor"),
    ("  per-frame 3D (lifter or triangulation)", "rmpl.pipeline.runner.estimate"),
    ("  track", "rmpl.pipeline.runner.track_index"),
    ("  outliers, gaps, filter", "rmpl.pipeline.runner.smooth"),
    ("  temporal model", "rmpl.pipeline.tracklift.lift_tracks"),
    ("  ONNX sessions (export or cache, and start)", "rmpl.model.export._session"),
    ("write", "rmpl.pipeline.outputs.write_all"),
    ("  report", "rmpl.pipeline.report.build_report"),
    ("    view check", "rmpl.pipeline.consistency.check_views"),
    ("  poses files", "rmpl.io.poses.save_poses"),
)

#: Imported (and timed) before the run, so that both versions pay them outside the chain.
HEAVY = ("numpy", "torch", "onnxruntime", "onnx", "scipy.optimize", "scipy.signal", "tqdm")

_DRIVER = r"""
import json, sys, time
t0 = time.perf_counter()
spec = json.loads(sys.argv[1])
import importlib
for name in spec["heavy"]:
    try:
        importlib.import_module(name)
    except ImportError:
        pass
t_imports = time.perf_counter() - t0
import cProfile, functools, io, pstats
import rmpl.cli
times, depth, profiles = {}, {}, {}

def wrap(label, fn, top):
    @functools.wraps(fn)
    def inner(*a, **k):
        depth[label] = depth.get(label, 0) + 1
        prof = None
        if spec["profile"] and top and depth[label] == 1:
            prof = profiles.setdefault(label, cProfile.Profile())
            prof.enable()
        start = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            if depth[label] == 1:
                times[label] = times.get(label, 0.0) + time.perf_counter() - start
            if prof is not None:
                prof.disable()
            depth[label] -= 1
    return inner

for label, dotted in spec["stages"]:
    mod_name, _, attr = dotted.rpartition(".")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError:
        continue
    fn = getattr(mod, attr, None)
    if fn is None:
        continue
    new = wrap(label.strip(), fn, not label.startswith(" "))
    for m in list(sys.modules.values()):
        if getattr(m, "__name__", "").startswith("rmpl") and getattr(m, attr, None) is fn:
            setattr(m, attr, new)
start = time.perf_counter()
code = rmpl.cli.main(["run", *spec["argv"]])
chain = time.perf_counter() - start
out = {"imports": t_imports, "chain": chain, "code": code, "stages": times, "profile": {}}
for label, prof in profiles.items():
    s = io.StringIO()
    pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(spec["profile"])
    out["profile"][label] = s.getvalue()
out["total"] = time.perf_counter() - t0
with open(spec["result"], "w") as f:
    json.dump(out, f)
"""


_DETECT = r"""
import itertools, json, sys, time
spec = json.loads(sys.argv[1])
from rmpl.pipeline import detect2d
det, _ = detect2d._make_detector(spec["detector"])
out = []
for path in spec["videos"]:
    info = detect2d.probe_video(path)
    n = min(spec["frames"], info.num_frames)
    start = time.perf_counter()
    frames = itertools.islice(detect2d.video_frames(info), n)
    kp, _ = detect2d._detect_stream(frames, n, det, 8, "", False)
    out.append({"video": path, "frames": n, "seconds": time.perf_counter() - start,
                "size": list(info.size)})
det.close()
print(json.dumps(out))
"""


def detect_scaling(videos: list[str], frames: int, workers: list[int], detector: str) -> str:
    """2D detection frames/s with the videos shared out among ``w`` processes at once, for
    each ``w`` in ``workers``: a Markdown table (per camera and all together)."""
    rows = []
    for w in workers:
        groups = [videos[i::w] for i in range(w) if videos[i::w]]
        start = time.perf_counter()
        procs = [
            subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    _DETECT,
                    json.dumps({"videos": g, "frames": frames, "detector": detector}),
                ],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )  # fmt: skip
            for g in groups
        ]
        done = [p.communicate() for p in procs]
        wall = time.perf_counter() - start
        per_process = []
        for proc, (out, err) in zip(procs, done, strict=True):
            if proc.returncode != 0:
                raise RuntimeError(f"detection failed:\n{err.strip()[-800:]}")
            per_process.append(json.loads(out.strip().splitlines()[-1]))
        cams = [c for group in per_process for c in group]
        total = sum(c["frames"] for c in cams)
        busy = max(sum(c["seconds"] for c in group) for group in per_process)
        per_cam = " / ".join(f"{c['frames'] / c['seconds']:.1f}" for c in cams)
        size = "x".join(str(x) for x in cams[0]["size"])
        rows.append(
            f"| {w} | {len(groups)} | {size} | {per_cam} | {total / busy:.1f} | {wall:.1f} |"
        )
    head = [
        f"2D detection ({detector}), the first {frames} frames of each video, decoding "
        "included; each worker a process detecting its videos one after another.",
        "",
        "| workers | processes | frame size | frames/s per camera | frames/s, all cameras "
        "| wall s (with start-up) |",
        "|---:|---:|---|---|---:|---:|",
    ]
    return "\n".join(head + rows) + "\n"


def _one_run(src: Path, argv: list[str], profile: int) -> dict:
    """One ``rmpl run`` in a fresh process on the code in ``src``: its timings."""
    with tempfile.TemporaryDirectory() as tmp:
        result = Path(tmp) / "result.json"
        spec = {
            "argv": argv,
            "heavy": HEAVY,
            "stages": STAGES,
            "profile": profile,
            "result": str(result),
        }
        env = dict(os.environ, PYTHONPATH=str(src))
        proc = subprocess.run(
            [sys.executable, "-c", _DRIVER, json.dumps(spec)],
            env=env,
            capture_output=True,
            text=True,
        )
        if proc.returncode != 0 or not result.is_file():
            tail = "\n".join(proc.stderr.strip().splitlines()[-5:])
            raise RuntimeError(f"rmpl run {' '.join(argv)} failed in {src}:\n{tail}")
        return json.loads(result.read_text())


def _frames(out: Path) -> int:
    with np.load(out / "poses.npz") as z:
        return int(z["points"].shape[0])


def _close(a, b, tol: float, where: str, diffs: list[str]) -> None:
    """Append to ``diffs`` where two JSON values differ (numbers: by more than ``tol``)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            diffs.append(f"{where}: keys {sorted(set(a) ^ set(b))}")
        for k in a.keys() & b.keys():
            _close(a[k], b[k], tol, f"{where}.{k}", diffs)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            diffs.append(f"{where}: {len(a)} vs {len(b)} items")
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            _close(x, y, tol, f"{where}[{i}]", diffs)
    elif isinstance(a, float | int) and isinstance(b, float | int) and not isinstance(a, bool):
        if not (a == b or abs(a - b) <= tol * max(1.0, abs(a), abs(b))):
            diffs.append(f"{where}: {a} vs {b}")
    elif a != b:
        diffs.append(f"{where}: {str(a)[:60]} vs {str(b)[:60]}")


def _max_gap(x: np.ndarray, y: np.ndarray) -> float:
    """Largest difference of two float arrays with NaN (and infinities) in the same places."""
    both = np.isfinite(x) & np.isfinite(y)
    if not np.array_equal(x[~both], y[~both], equal_nan=True):
        return np.inf
    return float(np.abs(x[both] - y[both]).max(initial=0.0))


def compare_outputs(new: Path, ref: Path, tol: float = 1e-6) -> list[str]:
    """Where the run folder ``new`` differs from ``ref``: poses.npz arrays (floats to
    ``tol``, NaN where NaN; others exactly) and report.json (numbers to ``tol``, relative
    for numbers above 1). Empty when they agree."""
    diffs: list[str] = []
    with np.load(new / "poses.npz") as a, np.load(ref / "poses.npz") as b:
        if set(a.files) != set(b.files):
            diffs.append(f"poses.npz: arrays {sorted(set(a.files) ^ set(b.files))}")
        for k in sorted(set(a.files) & set(b.files)):
            x, y = a[k], b[k]
            if x.shape != y.shape:
                diffs.append(f"poses.npz {k}: shape {x.shape} vs {y.shape}")
            elif x.dtype.kind == "f" and x.size:
                if not np.array_equal(np.isnan(x), np.isnan(y)):
                    diffs.append(f"poses.npz {k}: NaN in different places")
                elif (gap := _max_gap(x, y)) > tol:
                    diffs.append(f"poses.npz {k}: max difference {gap:.3g}")
            elif not np.array_equal(x, y):
                diffs.append(f"poses.npz {k}: {int((x != y).sum())} entries differ")
    ra = json.loads((new / "report.json").read_text())
    rb = json.loads((ref / "report.json").read_text())
    _close(ra, rb, tol, "report.json", diffs)
    return diffs


def _stats(runs: list[dict], frames: int) -> dict:
    """Median seconds (and frames/s) per stage over repeated runs."""
    labels = {k for r in runs for k in r["stages"]}
    med = {k: float(np.median([r["stages"].get(k, 0.0) for r in runs])) for k in labels}
    chain = float(np.median([r["chain"] for r in runs]))
    return {
        "frames": frames,
        "chain": chain,
        "fps": frames / chain,
        "total": float(np.median([r["total"] for r in runs])),
        "imports": float(np.median([r["imports"] for r in runs])),
        "stages": med,
    }


def markdown(results: dict, labels: list[str]) -> str:
    """One table per case: seconds and frames/s per stage, one column pair per version."""
    lines = []
    for case, by_version in results.items():
        frames = next(iter(by_version.values()))["frames"]
        lines += [f"### {case} ({frames} frames)", ""]
        head = "| stage | " + " | ".join(f"{v} s | {v} frames/s" for v in labels) + " |"
        lines += [head, "|---" + "|---:" * 2 * len(labels) + "|"]
        rows = [("chain (read to last file)", "chain")]
        rows += [(lab, lab.strip()) for lab, _ in STAGES]
        for text, key in rows:
            cells = []
            for v in labels:
                st = by_version[v]
                sec = st["chain"] if key == "chain" else st["stages"].get(key)
                cells += ["-", "-"] if not sec else [f"{sec:.2f}", f"{st['frames'] / sec:.0f}"]
            if any(c != "-" for c in cells):
                lines.append(f"| {text} | " + " | ".join(cells) + " |")
        tot = " | ".join(f"{by_version[v]['total']:.2f} | -" for v in labels)
        imp = " | ".join(f"{by_version[v]['imports']:.2f} | -" for v in labels)
        lines += [f"| imports (before the chain) | {imp} |", f"| whole process | {tot} |", ""]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rmpl.benchmarks.speed",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_arguments(p, required=False)
    return p


def add_arguments(p, required: bool = True, out: bool = True) -> None:
    """The benchmark's options (shared with ``rmpl bench --run``, where ``--calib`` and
    ``--keypoints`` are checked by :func:`run` and ``--out`` is ``rmpl bench``'s own)."""
    p.add_argument("--calib", required=required, help="calibration of the trial")
    p.add_argument("--keypoints", nargs="+", required=required, help="the trial's 2D")
    p.add_argument(
        "--case",
        action="append",
        default=None,
        metavar="NAME=OPTIONS",
        help="a run to time, e.g. robust='--method robust' (repeatable; default: "
        + "; ".join(f"{k}='{v}'" for k, v in CASES.items())
        + ")",
    )
    p.add_argument("--baseline", default=None, help="another source tree (holding rmpl/)")
    p.add_argument("--repeat", type=int, default=3, help="runs per case and version (median)")
    p.add_argument("--profile", type=int, default=0, help="functions per stage in a profile run")
    p.add_argument("--compare", action="store_true", help="check outputs against the baseline")
    p.add_argument("--reference", default=None, help="compare with REFERENCE/<case>/ instead")
    p.add_argument("--tolerance", type=float, default=1e-6, help="metres (default 1e-6)")
    p.add_argument("--work", default=None, help="keep the run folders here (default: temporary)")
    p.add_argument("--detect", nargs="+", default=None, help="time 2D detection on these videos")
    p.add_argument("--frames", type=int, default=100, help="--detect: frames per video")
    p.add_argument("--workers", default="1,2", help="--detect: worker processes to compare")
    p.add_argument("--detector", default="blazepose-multi", help="--detect: the 2D detector")
    if out:
        p.add_argument("--out", default=None, help="write the Markdown here")


def _cases(given: list[str] | None) -> dict[str, list[str]]:
    if not given:
        return {k: shlex.split(v) for k, v in CASES.items()}
    out = {}
    for item in given:
        name, sep, opts = item.partition("=")
        if not sep or not name:
            raise SystemExit(f"--case: expected NAME=OPTIONS, got {item!r}")
        out[name] = shlex.split(opts)
    return out


def run(args: argparse.Namespace) -> int:
    """Time every case on each version; print (and write) the tables; 1 if outputs differ."""
    if args.detect:
        load0 = os.getloadavg()[0]
        workers = [int(w) for w in args.workers.split(",") if w.strip()]
        text = detect_scaling(args.detect, args.frames, workers, args.detector)
        text += f"\nLoad average (1 min) {load0:.2f} before, {os.getloadavg()[0]:.2f} after.\n"
        return _emit(text, args.out)
    if not args.calib or not args.keypoints:
        from rmpl.errors import InputError

        raise InputError(None, "--calib/--keypoints", "the trial to time (both)", "missing")
    this = Path(__file__).resolve().parents[2]
    versions = {"this": this}
    if args.baseline:
        versions = {"baseline": Path(args.baseline).resolve(), **versions}
    work = Path(args.work or tempfile.mkdtemp(prefix="rmpl-speed-"))
    load0 = os.getloadavg()[0]
    results: dict[str, dict] = {}
    problems: list[str] = []
    inputs = ["--calib", args.calib, "--keypoints", *args.keypoints, "--no-pictures"]
    for case, opts in _cases(args.case).items():
        runs: dict[str, list[dict]] = {v: [] for v in versions}
        for i in range(max(1, args.repeat) + (1 if args.profile else 0)):
            for v, src in versions.items():  # alternate: both see the same load
                out = work / v / case
                prof = args.profile if i == args.repeat else 0
                r = _one_run(src, [*inputs, *opts, "--out", str(out)], prof)
                if prof:
                    runs[v + " profile"] = [r]
                else:
                    runs[v].append(r)
        results[case] = {v: _stats(runs[v], _frames(work / v / case)) for v in versions}
        for v in versions:
            for label, text in runs.get(v + " profile", [{}])[0].get("profile", {}).items():
                results[case][v].setdefault("profiles", {})[label] = text
        if args.compare or args.reference:
            ref = Path(args.reference) / case if args.reference else work / "baseline" / case
            diffs = compare_outputs(work / "this" / case, ref, args.tolerance)
            problems += [f"{case}: {d}" for d in diffs]
            print(f"{case}: outputs {'differ' if diffs else 'agree'} with {ref}", file=sys.stderr)
    text = markdown(results, list(versions))
    load1 = os.getloadavg()[0]
    text += (
        f"\nMachine: {os.cpu_count()} CPUs; load average (1 min) {load0:.2f} before, "
        f"{load1:.2f} after; median of {args.repeat} runs per case and version.\n"
    )
    if args.compare or args.reference:
        text += "\nOutputs: " + ("; ".join(problems) if problems else "identical to within ")
        text += "" if problems else f"{args.tolerance:g} m (poses.npz, report.json).\n"
    for case, by_version in results.items():
        for v, st in by_version.items():
            for label, prof in st.get("profiles", {}).items():
                text += f"\n#### Profile: {case}, {v}, {label}\n\n```\n{prof.strip()}\n```\n"
    _emit(text, args.out)
    return 1 if problems else 0


def _emit(text: str, out: str | None) -> int:
    print(text)
    if out:
        from rmpl.io.atomic import atomic_path

        with atomic_path(Path(out)) as tmp:
            tmp.write_text(text)
    return 0


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
