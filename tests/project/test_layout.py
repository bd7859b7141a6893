"""Finding a project's trials: Pose2Sim's layout and rmpl's."""

from __future__ import annotations

from pathlib import Path

from rmpl.project.layout import find_trials


def _touch(path: Path, text: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _pose2sim_session(root: Path) -> Path:
    """Pose2Sim's batch layout: calibration/ and Config.toml at the top, trials below (one
    in a participant folder), each with its Config.toml and videos/ or pose/."""
    _touch(root / "calibration" / "Calib.qca.txt", "<calibration/>")
    _touch(root / "Config.toml", "[project]\n")
    for cam in ("cam01", "cam02"):
        _touch(root / "Trial_1" / "videos" / f"{cam}.mp4")
        _touch(root / "P01" / "Trial_2" / "pose" / f"{cam}_json" / f"{cam}.0000.json", "{}")
    _touch(root / "Trial_1" / "Config.toml")
    _touch(root / "P01" / "Config.toml")
    _touch(root / "P01" / "Trial_2" / "Config.toml")
    return root


def test_pose2sim_session(tmp_path):
    root = _pose2sim_session(tmp_path / "session")
    trials = {t.name: t for t in find_trials(root)}
    assert set(trials) == {"Trial_1", "P01/Trial_2"}
    one, two = trials["Trial_1"], trials["P01/Trial_2"]
    assert one.source == "videos" and [p.name for p in one.inputs] == ["cam01.mp4", "cam02.mp4"]
    assert two.source == "keypoints" and two.inputs == [root / "P01" / "Trial_2" / "pose"]
    assert one.calib == two.calib == root / "calibration" / "Calib.qca.txt"
    assert one.layout == two.layout == "pose2sim"
    assert not one.missing and not two.missing
    # Config.toml of every level, the session's first
    assert two.pose2sim == [root / "Config.toml", root / "P01" / "Config.toml",
                            root / "P01" / "Trial_2" / "Config.toml"]  # fmt: skip


def test_pose_sync_before_pose_before_videos(tmp_path):
    root = _pose2sim_session(tmp_path / "session")
    trial = root / "Trial_1"
    _touch(trial / "pose" / "cam01_json" / "a.0000.json", "{}")
    assert find_trials(root)[1].inputs == [trial / "pose"]
    _touch(trial / "pose-sync" / "cam01_json" / "a.0000.json", "{}")
    (t,) = [t for t in find_trials(root) if t.name == "Trial_1"]
    assert t.source == "keypoints" and t.inputs == [trial / "pose-sync"]


def test_a_single_trial_folder_is_a_project_of_one(tmp_path):
    root = tmp_path / "Demo"
    _touch(root / "calibration" / "Calib.qca.txt", "<x/>")
    _touch(root / "videos" / "cam01.mp4")
    _touch(root / "Config.toml")
    (trial,) = find_trials(root)
    assert trial.name == "Demo" and trial.folder == root and trial.source == "videos"


def test_trial_calibration_overrides_the_project(tmp_path):
    root = _pose2sim_session(tmp_path / "session")
    own = _touch(root / "Trial_1" / "calibration" / "calib.toml", "x")
    trials = {t.name: t for t in find_trials(root)}
    assert trials["Trial_1"].calib == own
    assert trials["P01/Trial_2"].calib == root / "calibration" / "Calib.qca.txt"


def test_rmpl_layout_files_videos_images(tmp_path):
    root = tmp_path / "p"
    _touch(root / "calibration" / "rig.toml", "x")
    _touch(root / "walk" / "keypoints.json", "{}")
    _touch(root / "run" / "cam1.mp4")
    _touch(root / "run" / "cam2.avi")
    _touch(root / "jump" / "cam1" / "000.png")
    _touch(root / "jump" / "cam2" / "000.jpg")
    _touch(root / "notes" / "readme.txt")  # neither inputs nor a configuration: passed over
    trials = {t.name: t for t in find_trials(root)}
    assert set(trials) == {"walk", "run", "jump"}
    assert trials["walk"].source == "keypoints"
    assert trials["run"].source == "videos" and len(trials["run"].inputs) == 2
    assert trials["jump"].source == "images"
    assert [p.name for p in trials["jump"].inputs] == ["cam1", "cam2"]
    assert all(t.layout == "rmpl" and t.calib == root / "calibration" / "rig.toml"
               for t in trials.values())  # fmt: skip


def test_missing_inputs_and_calibration_are_said(tmp_path):
    root = tmp_path / "p"
    _touch(root / "empty" / "rmpl.toml")  # a trial (it has a configuration) without inputs
    _touch(root / "walk" / "keypoints.json", "{}")
    trials = {t.name: t for t in find_trials(root)}
    assert (
        "source" in trials["empty"].missing
        and "expected videos" in trials["empty"].missing["source"]
    )
    assert "calibration/" in trials["walk"].missing["calib"]


def test_several_calibration_files(tmp_path):
    root = tmp_path / "p"
    _touch(root / "walk" / "keypoints.json", "{}")
    _touch(root / "calibration" / "a.toml", "x")
    _touch(root / "calibration" / "b.json", "x")
    (t,) = find_trials(root)
    assert "one calibration file" in t.missing["calib"]
    _touch(root / "calibration" / "b.json").unlink()
    _touch(root / "calibration" / "Calib.qca.txt", "<x/>")
    _touch(root / "calibration" / "Calib_qualisys.toml", "x")  # Pose2Sim's converted one
    (root / "calibration" / "a.toml").unlink()
    (t,) = find_trials(root)
    assert t.calib == root / "calibration" / "Calib_qualisys.toml" and not t.missing


def test_output_folder_inside_the_project_is_not_a_trial(tmp_path):
    root = tmp_path / "p"
    _touch(root / "calibration" / "rig.toml", "x")
    _touch(root / "walk" / "keypoints.json", "{}")
    _touch(root / "out" / "walk" / "report.json", "{}")
    assert [t.name for t in find_trials(root, skip=[root / "out"])] == ["walk"]


def test_rmpl_outputs_are_not_inputs(tmp_path):
    """A one-trial folder with its default output folder inside: the second run sees the
    same inputs."""
    root = tmp_path / "walk"
    _touch(root / "calibration" / "rig.toml", "x")
    _touch(root / "keypoints.json", "{}")
    _touch(root / "rmpl-out" / "summary.json", "{}")
    _touch(root / "rmpl-out" / "walk" / "report.json", "{}")
    (t,) = find_trials(root)
    assert t.folder == root and t.inputs == [root / "keypoints.json"]
