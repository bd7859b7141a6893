"""Planning curves from rmpl simulate: 3D by cameras, people calibration by walk, sync by rate.

Each part simulates its recordings once (``rmpl simulate``, resumed when run again),
detects the 2D once with the shipped detector, then varies one thing:

- ``cameras``: 8 cameras on a ring around 2 walking people; ``rmpl run`` through the true
  cameras on 1 to 8 of them, evenly spaced (their own 2D), rmpl's default and robust
  triangulation;
- ``duration``: 4 cameras around 2 walking people for 30 s; ``rmpl calibrate
  --from-people`` with the true lenses on the first 1, 2, 5, 10 and 30 s; and 10 s of 1
  and of 3 people. Each camera's rotation and centre error after aligning the worlds, the
  relative rotation error of every pair of cameras (no alignment: HumanCalib's measure),
  and the scale;
- ``sync``: 4 cameras started at random instants (up to 12 frames apart) at 25, 30, 60 and
  mixed 30, 30, 25, 60 frames/s, one person walking or running; ``rmpl sync --calib`` with
  the true cameras against the true offsets.

Example::

    rmpl benchmark simulate_plan --out plan/ --part cameras
    rmpl benchmark simulate_plan --out plan/ --part all --resolution 1280x720
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rmpl.benchmarks._common import run_main

DURATIONS = (1, 2, 5, 10, 30)


def _rmpl(argv: list[str]) -> int:
    from rmpl.cli import main

    print("rmpl " + " ".join(argv), flush=True)
    return main(argv)


def _simulate(folder: Path, options: list[str], args) -> Path:
    argv = [
        "simulate",
        *options,
        "--resolution",
        args.resolution,
        "--seed",
        args.seed,
        "--out",
        str(folder),
        "--no-progress",
    ]
    if _rmpl(argv) != 0:
        raise SystemExit(f"the simulation {folder} failed")
    return folder


def _detected(sim: Path):
    """The simulation's rig, frame rates and 2D (detected once, cached)."""
    from rmpl.io.calibration import load_rig
    from rmpl.io.keypoints import load_keypoints
    from rmpl.simulate.chain import _detect

    doc = json.loads((sim / "simulate.json").read_text(encoding="utf-8"))
    rig = load_rig(sim / "truth" / "calibration.toml")
    (sim / "chain").mkdir(exist_ok=True)
    fps = np.asarray(doc["rig"]["fps"], float)
    return rig, fps, load_keypoints(_detect(sim, sim / "chain", rig, fps, None))


def _subset(kp, rig, views, frames, folder: Path) -> tuple[Path, Path]:
    """Calibration and 2D of some views and the first ``frames`` frames, written."""
    from rmpl.geometry.camera import Rig
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    folder.mkdir(parents=True, exist_ok=True)
    sub = Keypoints2D(
        kp.keypoints[:frames, views],
        kp.scores[:frames, views],
        kp.skeleton,
        [kp.views[v] for v in views],
        np.asarray(kp.frames)[:frames],
        kp.fps,
    )
    save_keypoints(sub, folder / "keypoints2d.npz")
    save_rig(Rig(tuple(rig[v] for v in views)), folder / "calibration.toml")
    return folder / "calibration.toml", folder / "keypoints2d.npz"


def _score(poses_path: Path, truth) -> dict:
    from rmpl.io.poses import load_poses
    from rmpl.simulate.score import pose_scores
    from rmpl.simulate.scoring import _on_truth_frames, _same_joints

    if not poses_path.exists():
        return {}
    pred = _on_truth_frames(load_poses(poses_path), truth)
    pred, true, _ = _same_joints(pred, truth.points.astype(float))
    out = pose_scores(pred, true)["overall"]
    out["body_mpjpe_mm"] = pose_scores(pred[:, :, :17], true[:, :, :17])["overall"]["mpjpe_mm"]
    return out


def part_cameras(out: Path, args) -> list[str]:
    from rmpl.io.poses import load_poses

    sim = _simulate(
        out / "cameras8", ["--cameras", "8", "--people", "2", "--seconds", args.seconds], args
    )
    rig, fps, kp = _detected(sim)
    truth = load_poses(sim / "truth" / "poses.npz")
    rows = [
        "| cameras | rmpl MPJPE mm | body | PCK@150 | coverage | robust MPJPE mm | body | "
        "PCK@150 | coverage |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for n in range(1, len(rig) + 1):
        views = list(np.floor(np.arange(n) * len(rig) / n).astype(int))
        calib, kps = _subset(kp, rig, views, len(kp.frames), sim / "subsets" / f"n{n}")
        cells = [str(n)]
        for method in ("rmpl", "robust"):
            run = sim / "subsets" / f"n{n}" / method
            if not (run / "poses.npz").exists() and not (method == "robust" and n == 1):
                argv = ["run", "--calib", str(calib), "--keypoints", str(kps), "--fps"]
                argv += [f"{fps[0]:g}", "--out", str(run), "--no-pictures", "--formats", "npz"]
                _rmpl(argv + ([] if method == "rmpl" else ["--method", method]))
            o = _score(run / "poses.npz", truth)
            if not o or o.get("mpjpe_mm") is None:
                cells += ["-", "-", "-", "-"]
                continue
            cells += [
                f"{o['mpjpe_mm']:.1f}",
                f"{o['body_mpjpe_mm']:.1f}",
                f"{o['pck']['150']:.1f}%",
                f"{100 * o['coverage']:.0f}%",
            ]
        rows.append("| " + " | ".join(cells) + " |")
    return rows


def relative_rotation_errors(found, truth) -> list[float]:
    """The angle between found and true relative rotations of every pair of cameras,
    degrees (no alignment needed)."""
    from scipy.spatial.transform import Rotation

    out = []
    names = [n for n in truth.names if n in found.names]
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            fa, fb = found[found.names.index(a)], found[found.names.index(b)]
            ta, tb = truth[truth.names.index(a)], truth[truth.names.index(b)]
            d = (fb.R @ fa.R.T) @ (tb.R @ ta.R.T).T
            out.append(float(np.degrees(Rotation.from_matrix(d).magnitude())))
    return out


def _calibrate(sim: Path, rig, kp, seconds: float, fps: float, tag: str) -> dict:
    from rmpl.io.calibration import load_rig
    from rmpl.simulate.chain import _lenses_only
    from rmpl.simulate.score import calibration_errors

    folder = sim / "durations" / tag
    frames = int(round(seconds * fps))
    _, kps = _subset(kp, rig, list(range(len(rig))), frames, folder)
    found = folder / "found.toml"
    if not found.exists():
        argv = [
            "calibrate",
            "--from-people",
            "--calib",
            str(_lenses_only(sim, sim / "chain")),
            "--keypoints",
            str(kps),
            "--out",
            str(found),
            "--no-progress",
        ]
        _rmpl(argv)
    if not found.exists():
        return {"refused": True}
    f = load_rig(found)
    err = calibration_errors(f, rig)
    rel = relative_rotation_errors(f, rig)
    return {
        "rotation_max": err["rotation_deg"]["max"],
        "centre_max": err["centre_mm"]["max"],
        "scale": err["scale"],
        "relative_mean": float(np.mean(rel)),
        "relative_max": float(np.max(rel)),
    }


def part_duration(out: Path, args) -> list[str]:
    rows = [
        "| people | walk, s | relative rotation, deg (mean / max) | rotation, deg (max) | "
        "centre, mm (max) | scale |",
        "|---:|---:|---:|---:|---:|---:|",
    ]
    cases = [
        (2, "walk30", 30.0, DURATIONS),
        (1, "walk10-1", 10.0, (10,)),
        (3, "walk10-3", 10.0, (10,)),
    ]
    for people, name, length, durations in cases:
        sim = _simulate(
            out / name,
            ["--cameras", "4", "--people", str(people), "--seconds", f"{length:g}"],
            args,
        )
        rig, fps, kp = _detected(sim)
        for d in durations:
            r = _calibrate(sim, rig, kp, d, fps[0], f"{people}p-{d}s")
            if r.get("refused"):
                rows.append(f"| {people} | {d} | refused | | | |")
                continue
            rows.append(
                f"| {people} | {d} | {r['relative_mean']:.2f} / {r['relative_max']:.2f} | "
                f"{r['rotation_max']:.2f} | {r['centre_max']:.0f} | {r['scale']:.3f} |"
            )
    return rows


def part_sync(out: Path, args) -> list[str]:
    from rmpl.calibration.sync import read_sync
    from rmpl.simulate.score import sync_errors

    rows = [
        "| frame rates | motion | whole frames exact | largest error, frames | "
        "mean error, frames |",
        "|---|---|---|---:|---:|",
    ]
    for rates in ("25", "30", "60", "30,30,25,60"):
        for motion in ("walk", "run"):
            name = f"sync-{rates.replace(',', '-')}-{motion}"
            sim = _simulate(
                out / name,
                [
                    "--cameras",
                    "4",
                    "--people",
                    "1",
                    "--motion",
                    motion,
                    "--fps",
                    rates,
                    "--offsets",
                    "random:12",
                    "--seconds",
                    args.sync_seconds,
                ],
                args,
            )
            rig, fps, kp = _detected(sim)
            found = sim / "chain" / "sync_true_cameras.json"
            if not found.exists():
                _rmpl(
                    [
                        "sync",
                        "--calib",
                        str(sim / "truth" / "calibration.toml"),
                        "--keypoints",
                        str(sim / "chain" / "keypoints2d.npz"),
                        "--fps",
                        *[f"{f:g}" for f in fps],
                        "--out",
                        str(found),
                    ]
                )
            got = read_sync(found) if found.exists() else None
            e = sync_errors(got, read_sync(sim / "truth" / "sync.json"))
            if e["refused"]:
                rows.append(f"| {rates} | {motion} | refused | | |")
                continue
            errs = [abs(c["error_frames"]) for c in e["cameras"].values() if c]
            rows.append(
                f"| {rates} | {motion} | {'yes' if e['all_exact'] else 'no'} | "
                f"{max(errs):.2f} | {np.mean(errs):.2f} |"
            )
    return rows


PARTS = {"cameras": part_cameras, "duration": part_duration, "sync": part_sync}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="rmpl benchmark simulate_plan",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", required=True, help="folder of the simulations (resumed)")
    p.add_argument("--part", default="all", choices=[*PARTS, "all"])
    p.add_argument("--seconds", default="8", help="length of the cameras part's recording")
    p.add_argument("--sync-seconds", default="5", help="length of each sync recording")
    p.add_argument("--resolution", default="1280x720")
    p.add_argument("--seed", default="0")
    args = p.parse_args(argv)
    out = Path(args.out)
    for name, part in PARTS.items():
        if args.part in (name, "all"):
            rows = part(out, args)
            print(f"\n## {name}\n")
            print("\n".join(rows), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
