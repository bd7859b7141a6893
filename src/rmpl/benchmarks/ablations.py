"""Train the thesis ablations, the MHP-source runs and the shipped model's candidates.

Every ablation is the base recipe with one change, at an equal short budget (600 steps of
128 samples, one torch thread), validated on the same fixed batches of held-out CMU subject
03. The base recipe is ``configs/default.toml`` without robust ray intersections and without
MHP renders (``model.robust_anchor=0``, ``mhp=[]``): the runs pin it. Then the two presets at
an equal budget of wall time, the full-length candidates, and the shipped recipe itself.
Resumable: run it again after a kill.

    python -m rmpl.benchmarks.ablations BANK.npz RUNS [--mhp-train DIR --mhp-val DIR]
        [--mhp-train2 DIR] [--dry-run]

BANK is ``rmpl poses PATH/cmu_mocap --out BANK.npz``; the MHP sets come from
``python -m rmpl.benchmarks.mhp_sets`` (the runs that need them are skipped without them).
Tabulate with ``python -m rmpl.benchmarks.runs_table RUNS/abl/*`` (or ``RUNS/mhp/*``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rmpl.benchmarks._common import run_commands, run_main, toml_string

#: The one-change ablations: name -> the --set overrides on the base recipe.
ABLATIONS = {
    "base": [],
    "no_conf": ["model.confidence=false"],
    "recenter_only": ["model.geometric=false"],
    "literal": ["model.geometric=false", "model.recenter=false"],
    "maxv2": ["max_views=2"],
    "maxv3": ["max_views=3"],
    "maxv8": ["max_views=8"],
    "calib_aug": ["sampler.calib_noise_deg=2.0", "sampler.calib_noise_m=0.02"],
    "pixels": ['model.inputs="pixels"', "model.geometric=false", "model.recenter=false"],
    "pixels_calib": [
        'model.inputs="pixels+calib"',
        "model.geometric=false",
        "model.recenter=false",
    ],
    "mlp": ['model.architecture="mlp"', "model.geometric=false"],
    "drop04": ["sampler.drop_rate=0.4"],
}


def _sets(*pairs: str) -> list[str]:
    return [x for pair in pairs for x in ("--set", pair)]


def short_run(bank: Path, runs: Path, name: str, overrides: list[str]) -> list[str]:
    """The base recipe at the ablations' budget with ``overrides``, into ``runs/name``."""
    base = [f"poses={toml_string(bank)}", "steps=600", "batch_size=128", "val_every=200"]
    base += ["threads=1", "model.robust_anchor=0", "mhp=[]"]
    return ["train", "configs/default.toml", "--out", str(runs / name), *_sets(*base, *overrides)]


def mhp_runs(train: Path, val: Path, train2: Path | None) -> dict[str, list[str]]:
    """The training-source runs: parametric, MHP renders, mixes, fitted noise, robust rays."""
    v, one, noise = f"mhp_val={toml_string(val)}", f'mhp=["{train}"]', train / "noise.toml"
    out = {
        "B_parametric": [v],
        "C_mhp": [v, one],
        "D_mix": [v, one, "mhp_weight=0.5"],
        "E_fitted": [v, f"noise_file={toml_string(noise)}"],
        "F_mix_fitted": [v, one, "mhp_weight=0.5", f"noise_file={toml_string(noise)}"],
    }
    if train2 is not None:
        both = f'mhp=["{train}","{train2}"]'
        out |= {
            "C2_mhp": [v, both],
            "D2_mix": [v, both, "mhp_weight=0.5"],
            "G_random": [v, "sampler.noise_randomize=1.0"],
            "H2_mix_random": [v, both, "mhp_weight=0.5", "sampler.noise_randomize=1.0"],
            "K_robust": [v, "model.robust_anchor=3"],
            "L2_mix_robust": [v, both, "mhp_weight=0.5", "model.robust_anchor=3"],
        }
    return out


def long_runs(bank: Path, runs: Path, train, val, train2) -> list[list[str]]:
    """The presets at equal wall time, the full-length candidates and the shipped recipe."""
    poses = f"poses={toml_string(bank)}"
    out = [
        ["train", "configs/default.toml", "--out", str(runs / "eq/small")]
        + _sets(poses, "model.robust_anchor=0", "steps=700", "batch_size=256")
        + _sets("val_every=350", "threads=1"),
        ["train", "configs/paper.toml", "--out", str(runs / "eq/paper")]
        + _sets(poses, "steps=250", "batch_size=32", "val_every=125", "lr=3e-4", "threads=1"),
    ]
    if train is not None:
        mix = [poses, f'mhp=["{train}"]', "mhp_weight=0.5", f"mhp_val={toml_string(val)}"]
        mix += ["steps=2500"]
        out.append(
            ["train", "configs/default.toml", "--out", str(runs / "default_mix")]
            + _sets(*mix, "threads=1", "model.robust_anchor=0")
        )
        out.append(
            ["train", "configs/default.toml", "--out", str(runs / "default_mix_drop04")]
            + _sets(*mix, "sampler.drop_rate=0.4", "threads=2", "model.robust_anchor=0")
        )
    out.append(  # the first shipped recipe on today's bank (a provenance check)
        ["train", "configs/default.toml", "--out", str(runs / "default_today")]
        + _sets(poses, "steps=4500", "model.robust_anchor=0", "mhp=[]")
    )
    if train2 is not None:  # the shipped recipe, and the same with keypoint removal 0.4
        both = [poses, f'mhp=["{train}","{train2}"]', f"mhp_val={toml_string(val)}"]
        out.append(
            ["train", "configs/default.toml", "--out", str(runs / "default_v2")] + _sets(*both)
        )
        out.append(
            ["train", "configs/default.toml", "--out", str(runs / "default_v2_drop04")]
            + _sets(*both, "sampler.drop_rate=0.4")
        )
    return out


def commands(bank: Path, runs: Path, train=None, val=None, train2=None) -> list[list[str]]:
    """Every ``rmpl`` command of the ablations, in order."""
    out = [short_run(bank, runs, f"abl/{n}", o) for n, o in ABLATIONS.items()]
    if train is not None:
        mhp = mhp_runs(train, val, train2)
        fitted = list(mhp).index("E_fitted")
        out += [short_run(bank, runs, f"mhp/{n}", o) for n, o in list(mhp.items())[:fitted]]
        if not (train / "noise.toml").exists():
            out.append(["generate", "--stats", str(train)])  # writes its noise.toml
        out += [short_run(bank, runs, f"mhp/{n}", o) for n, o in list(mhp.items())[fitted:]]
    return out + long_runs(bank, runs, train, val, train2)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank", type=Path, help="the pose bank (rmpl poses)")
    ap.add_argument("runs", type=Path, help="the folder the runs go to")
    ap.add_argument("--mhp-train", type=Path, default=None)
    ap.add_argument("--mhp-val", type=Path, default=None)
    ap.add_argument("--mhp-train2", type=Path, default=None)
    ap.add_argument("--dry-run", action="store_true", help="print the commands only")
    a = ap.parse_args(argv)
    if (a.mhp_train is None) != (a.mhp_val is None):
        ap.error("--mhp-train and --mhp-val go together")
    cmds = commands(a.bank, a.runs, a.mhp_train, a.mhp_val, a.mhp_train2)
    return run_commands(cmds, a.dry_run)


if __name__ == "__main__":
    raise SystemExit(run_main(main))
