"""Train the temporal model's candidates and its design ablations (configs/temporal.toml).

The shipped recipe ``B_fused`` (1,200 steps), then design ablations at 400 steps, each
``configs/temporal.toml`` with one change. ``--with-first`` also runs the first candidate
(``A_base``: per-frame answers as the starting points, no fused start, lr 5e-4), which
was stopped at step 600 when its validation showed no gain. Resumable: run it again after a
kill.

    python -m rmpl.benchmarks.temporal_ablations SEQBANK.npz RUNS [--with-first] [--dry-run]

SEQBANK is ``rmpl poses PATH/cmu_mocap --sequences --out SEQBANK.npz``. Tabulate with
``python -m rmpl.benchmarks.temporal_table RUNS/t``; score on held-out windows with
``python -m rmpl.benchmarks.temporal_synthetic``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rmpl.benchmarks._common import run_commands, run_main, toml_string

SHORT = ["steps=400", "val_every=200"]
IID_NOISE = [
    "noise.burst_rate=0.0",
    "noise.swap_rate=0.0",
    "noise.flip_rate=0.0",
    "noise.identity_rate=0.0",
    "noise.gap_rate=0.0",
    "noise.corr_scale=0.0",
    "noise.iid_scale=1.0",
]
#: name -> --set overrides of configs/temporal.toml, in the order they run.
RUNS = {
    "B_fused": [],
    "C_w48_400": SHORT,
    "F_nobody_400": SHORT + ["model.body_token=false"],
    "I_nofused_400": SHORT + ["model.fused_start=false"],
    "G_iidnoise_400": SHORT + IID_NOISE,
    "D_w24_400": SHORT + ["model.window=24"],
    "E_w96_400": SHORT + ["model.window=96", "batch_size=6"],
    # the per-frame model fine-tuned too, at about C's CPU time
    "H_finetune": SHORT + ["model.frozen_encoder=false", "steps=100", "val_every=100"],
}
FIRST = {
    "A_base": [
        "model.interpolate_valid=false",
        "model.body_token=false",
        "model.fused_start=false",
        "lr=5e-4",
    ]
}


def commands(bank: Path, runs: Path, with_first: bool = False) -> list[list[str]]:
    """Every ``rmpl train`` command, in order."""
    todo = (FIRST if with_first else {}) | RUNS
    out = []
    for name, overrides in todo.items():
        sets = [f"sequences={toml_string(bank)}", *overrides]
        out.append(
            ["train", "configs/temporal.toml", "--out", str(runs / "t" / name)]
            + [x for s in sets for x in ("--set", s)]
        )
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank", type=Path, help="the sequence bank (rmpl poses --sequences)")
    ap.add_argument("runs", type=Path, nargs="?", default=Path("runs"))
    ap.add_argument("--with-first", action="store_true", help="also the first candidate A_base")
    ap.add_argument("--dry-run", action="store_true", help="print the commands only")
    a = ap.parse_args(argv)
    return run_commands(commands(a.bank, a.runs, a.with_first), a.dry_run)


if __name__ == "__main__":
    raise SystemExit(run_main(main))
