"""rmpl.toml options per level, Pose2Sim's Config.toml, the command line."""

from __future__ import annotations

import argparse

import pytest

from rmpl.errors import InputError
from rmpl.project import options as opts
from rmpl.project.plan import plan_project


def _argv_value(argv: list[str], option: str) -> list[str] | None:
    if option not in argv:
        return None
    i = argv.index(option) + 1
    j = i
    while j < len(argv) and not argv[j].startswith("--"):
        j += 1
    return argv[i:j]


def test_every_rmpl_run_option_is_a_key():
    """The keys come from rmpl run's own parser: each of its options (but --out) is valid."""
    from rmpl.cli.run import register

    parser = argparse.ArgumentParser()
    register(parser)
    dests = {a.dest for a in parser._actions if a.option_strings and a.dest != "help"}
    assert set(opts.run_actions()) == dests
    assert "max_gap" in dests and "out" in dests


def test_trial_overrides_project_and_command_line_overrides_both(walk_project):
    (walk_project / "rmpl.toml").write_text(
        'method = "robust"\nmax-gap = 5\nno-pictures = true\nmin_track = 2\n'
    )
    (walk_project / "t1" / "rmpl.toml").write_text('method = "triangulate"\nno-pictures = false\n')
    out = walk_project / "out"
    plans = {p.name: p for p in plan_project(walk_project, out, opts.parse_command_line([]))}
    one, two = plans["t1"].argv, plans["t2"].argv
    assert _argv_value(one, "--method") == ["triangulate"] and "--no-pictures" not in one
    assert _argv_value(two, "--method") == ["robust"] and "--no-pictures" in two
    assert _argv_value(one, "--max-gap") == ["5"] and _argv_value(one, "--min-track") == ["2"]
    assert _argv_value(one, "--out") == [str(out / "t1")]
    cli = opts.parse_command_line(["--max-gap", "7", "--method=triangulate"])
    plans = {p.name: p for p in plan_project(walk_project, out, cli)}
    assert _argv_value(plans["t2"].argv, "--max-gap") == ["7"]
    assert _argv_value(plans["t2"].argv, "--method") == ["triangulate"]


def test_unknown_key_is_refused_with_file_and_key(tmp_path):
    path = tmp_path / "rmpl.toml"
    path.write_text('methd = "robust"\n')
    with pytest.raises(InputError) as e:
        opts.read_config(path)
    assert str(path) in str(e.value) and "methd" in str(e.value) and "\n" not in str(e.value)
    path.write_text('out = "elsewhere"\n')
    with pytest.raises(InputError, match="own folder"):
        opts.read_config(path)
    with pytest.raises(InputError, match="--methd"):
        opts.parse_command_line(["--methd", "robust"])


@pytest.mark.parametrize(
    "text, what",
    [
        ("fps = -3\n", "fps"),
        ('method = "fast"\n', "method"),
        ("no-pictures = 1\n", "true or false"),
        ("[run]\nfps = 3\n", "no tables"),
        ("fps = \n", "readable TOML"),
        ('keypoints = "a.json"\nvideos = "b.mp4"\n', "not allowed with"),
    ],
)
def test_bad_values_are_refused(tmp_path, text, what):
    path = tmp_path / "rmpl.toml"
    path.write_text(text)
    with pytest.raises(InputError, match=what) as e:
        opts.read_config(path)
    assert str(path) in str(e.value)


def test_paths_are_relative_to_their_file(tmp_path):
    (tmp_path / "trial").mkdir()
    path = tmp_path / "trial" / "rmpl.toml"
    path.write_text('calib = "../rig.toml"\nvideos = ["a.mp4", "b.mp4"]\nfloor = "z=0"\n')
    raw = opts.read_config(path)
    assert raw["calib"] == [str(tmp_path / "trial" / "../rig.toml")]
    assert raw["videos"] == [str(tmp_path / "trial" / "a.mp4"), str(tmp_path / "trial" / "b.mp4")]
    assert raw["floor"] == ["z=0"]


def test_the_input_is_one_setting():
    merged = opts.merge({"videos": ["a.mp4"], "fps": ["30"]}, {"keypoints": ["k.json"]})
    assert merged == {"fps": ["30"], "keypoints": ["k.json"]}


def test_pose2sim_config_levels(tmp_path):
    session = tmp_path / "Config.toml"
    session.write_text(
        "[project]\nframe_rate = 60\nparticipant_height = [1.72, 1.6]\n"
        "participant_mass = 70.0\nexclude_from_batch = ['P01/Trial_3']\n"
        "[filtering.butterworth]\ncut_off_frequency = 6\n"
    )
    trial = tmp_path / "trial.toml"
    trial.write_text("[project]\nframe_rate = 100\nparticipant_height = 'auto'\n")
    s = opts.pose2sim_settings([session, trial])
    assert s.fps == 100.0 and s.heights is None and s.masses == [70.0]
    assert s.excluded == ["P01/Trial_3"]
    assert any("frame_rate" in n for n in s.notes) and any("mass" in n for n in s.notes)
    s = opts.pose2sim_settings([session])
    assert s.heights == [1.72, 1.6] and s.fps == 60.0
    trial.write_text("[project]\nframe_rate = 'auto'\n")  # the trial's: the input's own
    assert opts.pose2sim_settings([session, trial]).fps is None
    trial.write_text("[project]\nframe_rate = 'fast'\n")
    with pytest.raises(InputError, match="frame_rate"):
        opts.pose2sim_settings([session, trial])
    trial.write_text("[project]\nparticipant_mass = [true]\n")
    with pytest.raises(InputError, match="participant_mass"):
        opts.pose2sim_settings([session, trial])


def test_pose2sim_frame_rate_and_exclusion_in_a_plan(walk_project):
    (walk_project / "Config.toml").write_text(
        "[project]\nframe_rate = 25\nexclude_from_batch = ['t2']\n"
    )
    plans = {p.name: p for p in plan_project(walk_project, walk_project / "out")}
    assert _argv_value(plans["t1"].argv, "--fps") == ["25"]
    assert plans["t2"].excluded and not plans["t1"].excluded
    (walk_project / "t1" / "rmpl.toml").write_text("fps = 30\n")
    plans = {p.name: p for p in plan_project(walk_project, walk_project / "out")}
    assert _argv_value(plans["t1"].argv, "--fps") == ["30"]
