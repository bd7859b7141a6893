"""The temporal runs' last validation records as a Markdown table (docs/results.md).

python -m rmpl.benchmarks.temporal_table RUNS/t
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rmpl.benchmarks._common import run_main

COLUMNS = [  # frames with some 2D (the per-frame model answers only those)
    ("temporal_seenframes_2v", "frame_kpstar_2v", "2 views"),
    ("hard_2v", "frame_hard_2v", "2 views, hard"),
    ("temporal_seenframes_3v", "frame_kpstar_3v", "3 views"),
    ("hard_3v", "frame_hard_3v", "3 views, hard"),
    ("temporal_seenframes_5v", "frame_kpstar_5v", "5 views"),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, help="a folder of temporal training runs (RUN/log.jsonl)")
    root = ap.parse_args(argv).runs
    head = " | ".join(c for _, _, c in COLUMNS)
    print(f"| run | steps | minutes | {head} | selection: mean 2/3/5, all frames |")
    print("|---|---:|---:|" + "---:|" * (len(COLUMNS) + 1))
    first = None
    for log in sorted(root.glob("*/log.jsonl")):
        r = json.loads(log.read_text().splitlines()[-1])
        if first is None:
            first = r
        cells = " | ".join(f"{r.get(k, float('nan')):.1f}" for k, _, _ in COLUMNS)
        mean = sum(r[f"kpstar_{v}v"] for v in (2, 3, 5)) / 3
        print(
            f"| {log.parent.name} | {r['step']} | {r['seconds'] / 60:.0f} | {cells} | {mean:.1f} |"
        )
    if first is not None:
        frame = " | ".join(f"{first.get(k, float('nan')):.1f}" for _, k, _ in COLUMNS)
        print(f"| per-frame model alone | — | — | {frame} | — |")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
