"""3D pose writers (NPZ, JSON, TRC, C3D) and readers (NPZ, JSON, TRC)."""

from __future__ import annotations

import json
import tempfile
import warnings
from pathlib import Path

import c3d
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rmpl.errors import InputError
from rmpl.io import poses as poses_module
from rmpl.io.poses import JointSource, Poses3D, load_poses, save_poses
from rmpl.skeleton import COCO17, H36M17

TRC_KEYS = [
    "DataRate",
    "CameraRate",
    "NumFrames",
    "NumMarkers",
    "Units",
    "OrigDataRate",
    "OrigDataStartFrame",
    "OrigNumFrames",
]


def _poses(T=5, P=2, seed=0, frames=None, fps=60.0, skeleton="coco17", ids=None) -> Poses3D:
    rng = np.random.default_rng(seed)
    J = {"coco17": 17, "h36m17": 17, "shelf14": 14}[skeleton]
    points = rng.uniform(-3.0, 3.0, size=(T, P, J, 3))
    missing = rng.random((T, P, J)) < 0.2
    points[missing] = np.nan
    flags = rng.integers(1, 4, size=(T, P, J))
    flags[missing] = JointSource.MISSING
    scores = np.where(missing, 0.0, rng.uniform(0, 1, size=(T, P, J)))
    return Poses3D(
        points, scores, flags, rng.integers(0, 6, size=(T, P, J)), skeleton, frames, fps, ids
    )


def _opensim_fields(line: str) -> list[str]:
    """Split a TRC data row as OpenSim's reader does: tab-separated, a last empty field
    (after a trailing tab) not counted."""
    fields = line.rstrip("\r\n").split("\t")
    return fields[:-1] if fields[-1] == "" else fields


# --------------------------------------------------------------------------- npz / json


@st.composite
def poses3d(draw):
    T, P = draw(st.integers(1, 4)), draw(st.integers(0, 3))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    J = 17
    points = rng.normal(scale=draw(st.sampled_from([1e-3, 1.0, 1e3])), size=(T, P, J, 3))
    missing = rng.random((T, P, J)) < draw(st.sampled_from([0.0, 0.3, 1.0]))
    points[missing] = np.nan
    opt = draw(
        st.fixed_dictionaries(
            {"scores": st.booleans(), "flags": st.booleans(), "num_views": st.booleans()}
        )
    )
    flags = np.where(missing, 0, rng.integers(1, 4, size=(T, P, J)))
    return Poses3D(
        points,
        scores=rng.uniform(0, 2, size=(T, P, J)) if opt["scores"] else None,
        flags=flags if opt["flags"] else None,
        num_views=rng.integers(0, 40, size=(T, P, J)) if opt["num_views"] else None,
        skeleton=draw(st.sampled_from(["coco17", "h36m17"])),
        frames=draw(st.integers(-10, 500)) + np.cumsum(rng.integers(1, 5, size=T)),
        fps=draw(st.one_of(st.none(), st.floats(0.5, 1000.0))),
        person_ids=rng.choice(100, size=P, replace=False),
    )


def _assert_same(a: Poses3D, b: Poses3D) -> None:
    np.testing.assert_array_equal(a.points, b.points)
    for name in ("scores", "flags", "num_views"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.person_ids, b.person_ids)
    assert a.fps == b.fps and a.skeleton == b.skeleton


@settings(max_examples=30, deadline=None)
@given(poses=poses3d(), ext=st.sampled_from(["npz", "json"]))
def test_npz_json_round_trip(poses, ext):
    with tempfile.TemporaryDirectory() as d:
        back = load_poses(save_poses(poses, Path(d) / f"poses.{ext}"))
    _assert_same(back, poses)
    if poses.flags is not None:
        assert back.flags.dtype == np.uint8


def test_json_names_units_and_joints(tmp_path):
    poses = _poses(T=2, P=1)
    doc = json.loads(save_poses(poses, tmp_path / "p.json").read_text())
    assert doc["units"] == "m"
    assert doc["joints"] == list(COCO17.joints)
    assert doc["flag_values"] == {"missing": 0, "lifted": 1, "triangulated": 2, "interpolated": 3}
    missing = np.isnan(poses.points[0, 0, :, 0])
    assert all(doc["points"][0][0][j] == [None, None, None] for j in np.flatnonzero(missing))


def test_json_in_millimetres_is_read_in_metres(tmp_path):
    poses = _poses(T=2, P=1, seed=3)
    path = save_poses(poses, tmp_path / "p.json")
    doc = json.loads(path.read_text())
    doc["units"] = "mm"
    doc["points"] = [
        [[[None if c is None else c * 1000 for c in j] for j in p] for p in t]
        for t in doc["points"]
    ]
    path.write_text(json.dumps(doc))
    np.testing.assert_allclose(load_poses(path).points, poses.points, rtol=1e-12)


# --------------------------------------------------------------------------- TRC


@pytest.mark.parametrize("units", ["m", "mm"])
def test_trc_round_trip(tmp_path, units):
    poses = _poses(T=6, P=2, frames=[3, 4, 5, 9, 10, 11], fps=50.0, ids=[4, 1])
    back = load_poses(save_poses(poses, tmp_path / "p.trc", units=units))
    np.testing.assert_allclose(back.points, poses.points, atol=2e-6)
    np.testing.assert_array_equal(np.isnan(back.points), np.isnan(poses.points))
    np.testing.assert_array_equal(back.frames, poses.frames)
    np.testing.assert_array_equal(back.person_ids, [4, 1])
    assert back.fps == 50.0 and back.skeleton == "coco17"
    assert back.scores is None and back.flags is None


def test_trc_single_person_other_skeleton(tmp_path):
    poses = _poses(T=3, P=1, skeleton="h36m17")
    back = load_poses(save_poses(poses, tmp_path / "p.trc"))
    assert back.skeleton == "h36m17" and back.num_people == 1
    np.testing.assert_allclose(back.points, poses.points, atol=2e-6)


def test_trc_header_is_what_opensim_reads(tmp_path):
    poses = _poses(T=4, P=2, frames=[0, 1, 2, 5], fps=60.0, ids=[0, 1])
    poses.points[2, 1, -1] = np.nan  # the very last marker of a row missing
    poses.flags[2, 1, -1] = JointSource.MISSING
    poses.scores[2, 1, -1] = 0
    path = save_poses(poses, tmp_path / "walk.trc", units="mm")
    lines = path.read_text().split("\n")
    M = 2 * 17

    assert lines[0].split("\t") == ["PathFileType", "4", "(X/Y/Z)", "walk.trc"]
    assert lines[1].split("\t") == TRC_KEYS
    values = dict(zip(TRC_KEYS, lines[2].split("\t"), strict=True))
    assert float(values["DataRate"]) == 60 and float(values["CameraRate"]) == 60
    assert int(values["NumFrames"]) == 4 and int(values["NumMarkers"]) == M
    assert values["Units"] == "mm" and float(values["OrigDataRate"]) == 60
    assert int(values["OrigDataStartFrame"]) == 1 and int(values["OrigNumFrames"]) == 4

    names = lines[3].split("\t")
    assert names[:2] == ["Frame#", "Time"]
    expected = [f"{j}_p{p}" for p in (0, 1) for j in COCO17.joints]
    assert [n for n in names[2:] if n] == expected
    assert all(names[2 + 3 * i] == expected[i] for i in range(M))  # over its X column
    xyz = lines[4].split("\t")
    assert xyz[:2] == ["", ""]
    # a trailing tab, as on the data rows: Pose2Sim's reader counts the columns on this line
    assert xyz[2:] == [f"{c}{i}" for i in range(1, M + 1) for c in "XYZ"] + [""]
    assert lines[5] == ""

    rows = [ln for ln in lines[6:] if ln]
    assert len(rows) == 4
    for row, frame, pts in zip(rows, poses.frames, poses.points, strict=True):
        fields = _opensim_fields(row)
        assert len(fields) == 2 + 3 * M
        assert int(fields[0]) == frame + 1
        assert float(fields[1]) == pytest.approx(frame / 60.0, abs=1e-6)
        flat = pts.reshape(-1)
        for value, field in zip(flat, fields[2:], strict=True):
            if np.isnan(value):
                assert field == ""
            else:
                assert float(field) == pytest.approx(value * 1000, abs=1e-3)
    assert _opensim_fields(rows[2])[-3:] == ["", "", ""]


def test_trc_up_axis_y(tmp_path):
    poses = _poses(T=3, P=1, seed=5)
    path = save_poses(poses, tmp_path / "p.trc", up_axis="y")
    row = _opensim_fields([ln for ln in path.read_text().split("\n")[6:] if ln][0])
    j = int(np.flatnonzero(~np.isnan(poses.points[0, 0, :, 0]))[0])
    x, y, z = (float(v) for v in row[2 + 3 * j : 5 + 3 * j])
    X, Y, Z = poses.points[0, 0, j]
    assert (x, y, z) == pytest.approx((X, Z, -Y), abs=1e-6)  # up is +Y, handedness kept
    back = load_poses(path, up_axis="y")
    np.testing.assert_allclose(back.points, poses.points, atol=2e-6)
    as_written = load_poses(path)
    np.testing.assert_allclose(as_written.points[0, 0, j], [x, y, z])


def test_malformed_trc(tmp_path):
    path = save_poses(_poses(T=3, P=1), tmp_path / "p.trc")
    lines = path.read_text().split("\n")
    short = tmp_path / "short.trc"
    short.write_text("\n".join(lines[:-2]) + "\n")  # one data row fewer than NumFrames
    with pytest.raises(InputError, match="NumFrames") as info:
        load_poses(short)
    assert Path(info.value.path) == short
    cut = tmp_path / "cut.trc"
    cut.write_text("\n".join(lines[:6] + [lines[6].rsplit("\t", 5)[0]] + lines[7:]))
    with pytest.raises(InputError, match="data row 1"):
        load_poses(cut)
    keys = tmp_path / "keys.trc"
    keys.write_text("\n".join([lines[0], lines[1].replace("Units", "Unit")] + lines[2:]))
    with pytest.raises(InputError, match="line 2"):
        load_poses(keys)


# --------------------------------------------------------------------------- C3D


def _read_c3d(path: Path):
    with open(path, "rb") as f, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "no analog data"
        reader = c3d.Reader(f)
        frames = list(reader.read_frames())
        labels = [str(s).strip() for s in reader.point_labels]
        units = reader.get("POINT:UNITS").string_value.strip()
        return reader, frames, labels, units


@pytest.mark.parametrize("units", ["m", "mm"])
def test_c3d_reads_back_with_the_c3d_package(tmp_path, units):
    poses = _poses(T=4, P=2, frames=[2, 3, 5, 6], fps=100.0, ids=[0, 9])
    path = save_poses(poses, tmp_path / "p.c3d", units=units)
    reader, frames, labels, file_units = _read_c3d(path)

    assert file_units == units
    assert reader.point_rate == 100.0
    assert labels == [f"{j}_p{p}" for p in (0, 9) for j in COCO17.joints]
    assert reader.first_frame == 3 and reader.last_frame == 7  # 1-based, gap filled
    assert [f for f, _, _ in frames] == [3, 4, 5, 6, 7]
    scale = 1000.0 if units == "mm" else 1.0
    by_number = {f: pts for f, pts, _ in frames}
    for t, frame in enumerate(poses.frames):
        pts = by_number[frame + 1]
        want = poses.points[t].reshape(-1, 3)
        ok = ~np.isnan(want).any(-1)
        np.testing.assert_array_equal(pts[:, 3] < 0, ~ok)  # residual -1 = missing
        np.testing.assert_allclose(pts[ok, :3], want[ok] * scale, rtol=1e-6, atol=1e-4 * scale)
    assert (by_number[5][:, 3] == -1).all()  # frame 4 (rmpl) is not in the poses


def test_c3d_with_40_people_puts_labels_past_255_in_labels2(tmp_path):
    # 40 x 17 = 680 points: one C3D parameter holds 255 labels (a one-byte dimension).
    poses = _poses(T=3, P=40, fps=30.0, ids=list(range(100, 140)))
    path = save_poses(poses, tmp_path / "many.c3d")
    reader, frames, first, _ = _read_c3d(path)
    labels = list(first)
    for extra in ("POINT:LABELS2", "POINT:LABELS3"):
        labels += [str(s).strip() for s in reader.get(extra).string_array]
    assert reader.get("POINT:LABELS4") is None
    assert labels == [f"{j}_p{p}" for p in range(100, 140) for j in COCO17.joints]
    assert reader.point_used == 680 and len(frames) == 3
    want = poses.points.reshape(3, 680, 3)
    for t, (_, pts, _) in enumerate(frames):
        ok = ~np.isnan(want[t]).any(-1)
        np.testing.assert_array_equal(pts[:, 3] < 0, ~ok)
        np.testing.assert_allclose(pts[ok, :3], want[t][ok], rtol=1e-6, atol=1e-4)


def test_c3d_up_axis(tmp_path):
    poses = Poses3D(np.array([[[[1.0, 2.0, 3.0]] * 17]]), fps=30.0)
    _, frames, _, _ = _read_c3d(save_poses(poses, tmp_path / "p.c3d", up_axis="y"))
    np.testing.assert_allclose(frames[0][1][0, :3], [1.0, 3.0, -2.0])


# --------------------------------------------------------------------------- bad input


def test_trc_and_c3d_need_fps_and_leave_no_file(tmp_path):
    poses = _poses(T=2, P=1, fps=None)
    for name in ("p.trc", "p.c3d"):
        with pytest.raises(InputError, match="fps") as info:
            save_poses(poses, tmp_path / name)
        assert Path(info.value.path) == tmp_path / name
    assert list(tmp_path.iterdir()) == []


def test_unknown_format_and_options(tmp_path):
    poses = _poses(T=2, P=1)
    with pytest.raises(InputError, match="format"):
        save_poses(poses, tmp_path / "p.fbx")
    with pytest.raises(InputError, match="units"):
        save_poses(poses, tmp_path / "p.trc", units="inch")
    with pytest.raises(InputError, match="up_axis"):
        save_poses(poses, tmp_path / "p.npz", up_axis="y")
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_no_file(tmp_path, monkeypatch):
    poses = _poses(T=2, P=1)

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(poses_module.json, "dumps", boom)
    monkeypatch.setattr(poses_module.np, "savez_compressed", boom)
    monkeypatch.setattr(poses_module, "_trc_text", boom)
    for name in ("p.json", "p.npz", "p.trc"):
        with pytest.raises(OSError, match="disk full"):
            save_poses(poses, tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_invalid_poses_are_refused():
    pts = np.zeros((2, 1, 17, 3))
    with pytest.raises(InputError, match="shape"):
        Poses3D(np.zeros((2, 17, 3)))
    with pytest.raises(InputError, match="joints"):
        Poses3D(np.zeros((2, 1, 14, 3)))  # COCO-17 by default
    partial = pts.copy()
    partial[0, 0, 0, 1] = np.nan
    with pytest.raises(InputError, match="NaN"):
        Poses3D(partial)
    with pytest.raises(InputError, match="MISSING"):
        Poses3D(pts, flags=np.zeros((2, 1, 17)))  # finite points flagged missing
    with pytest.raises(InputError, match="JointSource"):
        Poses3D(pts, flags=np.full((2, 1, 17), 9))
    with pytest.raises(InputError, match="scores"):
        Poses3D(pts, scores=np.full((2, 1, 17), np.nan))
    with pytest.raises(InputError, match="increasing"):
        Poses3D(pts, frames=[3, 3])
    with pytest.raises(InputError, match="distinct"):
        Poses3D(np.zeros((1, 2, 17, 3)), person_ids=[1, 1])
    with pytest.raises(InputError, match="skeleton"):
        Poses3D(pts, skeleton="smpl24")
    assert Poses3D(np.zeros((1, 1, 17, 3)), skeleton="h36m17").joint_names == H36M17.joints


def test_load_errors_name_the_file_and_field(tmp_path):
    missing = tmp_path / "none.npz"
    with pytest.raises(InputError) as info:
        load_poses(missing)
    assert Path(info.value.path) == missing

    empty = tmp_path / "empty.json"
    empty.write_text("")
    with pytest.raises(InputError, match="empty") as info:
        load_poses(empty)
    assert Path(info.value.path) == empty

    path = save_poses(_poses(T=2, P=1), tmp_path / "p.json")
    doc = json.loads(path.read_text())
    del doc["points"]
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as info:
        load_poses(path)
    assert info.value.field == "points" and Path(info.value.path) == path

    doc = json.loads(save_poses(_poses(T=2, P=1), path).read_text())
    doc["points"][0][0].pop()  # 16 joints
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="shape") as info:
        load_poses(path)
    assert info.value.field == "points"

    npz = save_poses(_poses(T=2, P=1), tmp_path / "p.npz")
    with np.load(npz) as z:
        arrays = dict(z)
    arrays["flags"] = np.zeros_like(arrays["flags"])  # inconsistent with the points
    np.savez(npz, **arrays)
    with pytest.raises(InputError) as info:
        load_poses(npz)
    assert info.value.field == "flags" and Path(info.value.path) == npz
    with pytest.raises(InputError, match="write-only"):
        load_poses(tmp_path / "p.c3d")


# --------------------------------------------------------------------------- per-view records


def _with_views(T=4, P=2, V=3, seed=0) -> Poses3D:
    """Poses with every per-view field and heights; the last person absent in frame 0."""
    from rmpl.io.poses import ViewStatus

    base = _poses(T=T, P=P, seed=seed)
    points = base.points.copy()
    points[0, P - 1] = np.nan
    rng = np.random.default_rng(seed)
    absent = np.isnan(points).all((-1, -2))[..., None]
    status = np.where(absent, ViewStatus.ABSENT, rng.integers(1, 6, size=(T, P, V)))
    return Poses3D(
        points,
        flags=np.where(np.isnan(points).any(-1), 0, 1),
        membership=np.where(absent, -1, rng.integers(-1, 3, size=(T, P, V))),
        views_excluded=rng.integers(0, 17, size=(T, P, V)),
        view_status=status,
        camera_names=[f"cam{v}" for v in range(V)],
        heights=np.array([1.71, np.nan])[:P],
        fps=30.0,
    )


@pytest.mark.parametrize("ext", ["npz", "json"])
def test_per_view_fields_and_heights_round_trip(tmp_path, ext):
    poses = _with_views()
    back = load_poses(save_poses(poses, tmp_path / f"p.{ext}"))
    for name in ("membership", "views_excluded", "view_status", "heights"):
        np.testing.assert_array_equal(getattr(back, name), getattr(poses, name), err_msg=name)
    assert back.camera_names == ("cam0", "cam1", "cam2")
    assert back.membership.dtype == np.int64 and back.view_status.dtype == np.uint8


def test_json_marks_views_and_suspect_joints(tmp_path):
    from rmpl.io.poses import ViewStatus

    poses = _with_views(T=3, P=1, V=2)
    poses.view_status[1:] = ViewStatus.AGREES  # frame 0: the person is absent
    poses.view_status[1, 0, 1] = ViewStatus.DISAGREES
    doc = json.loads(save_poses(poses, tmp_path / "p.json").read_text())
    assert doc["view_status_values"]["disagrees"] == 2
    assert doc["view_status"][1][0] == [1, 2]
    suspect = np.array(doc["suspect"])  # (T, P, J)
    present = ~np.isnan(poses.points).any(-1)
    np.testing.assert_array_equal(suspect[1], present[1])
    assert present[1].any() and not suspect[[0, 2]].any()
    assert doc["heights"][0] == pytest.approx(1.71)


@pytest.mark.parametrize("ext", ["npz", "json"])
def test_files_without_per_view_fields_still_load(tmp_path, ext):
    poses = _poses(T=3, P=2)
    path = save_poses(poses, tmp_path / f"p.{ext}")
    if ext == "json":  # an older file: none of the new keys at all
        doc = json.loads(path.read_text())
        assert "membership" not in doc and "view_status" not in doc
    back = load_poses(path)
    assert back.membership is None and back.view_status is None and back.heights is None
    assert back.camera_names is None


def test_invalid_per_view_fields_are_refused(tmp_path):
    from rmpl.io.poses import ViewStatus

    good = _with_views()
    pts = good.points

    def make(**kw):
        fields = {
            "membership": good.membership,
            "view_status": good.view_status,
            "camera_names": good.camera_names,
        }
        fields.update(kw)
        return Poses3D(pts, **fields)

    with pytest.raises(InputError, match="membership"):
        make(membership=np.full(good.membership.shape, -2))
    with pytest.raises(InputError, match="membership"):
        make(membership=good.membership[:, :, :, None])
    with pytest.raises(InputError, match="one number of views"):
        make(camera_names=["a", "b"])
    with pytest.raises(InputError, match="distinct"):
        make(camera_names=["a", "a", "b"])
    with pytest.raises(InputError, match="ViewStatus"):
        make(view_status=np.full(good.view_status.shape, 9))
    absent_marked = good.view_status.copy()
    absent_marked[0, 1] = ViewStatus.AGREES  # person 1 has no joint in frame 0
    with pytest.raises(InputError, match="ABSENT"):
        make(view_status=absent_marked)
    with pytest.raises(InputError, match="views_excluded"):
        make(views_excluded=np.full(good.view_status.shape, -1))
    with pytest.raises(InputError, match="heights"):
        Poses3D(pts, heights=[1.7])
    with pytest.raises(InputError, match="heights"):
        Poses3D(pts, heights=[1.7, -1.0])
    # A file whose view_status disagrees with its points names the file.
    path = save_poses(good, tmp_path / "p.json")
    doc = json.loads(path.read_text())
    doc["view_status"][0][1] = [1, 1, 1]
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="ABSENT") as info:
        load_poses(path)
    assert Path(info.value.path) == path and info.value.field == "view_status"
