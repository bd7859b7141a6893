"""Per-person TRC/C3D files for Pose2Sim (rmpl.io.pose2sim), read back with the ``c3d``
package, a TRC parser that follows the documented layout, and (benchmark, needs
scripts/setup_opensim.sh) OpenSim's TimeSeriesTableVec3, Pose2Sim's read_trc and
trc-data-reader."""

from __future__ import annotations

import json
import os
import subprocess
import warnings
from pathlib import Path

import c3d
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rmpl.errors import InputError
from rmpl.io.pose2sim import IK_MARKERS, POSE2SIM_MARKERS, write_pose2sim
from rmpl.io.poses import Poses3D
from rmpl.skeleton import COCO17

NAMES = list(POSE2SIM_MARKERS)
J = {name: i for i, name in enumerate(COCO17.joints)}
REPO = Path(__file__).resolve().parents[2]


def _people(T=6, P=1, seed=0, fps=50.0, frames=None, ids=None) -> Poses3D:
    """Random COCO-17 people, nothing missing."""
    rng = np.random.default_rng(seed)
    return Poses3D(rng.uniform(-2.0, 2.0, (T, P, 17, 3)), fps=fps, frames=frames, person_ids=ids)


def read_trc(path: Path) -> dict:
    """TRC per its documented layout: 5 header lines (tab-separated), then one row per
    frame ``Frame# Time X1 Y1 Z1 ...``; an empty field is a missing coordinate.

    Also checks that the marker-name line, the axes line and every data row have the same
    number of fields (2 + 3 M, plus the empty one after a last tab): a reader that takes the
    axes line as its column header (pandas, as Pose2Sim's ``read_trc`` does) then lines up
    the columns."""
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0].split("\t")[:3] == ["PathFileType", "4", "(X/Y/Z)"]
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=True))
    labels = lines[3].split("\t")
    assert labels[:2] == ["Frame#", "Time"]
    markers = [m for m in labels[2:] if m]
    M = len(markers)
    assert labels[2:] == [x for m in markers for x in (m, "", "")] + [""]  # a name per 3 columns
    axes = lines[4].split("\t")
    assert axes == ["", ""] + [f"{c}{i}" for i in range(1, M + 1) for c in "XYZ"] + [""]
    assert lines[5] == ""
    rows = lines[6:]
    data = np.full((len(rows), 2 + 3 * M), np.nan)
    for r, row in enumerate(rows):
        fields = row.split("\t")
        assert len(fields) == len(axes) and fields[-1] == ""  # a tab after every field
        data[r] = [float(x) if x else np.nan for x in fields[:-1]]
    return dict(
        header=header,
        markers=markers,
        frame=data[:, 0],
        time=data[:, 1],
        points=data[:, 2:].reshape(len(rows), M, 3),
    )


def read_c3d(path: Path) -> dict:
    with open(path, "rb") as f, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = c3d.Reader(f)
        frames = list(r.read_frames())
        return dict(
            labels=[s.strip() for s in r.point_labels],
            units=r.get("POINT:UNITS").string_value.strip(),
            rate=r.point_rate,
            first=r.first_frame,
            screen=(
                r.get("POINT:X_SCREEN").string_value.strip(),
                r.get("POINT:Y_SCREEN").string_value.strip(),
            ),
            frame=np.array([i for i, _, _ in frames]),
            points=np.stack([p[:, :3] for _, p, _ in frames]),
            residual=np.stack([p[:, 3] for _, p, _ in frames]),
        )


# --------------------------------------------------------------------------- layout


def test_names_order_and_header(tmp_path):
    poses = _people(T=4, frames=[10, 11, 12, 13], fps=60.0)
    paths = write_pose2sim(poses, tmp_path, stem="trial")
    assert [p.name for p in paths] == ["trial_p0.trc", "trial_p0.c3d"]
    trc = read_trc(paths[0])
    assert trc["markers"] == NAMES
    assert set(IK_MARKERS) <= set(NAMES)
    h = trc["header"]
    assert (h["DataRate"], h["NumFrames"], h["NumMarkers"], h["Units"]) == ("60", "4", "19", "m")
    assert h["OrigDataStartFrame"] == "11"  # TRC counts frames from 1
    np.testing.assert_array_equal(trc["frame"], [11, 12, 13, 14])
    np.testing.assert_allclose(trc["time"], np.array([10, 11, 12, 13]) / 60.0, atol=1e-6)
    c = read_c3d(paths[1])
    assert c["labels"] == NAMES
    assert (c["units"], c["rate"], c["first"]) == ("m", 60.0, 11)


def test_markers_are_the_named_joints_and_midpoints(tmp_path):
    poses = _people(T=3, seed=1)
    trc = read_trc(write_pose2sim(poses, tmp_path, orientation="z-up")[0])
    x = poses.points[:, 0]
    want = {
        "Nose": x[:, J["nose"]],
        "LEar": x[:, J["left_ear"]],
        "RWrist": x[:, J["right_wrist"]],
        "LAnkle": x[:, J["left_ankle"]],
        "Hip": (x[:, J["left_hip"]] + x[:, J["right_hip"]]) / 2,
        "Neck": (x[:, J["left_shoulder"]] + x[:, J["right_shoulder"]]) / 2,
    }
    for name, value in want.items():
        np.testing.assert_allclose(trc["points"][:, NAMES.index(name)], value, atol=1e-6)


def test_one_pair_of_files_per_person(tmp_path):
    poses = _people(T=3, P=3, ids=[4, 0, 7])
    paths = write_pose2sim(poses, tmp_path, formats=("trc",))
    assert [p.name for p in paths] == ["poses_p4.trc", "poses_p0.trc", "poses_p7.trc"]
    for p, path in enumerate(paths):
        got = read_trc(path)["points"][:, NAMES.index("RKnee")]
        np.testing.assert_allclose(
            got, poses.points[:, p, J["right_knee"]][:, [1, 2, 0]], atol=1e-6
        )


# --------------------------------------------------------------------------- axes and units


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_orientation_mapping(seed):
    """pose2sim-y-up: file (X, Y, Z) = world (y, z, x); z-up: world as it is."""
    import tempfile

    poses = _people(T=2, seed=seed)
    x = poses.points[:, 0, J["left_wrist"]]
    with tempfile.TemporaryDirectory() as d:
        y_up = write_pose2sim(poses, Path(d) / "y", orientation="pose2sim-y-up")
        z_up = write_pose2sim(poses, Path(d) / "z", orientation="z-up")
        k = NAMES.index("LWrist")
        np.testing.assert_allclose(read_trc(y_up[0])["points"][:, k], x[:, [1, 2, 0]], atol=1e-6)
        np.testing.assert_allclose(read_trc(z_up[0])["points"][:, k], x, atol=1e-6)
        np.testing.assert_allclose(read_c3d(y_up[1])["points"][:, k], x[:, [1, 2, 0]], atol=1e-5)
        assert read_c3d(y_up[1])["screen"] == ("+Z", "+Y")  # Y is up
        assert read_c3d(z_up[1])["screen"] == ("+X", "+Z")


def test_the_y_up_file_stands_upright(tmp_path):
    """A Z-up person (nose above ankles) has the nose at the larger file Y."""
    points = np.zeros((2, 1, 17, 3))
    points[..., 2] = np.linspace(0.1, 1.7, 17)[::-1]  # nose highest, ankles lowest
    trc = read_trc(write_pose2sim(Poses3D(points, fps=30.0), tmp_path)[0])
    y = trc["points"][..., 1]
    assert (y[:, NAMES.index("Nose")] > y[:, NAMES.index("LAnkle")] + 1.0).all()


def test_millimetres(tmp_path):
    poses = _people(T=3, seed=2)
    m = write_pose2sim(poses, tmp_path / "m")
    mm = write_pose2sim(poses, tmp_path / "mm", units="mm")
    a, b = read_trc(m[0]), read_trc(mm[0])
    assert b["header"]["Units"] == "mm"
    np.testing.assert_allclose(b["points"], a["points"] * 1000, atol=2e-3)
    c = read_c3d(mm[1])
    assert c["units"] == "mm"
    np.testing.assert_allclose(c["points"], a["points"] * 1000, rtol=1e-5, atol=1e-3)


# --------------------------------------------------------------------------- missing joints


def _with_holes() -> Poses3D:
    """10 frames; the right knee missing at frames 4-5, the nose at frames 0-1 (so the
    frames with all IK markers are 2..9), the left eye at frame 9."""
    poses = _people(T=10, seed=3)
    pts = poses.points.copy()
    pts[4:6, 0, J["right_knee"]] = np.nan
    pts[0:2, 0, J["nose"]] = np.nan
    pts[9, 0, J["left_eye"]] = np.nan
    return Poses3D(pts, fps=poses.fps)


def test_gaps_are_empty_fields_inside_the_complete_span(tmp_path):
    poses = _with_holes()
    paths = write_pose2sim(poses, tmp_path, missing="gaps", orientation="z-up")
    trc = read_trc(paths[0])
    np.testing.assert_array_equal(trc["frame"], np.arange(2, 10) + 1)
    knee = trc["points"][:, NAMES.index("RKnee")]
    assert np.isnan(knee[[2, 3]]).all() and np.isfinite(np.delete(knee, [2, 3], 0)).all()
    line = paths[0].read_text().splitlines()[6 + 2]  # frame 4 (5 header lines, a blank)
    k = NAMES.index("RKnee")
    assert line.split("\t")[2 + 3 * k : 5 + 3 * k] == ["", "", ""]
    c = read_c3d(paths[1])
    np.testing.assert_array_equal(c["residual"][[2, 3], NAMES.index("RKnee")], [-1, -1])
    assert (c["residual"][:, NAMES.index("RWrist")] == 0).all()


def test_interpolate_fills_gaps_linearly(tmp_path):
    poses = _with_holes()
    trc = read_trc(write_pose2sim(poses, tmp_path, missing="interpolate", orientation="z-up")[0])
    knee = poses.points[:, 0, J["right_knee"]]
    got = trc["points"][:, NAMES.index("RKnee")]
    np.testing.assert_allclose(got[2], knee[3] + (knee[6] - knee[3]) / 3, atol=1e-6)  # frame 4
    np.testing.assert_allclose(got[3], knee[3] + 2 * (knee[6] - knee[3]) / 3, atol=1e-6)
    assert np.isfinite(trc["points"][:, NAMES.index("Neck")]).all()
    assert np.isnan(trc["points"][-1, NAMES.index("LEye")]).all()  # after its last sighting


def test_complete_keeps_only_frames_with_every_ik_marker(tmp_path):
    poses = _with_holes()
    paths = write_pose2sim(poses, tmp_path, missing="complete")
    trc = read_trc(paths[0])
    np.testing.assert_array_equal(trc["frame"], np.array([2, 3, 6, 7, 8, 9]) + 1)
    ik = [NAMES.index(m) for m in IK_MARKERS]
    assert np.isfinite(trc["points"][:, ik]).all()
    c = read_c3d(paths[1])  # contiguous frames; the dropped ones have no points
    np.testing.assert_array_equal(c["frame"], np.arange(3, 11))
    assert (c["residual"][[2, 3]] == -1).all()


def test_derived_marker_is_missing_when_one_side_is(tmp_path):
    poses = _people(T=4, seed=4)
    pts = poses.points.copy()
    pts[1, 0, J["left_shoulder"]] = np.nan
    trc = read_trc(write_pose2sim(Poses3D(pts, fps=50.0), tmp_path)[0])
    neck = trc["points"][:, NAMES.index("Neck")]
    assert np.isnan(neck[1]).all() and np.isfinite(np.delete(neck, 1, 0)).all()


def test_person_without_a_complete_frame_gets_no_file(tmp_path, caplog):
    poses = _people(T=3, P=2, ids=[1, 2])
    pts = poses.points.copy()
    pts[:, 1, J["left_ankle"]] = np.nan
    paths = write_pose2sim(Poses3D(pts, fps=50.0, person_ids=[1, 2]), tmp_path)
    assert [p.name for p in paths] == ["poses_p1.trc", "poses_p1.c3d"]
    assert "person 2" in caplog.text


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "poses, kwargs, field",
    [
        (Poses3D(np.zeros((0, 1, 17, 3)), fps=30.0), {}, "points"),
        (Poses3D(np.zeros((3, 0, 17, 3)), fps=30.0), {}, "points"),
        (Poses3D(np.zeros((3, 1, 17, 3))), {}, "fps"),
        (Poses3D(np.zeros((3, 1, 14, 3)), skeleton="shelf14", fps=30.0), {}, "skeleton"),
        (Poses3D(np.full((3, 1, 17, 3), np.nan), fps=30.0), {}, "points"),
        (Poses3D(np.zeros((2, 1, 17, 3)), fps=30.0, frames=[-1, 0]), {}, "frames"),
        (_people(), {"orientation": "y-up"}, "orientation"),
        (_people(), {"units": "cm"}, "units"),
        (_people(), {"missing": "zeros"}, "missing"),
        (_people(), {"formats": ("trc", "bvh")}, "formats"),
        (_people(), {"stem": "a/b"}, "stem"),
        (_people(), {"stem": "trial_LSTM"}, "stem"),
    ],
)
def test_bad_input_is_one_input_error_and_writes_nothing(tmp_path, poses, kwargs, field):
    out = tmp_path / "out"
    with pytest.raises(InputError) as e:
        write_pose2sim(poses, out, **kwargs)
    assert e.value.field == field and str(out) in str(e.value)
    assert not out.exists() or not any(out.iterdir())


def test_fields_changed_after_construction_are_checked(tmp_path):
    poses = _people()
    poses.points = poses.points[..., :2]
    with pytest.raises(InputError, match="points"):
        write_pose2sim(poses, tmp_path)


# --------------------------------------------------------------------------- maintained readers


def _opensim_python() -> Path:
    venv = Path(os.environ.get("RMPL_OPENSIM_VENV", REPO / ".venv-opensim"))
    python = venv / "bin" / "python"
    if not python.exists():
        pytest.skip(f"no OpenSim venv at {venv} (run scripts/setup_opensim.sh)")
    return python


_READ_BACK = r"""
import json, sys
import opensim
from Pose2Sim.common import read_trc
from trc import TRCData

path, full = sys.argv[1:3]
table = opensim.TimeSeriesTableVec3(path)
rows = [[list(table.getRowAtIndex(r)[m].to_numpy()) for m in range(table.getNumColumns())]
        for r in range(table.getNumRows())]
data, frames, times, markers, _ = read_trc(path)
t = TRCData()
t.load(full)
print(json.dumps(dict(
    opensim=dict(labels=list(table.getColumnLabels()),
                 units=table.getTableMetaDataAsString("Units"),
                 times=list(table.getIndependentColumn()), points=rows),
    pose2sim=dict(markers=markers, frames=frames.tolist(), points=data.to_numpy().tolist()),
    trc_data_reader=dict(markers=t["Markers"], units=t["Units"], frames=t["Frame#"],
                         times=t["Time"], points=[t[m] for m in t["Markers"]]),
)).replace("NaN", "null"))
"""


@pytest.mark.benchmark
def test_opensim_pose2sim_and_trc_data_reader_read_the_trc(tmp_path):
    """OpenSim and Pose2Sim read a TRC with gaps; trc-data-reader 0.4.1 reads one without
    (it drops empty fields, so a row with a gap would shift the markers after it)."""
    python = _opensim_python()
    path = write_pose2sim(_with_holes(), tmp_path / "holes", formats=("trc",))[0]
    full = write_pose2sim(_people(T=5, seed=6), tmp_path / "full", formats=("trc",))[0]
    mine, mine_full = read_trc(path), read_trc(full)
    run = subprocess.run(
        [str(python), "-c", _READ_BACK, str(path), str(full)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(run.stdout.splitlines()[-1])

    def arr(x):
        return np.array(x, dtype=float)  # null -> nan

    o = got["opensim"]
    assert o["labels"] == NAMES and o["units"] == "m"
    np.testing.assert_allclose(o["times"], mine["time"], atol=1e-9)
    np.testing.assert_allclose(arr(o["points"]), mine["points"], atol=1e-9, equal_nan=True)
    p = got["pose2sim"]
    assert p["markers"] == NAMES
    np.testing.assert_array_equal(p["frames"], mine["frame"])
    K = len(mine["frame"])
    np.testing.assert_allclose(
        arr(p["points"]).reshape(K, -1, 3), mine["points"], atol=1e-9, equal_nan=True
    )
    t = got["trc_data_reader"]
    assert t["markers"] == NAMES and t["units"] == "m"
    np.testing.assert_array_equal(t["frames"], mine_full["frame"])
    np.testing.assert_allclose(t["times"], mine_full["time"], atol=1e-9)
    np.testing.assert_allclose(arr(t["points"]).transpose(1, 0, 2), mine_full["points"], atol=1e-9)


def test_rmpl_run_writes_the_pose2sim_trial_folder(tmp_path):
    """rmpl run: OUT/pose-3d/ holds one TRC + C3D per person in Pose2Sim's Y-up axes by
    default, the world's axes with --pose2sim z-up, nothing with --pose2sim off."""
    from rmpl.cli import main

    ex = Path(__file__).resolve().parents[2] / "src/rmpl/examples/walk"
    base = ["run", "--calib", str(ex / "calibration.toml"), "--keypoints",
            str(ex / "keypoints.json"), "--method", "triangulate", "--no-pictures"]  # fmt: skip
    assert main([*base, "--out", str(tmp_path / "y")]) == 0
    assert main([*base, "--out", str(tmp_path / "z"), "--pose2sim", "z-up"]) == 0
    assert main([*base, "--out", str(tmp_path / "off"), "--pose2sim", "off"]) == 0
    assert sorted(p.name for p in (tmp_path / "y" / "pose-3d").iterdir()) == [
        "poses_p0.c3d", "poses_p0.trc"]  # fmt: skip
    assert not (tmp_path / "off" / "pose-3d").exists()
    y = read_trc(tmp_path / "y" / "pose-3d" / "poses_p0.trc")
    z = read_trc(tmp_path / "z" / "pose-3d" / "poses_p0.trc")
    assert y["markers"] == z["markers"]
    assert np.allclose(y["points"], z["points"][..., [1, 2, 0]], equal_nan=True)


def test_a_world_whose_up_is_not_z_is_turned_before_pose2sims_axes(tmp_path):
    """A y-down world (OpenCV-style calibration): the Pose2Sim files still stand the person
    up along the file's Y, as a Z-up world of the same scene gives."""
    import dataclasses

    from rmpl.pipeline.outputs import _export_pose2sim

    zup = _people(T=3, seed=2)
    to_ydown = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # (x, y, z) -> (x, -z, y)
    ydown = dataclasses.replace(zup, points=zup.points @ to_ydown.T)
    _export_pose2sim(zup, tmp_path / "z", "pose2sim-y-up", None, np.array([0.0, 0, 1]))
    _export_pose2sim(ydown, tmp_path / "y", "pose2sim-y-up", None, np.array([0.0, -1, 0]))
    a = read_trc(tmp_path / "z" / "pose-3d" / "poses_p0.trc")["points"]
    b = read_trc(tmp_path / "y" / "pose-3d" / "poses_p0.trc")["points"]
    np.testing.assert_allclose(b, a, atol=1e-6)  # the same files: height along the file's Y
