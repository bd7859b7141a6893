"""Measure frames/s of the lifter presets and of triangulation, and peak memory.

A frame is one person seen by V views. Example: rmpl bench --views 1,2,4,8 --out bench.md

With --run: frames/s of rmpl run's whole chain on a trial, stage by stage (read, 3D,
report, view check, files), each case in a fresh process; --baseline SRC runs another
source tree beside it and --compare checks that both give the same outputs (1e-6 m):
  rmpl bench --run --calib shelf_dev/calibration.json --keypoints shelf_dev \
      --baseline /tmp/base/src --compare --out speed.md
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rmpl.io.atomic import atomic_path


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--presets", default="default,paper", help="comma-separated: default, paper, small, tiny"
    )
    parser.add_argument("--views", default="1,2,3,4,5,6,7,8")
    parser.add_argument("--batches", default="1,8,64,512")
    parser.add_argument(
        "--backends", default="torch,onnx", help="torch and/or onnx (needs rmpl[fast])"
    )
    parser.add_argument("--seconds", type=float, default=0.5, help="minimum timing per cell")
    parser.add_argument(
        "--long", type=int, default=10000, help="frames of the memory test sequence (0 = skip)"
    )
    parser.add_argument(
        "--temporal",
        type=int,
        default=10000,
        help="frames of the track lifted by the temporal model, 4 views (0 = skip)",
    )
    parser.add_argument("--out", default=None, help="write the Markdown tables here")
    from rmpl.benchmarks.speed import add_arguments

    parser.add_argument(
        "--run",
        action="store_true",
        dest="chain",
        help="time rmpl run's chain on --calib / --keypoints",
    )
    add_arguments(parser.add_argument_group("--run"), required=False, out=False)
    parser.set_defaults(run=run)


def _ints(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"expected comma-separated integers, got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    import os

    if args.chain:
        from rmpl.benchmarks.speed import run as run_chain

        return run_chain(args)

    from rmpl.bench import (
        long_sequence_memory,
        markdown,
        peak_memory_mb,
        run_bench,
        temporal_track,
    )

    load_before = os.getloadavg()
    rows = run_bench(
        presets=tuple(p.strip() for p in args.presets.split(",")),
        views=_ints(args.views),
        batches=_ints(args.batches),
        backends=tuple(b.strip() for b in args.backends.split(",")),
        min_time=args.seconds,
    )
    text = markdown(rows)
    if args.long:
        mb, seconds = long_sequence_memory(args.long)
        text += (
            f"\nLifting a {args.long}-frame, 4-view sequence with `Lifter.lift`: "
            f"{seconds:.1f} s, peak resident memory {mb:.0f} MB.\n"
        )
    if args.temporal:
        fps, mb = temporal_track(args.temporal)
        text += (
            f"\nThe temporal model on one {args.temporal}-frame, 4-view track "
            f"(`TemporalLifter.lift_track`): {fps:.0f} frames/s, peak resident memory "
            f"{mb:.0f} MB.\n"
        )
    text += f"\nPeak resident memory of the whole benchmark process: {peak_memory_mb():.0f} MB.\n"
    load_after = os.getloadavg()
    text += (
        f"\nMachine: {os.cpu_count()} CPUs; load average (1 min) {load_before[0]:.2f} before, "
        f"{load_after[0]:.2f} after (other work running at the same time slows every cell).\n"
    )
    print(text)
    if args.out:
        with atomic_path(Path(args.out)) as tmp:
            tmp.write_text(text)
    return 0
