"""The benchmarks' one entry point: discovery, ``rmpl benchmark``, every module's ``--help``."""

from __future__ import annotations

import importlib

import pytest

import rmpl.benchmarks as benchmarks
from rmpl.cli import build_parser, main

NAMES = sorted(benchmarks.available())


def test_every_module_is_listed_with_its_summary():
    names = benchmarks.available()
    assert {"foot_eval", "temporal_mhp", "ablations"} <= set(names)
    assert not any(n.startswith("_") for n in names)
    assert all(summary and not summary.startswith(" ") for summary in names.values())


@pytest.mark.parametrize("name", NAMES)
def test_each_module_has_main_and_help(name, capsys):
    module = importlib.import_module(f"rmpl.benchmarks.{name}")
    assert module.__doc__.strip().splitlines()[0] == benchmarks.available()[name]
    with pytest.raises(SystemExit) as e:
        module.main(["--help"])
    assert e.value.code == 0
    assert capsys.readouterr().out


def test_a_module_added_to_the_package_appears(tmp_path, monkeypatch):
    (tmp_path / "zz_new.py").write_text(
        '"""Count to three."""\n\ndef main(argv=None):\n    print(1, 2, 3)\n    return 0\n'
    )
    monkeypatch.setattr(benchmarks, "__path__", [*benchmarks.__path__, str(tmp_path)])
    assert benchmarks.available()["zz_new"] == "Count to three."
    assert benchmarks.run("zz_new", []) == 0


def test_rmpl_benchmark_lists_them(capsys):
    assert main(["benchmark"]) == 0
    out = capsys.readouterr().out
    for name in NAMES:
        assert f"{name} " in out
    assert benchmarks.available()["foot_eval"] in out


def test_rmpl_benchmark_passes_the_arguments_on(capsys):
    with pytest.raises(SystemExit) as e:
        main(["benchmark", "runs_table", "--help"])
    assert e.value.code == 0
    assert "log.jsonl" in capsys.readouterr().out


def test_an_unknown_benchmark_is_one_line_and_exit_2(capsys):
    assert main(["benchmark", "no_such_thing"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no_such_thing" in err and "foot_eval" in err


@pytest.mark.parametrize("name", ["ablations", "temporal_ablations", "mhp_sets"])
def test_the_training_sequences_are_valid_rmpl_commands(name, tmp_path, capsys):
    argv = {
        "ablations": ["bank.npz", str(tmp_path), "--mhp-train", "a", "--mhp-val", "b"],
        "temporal_ablations": ["seqbank.npz", str(tmp_path), "--with-first"],
        "mhp_sets": ["mocap", str(tmp_path)],
    }[name]
    assert benchmarks.run(name, [*argv, "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) >= 5 and not any(tmp_path.iterdir())  # nothing ran
    parser = build_parser()
    module = importlib.import_module(f"rmpl.benchmarks.{name}")
    for command in module.commands(*module_args(name, tmp_path)):
        parser.parse_args(command)  # every option exists


def module_args(name, tmp_path):
    from pathlib import Path

    return {
        "ablations": (Path("bank.npz"), tmp_path, Path("a"), Path("b"), Path("c")),
        "temporal_ablations": (Path("seqbank.npz"), tmp_path, True),
        "mhp_sets": (Path("mocap"), tmp_path, 6, 1, 3),
    }[name]
