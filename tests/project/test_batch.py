"""Running a project: skip on resume, a failed trial among good ones, bad input per trial."""

from __future__ import annotations

import json
from pathlib import Path

from rmpl.cli import main
from rmpl.project import batch_exit_code, run_project
from tests.project.conftest import make_trial


def _state(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file below ``folder``: (size, modification time)."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _run(project: Path, out: Path, *argv: str):
    return run_project(project, out, list(argv), ray=False, progress=False)


def test_second_run_skips_unchanged_trials(walk_project, tmp_path):
    out = tmp_path / "out"
    first = _run(walk_project, out)
    assert [r.status for r in first] == ["done", "done"] and batch_exit_code(first) == 0
    before = _state(out / "t1")
    second = _run(walk_project, out)
    assert [r.status for r in second] == ["unchanged", "unchanged"]
    assert _state(out / "t1") == before  # not written again
    assert second[0].report["frames"]["count"] == first[0].report["frames"]["count"]
    # an option changed: that trial runs again, the other is still unchanged
    (walk_project / "t2" / "rmpl.toml").write_text("max-gap = 3\n")
    third = _run(walk_project, out)
    assert [r.status for r in third] == ["unchanged", "done"]
    # an input changed (size / time): it runs again
    kp = walk_project / "t1" / "keypoints.json"
    kp.write_text(kp.read_text() + " ")
    assert [r.status for r in _run(walk_project, out)] == ["done", "unchanged"]
    # the command line is an option too
    assert [r.status for r in _run(walk_project, out, "--min-track", "2")] == ["done", "done"]


def test_one_failed_trial_among_good_ones(walk_project, tmp_path):
    bad = make_trial(walk_project / "t3", keypoints=False)
    (bad / "keypoints.json").write_text('{"format": "rmpl.keypoints2d", "views": ')
    out = tmp_path / "out"
    results = _run(walk_project, out)
    status = {r.plan.name: r for r in results}
    assert status["t1"].status == status["t2"].status == "done"
    assert status["t3"].status == "failed" and "keypoints.json" in status["t3"].error
    assert "\n" not in status["t3"].error
    assert batch_exit_code(results) == 1
    assert (out / "t1" / "poses.npz").is_file() and not (out / "t3" / "poses.npz").exists()
    summary = json.loads((out / "summary.json").read_text())
    rows = {r["trial"]: r for r in summary["trials"]}
    assert rows["t3"]["status"] == "failed" and rows["t3"]["error"] == status["t3"].error
    assert rows["t1"]["people"] == 1 and rows["t1"]["frames"] == 60
    assert rows["t1"]["reprojection_px"] > 0 and rows["t1"]["report"] == "t1/report.md"
    assert "t3" in (out / "summary.md").read_text() and (out / "summary.html").is_file()
    # the failed trial is tried again next time; the good ones are unchanged
    again = {r.plan.name: r.status for r in _run(walk_project, out)}
    assert again == {"t1": "unchanged", "t2": "unchanged", "t3": "failed"}


def test_bad_input_is_one_line_per_trial_and_touches_no_other(walk_project, tmp_path):
    out = tmp_path / "out"
    _run(walk_project, out)
    before = _state(out / "t1")
    make_trial(walk_project / "empty", keypoints=False)
    (walk_project / "empty" / "rmpl.toml").write_text("max-gap = 3\n")  # no inputs
    (walk_project / "t2" / "rmpl.toml").write_text("max-gap = = 3\n")  # unreadable
    nocal = walk_project / "sub"  # its calib names a missing file
    make_trial(nocal)
    (nocal / "rmpl.toml").write_text('calib = "missing.toml"\n')
    (walk_project / "t1" / "keypoints.json").touch()  # t1 runs again, and fine
    results = {r.plan.name: r for r in _run(walk_project, out)}
    assert results["t1"].status == "done"
    for name, words in [("empty", "expected videos"), ("t2", "readable TOML"),
                        ("sub", "missing.toml")]:  # fmt: skip
        r = results[name]
        assert r.status == "failed" and words in r.error and "\n" not in r.error, (name, r.error)
    assert set(_state(out / "t1")) == set(before)  # t1's set, rewritten whole
    assert not (out / "empty").exists()
    assert (out / "t2" / "poses.npz").is_file()  # t2's previous outputs are left as they were


def test_no_calibration_anywhere(tmp_path):
    root = tmp_path / "p"
    make_trial(root / "t1")
    (r,) = _run(root, tmp_path / "out")
    assert r.status == "failed" and "calibration/" in r.error


def test_command(walk_project, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["batch", str(walk_project), "--out", str(out), "--no-ray", "--dry-run"]) == 0
    assert "t1: rmpl run --calib" in capsys.readouterr().out and not out.exists()
    argv = ["batch", str(walk_project), "--out", str(out), "--no-ray", "--max-gap", "4"]
    assert main(argv) == 0
    assert "--max-gap 4" in " ".join(json.loads((out / "t1" / "trial.json").read_text())["argv"])
    (walk_project / "t2" / "keypoints.json").write_text("[")
    assert main(argv) == 1
    assert "trial t2 failed" in capsys.readouterr().err
    assert main(["batch", str(tmp_path / "nothing"), "--no-ray"]) == 2
    assert main([*argv, "--fps", "-1"]) == 2


def test_pose2sim_config_in_the_summary(walk_project, tmp_path):
    (walk_project / "Config.toml").write_text(
        "[project]\nparticipant_height = 1.7\nparticipant_mass = 65.0\n"
        "exclude_from_batch = ['t2']\n"
    )
    out = tmp_path / "out"
    results = {r.plan.name: r for r in _run(walk_project, out)}
    assert results["t1"].status == "done" and results["t2"].status == "excluded"
    assert not (out / "t2").exists()
    rows = {r["trial"]: r for r in json.loads((out / "summary.json").read_text())["trials"]}
    assert rows["t1"]["given_heights_m"] == [1.7] and rows["t1"]["given_masses_kg"] == [65.0]
    assert len(rows["t1"]["heights_m"]) == 1 and rows["t1"]["heights_m"][0] > 1.0
    assert any("participant height" in n for n in rows["t1"]["notes"])
    assert batch_exit_code(list(results.values())) == 0
