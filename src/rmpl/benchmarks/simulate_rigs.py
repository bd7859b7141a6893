"""rmpl simulate --run over several rigs: every stage's error, per rig, from pixels.

The rigs were chosen before any was run, to span what users build: a ring of 4 (the usual
lab), the same with a board sweep, 3 phones on an arc at three frame rates started at
random instants with a bystander, 4 high corner cameras filming a walker and a runner, 6
cameras around 3 people started at random instants, and 2 cameras. Each is ``rmpl simulate
... --run`` exactly as a user runs it (into ``OUT/<rig>/``; run again to resume), and the
table gathers each ``report.md``'s figures.

Example::

    rmpl benchmark simulate_rigs --out sims/ --seconds 10
    rmpl benchmark simulate_rigs --out sims/ --only ring4,arc3-mixed --resolution 1920x1080
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rmpl.benchmarks._common import run_main

#: name -> rmpl simulate options (the rig and its people).
RIGS: dict[str, list[str]] = {
    "ring4": ["--cameras", "4", "--people", "2"],
    "ring4-board": ["--cameras", "4", "--people", "2", "--board", "charuco:5x7:0.1:0.075"],
    "arc3-mixed": [
        "--rig",
        "arc",
        "--cameras",
        "3",
        "--fps",
        "30,25,60",
        "--offsets",
        "random:10",
        "--people",
        "1",
        "--bystander",
    ],
    "corners4-run": ["--rig", "corners", "--cameras", "4", "--people", "2", "--motion", "walk,run"],
    "ring6": ["--cameras", "6", "--people", "3", "--offsets", "random:15"],
    "ring2": ["--cameras", "2", "--people", "1", "--radius", "3.5"],
}


def _row(name: str, scores: dict) -> str:
    cal, sync, det = scores.get("calibration", {}), scores.get("sync") or {}, scores["detection"]
    rot = (cal.get("rotation_deg") or {}).get("max")
    ctr = (cal.get("centre_mm") or {}).get("max")
    cells = [name, cal.get("method", "-")]
    cells.append("refused" if rot is None else f"{rot:.2f} / {ctr:.0f}")
    if sync.get("refused") or not sync:
        cells.append("refused")
    else:
        cells.append(f"{sync['max_abs_error_frames']:.2f}")
    e = det.get("error_px") or {}
    cells.append(f"{100 * (det.get('recall') or 0):.0f}% / {e.get('median') or 0:.1f}")
    for method in ("rmpl", "robust"):
        for which in ("found", "true"):
            r = scores["3d"].get(f"{method} ({which} cameras)", {})
            o = r.get("overall") or {}
            cells.append("-" if o.get("mpjpe_mm") is None else f"{o['mpjpe_mm']:.0f}")
    ident = (scores["3d"].get("rmpl (found cameras)") or {}).get("identity") or {}
    cells.append(f"{ident.get('num_tracks', '-')} / {ident.get('num_people', '-')}")
    return "| " + " | ".join(cells) + " |"


HEADER = (
    "| rig | calibration | rotation deg / centre mm (max) | sync error, frames (max) | "
    "2D recall / median px | rmpl found | rmpl true | robust found | robust true | "
    "tracks / people |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="rmpl benchmark simulate_rigs",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", required=True, help="folder of the simulations (resumed)")
    p.add_argument("--seconds", default="10", help="each recording's length (10)")
    p.add_argument("--resolution", default="1280x720", help="every camera's (1280x720)")
    p.add_argument("--only", default=None, help="comma-separated rig names")
    p.add_argument("--seed", default="0")
    args = p.parse_args(argv)
    from rmpl.cli import main as rmpl
    from rmpl.errors import InputError

    names = list(RIGS) if args.only is None else args.only.split(",")
    unknown = [n for n in names if n not in RIGS]
    if unknown:
        raise InputError(None, "--only", f"rigs among {', '.join(RIGS)}", unknown)
    rows, out = [], Path(args.out)
    for name in names:
        folder = out / name
        argv_ = [
            "simulate",
            *RIGS[name],
            "--seconds",
            args.seconds,
            "--resolution",
            args.resolution,
            "--seed",
            args.seed,
            "--out",
            str(folder),
            "--run",
        ]
        print("rmpl " + " ".join(argv_), flush=True)
        code = rmpl(argv_)
        if code != 0:
            print(f"{name}: exit {code}", flush=True)
            continue
        scores = json.loads((folder / "scores.json").read_text(encoding="utf-8"))
        rows.append(_row(name, scores))
    print("\n3D: MPJPE mm over HALPE-26 through the found / the true cameras.\n")
    print(HEADER)
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
