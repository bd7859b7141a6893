"""Tabulate the last validation of training runs (their ``log.jsonl``) as Markdown.

Every run of one table validates on the same fixed held-out batches (CMU subject 03,
seeded, no keypoint removal), so their rows compare like with like.

With ``--mhp`` the columns are the second validation, on held-out MHP renders with the
real detector's 2D (runs trained with ``mhp_val``).

Usage: python -m rmpl.benchmarks.runs_table RUN_DIR [RUN_DIR ...] [--views 1,2,3,4,5] [--mhp]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rmpl.benchmarks._common import run_main
from rmpl.errors import InputError


def last_record(run: Path) -> dict:
    lines = (run / "log.jsonl").read_text().splitlines()
    if not lines:
        raise InputError(run / "log.jsonl", None, "a validation record", "none yet")
    return json.loads(lines[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--views", default="1,2,3,4,5")
    parser.add_argument("--mhp", action="store_true", help="the MHP validation columns")
    args = parser.parse_args(argv)
    pre = "mhp_" if args.mhp else ""
    views = [int(v) for v in args.views.split(",")]
    head = " | ".join(f"{v} views" for v in views)
    print(f"| run | params | steps | minutes | KP* MPJPE (mm): {head} |")
    print("|---|---:|---:|---:|" + "---:|" * len(views))
    tri = None
    for run in args.runs:
        rec = last_record(run)
        meta = json.loads((run / "config.json").read_text())
        params = meta.get("training", {}).get("parameters", 0)
        cells = " | ".join(f"{rec.get(f'{pre}kpstar_{v}v', float('nan')):.1f}" for v in views)
        print(
            f"| {run.name} | {params / 1e6:.2f}M | {rec['step']} | {rec['seconds'] / 60:.1f} "
            f"| {cells} |"
        )
        tri = tri or rec
    key = pre + "triangulation_kpstar_{}v"
    cells = " | ".join(f"{tri[key.format(v)]:.1f}" if key.format(v) in tri else "—" for v in views)
    print(f"| DLT (triangulable joints only) | | | | {cells} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
