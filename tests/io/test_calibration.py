"""Calibration formats: write -> read round trips, real fixtures, and bad input."""

from __future__ import annotations

import json
import os
import pickle
import string
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, project, rodrigues
from rmpl.geometry.triangulate import triangulate
from rmpl.io.calibration import FORMATS, detect_format, load_rig, save_rig

# Output name per writable format: the extension (or folder) save_rig and load_rig expect.
OUTPUT_NAMES = {
    "rmpl-toml": "calib.toml",
    "rmpl-json": "calib.json",
    "anipose": "calib.toml",
    "panoptic": "calibration_x.json",
    "shelf4d": "calibration.json",
    "voxelpose": "calibration_shelf.json",
    "easymocap": "calib",
}
NO_DISTORTION = {"shelf4d"}  # formats that store no lens distortion
NO_SIZE = {"voxelpose"}  # formats that store no image size


def test_every_writable_format_is_covered():
    writable = {name for name, (_, writer) in FORMATS.items() if writer is not None}
    assert writable == set(OUTPUT_NAMES)


# ---------------------------------------------------------------------------------------
# Round trips


def _finite(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def rigs(draw, distortion: bool = True) -> Rig:
    """Random rigs: random rotations, intrinsics, distortion, translations and sizes."""
    n = draw(st.integers(1, 4))
    alphabet = string.ascii_letters + string.digits + "_-"
    names = draw(
        st.lists(st.text(alphabet, min_size=1, max_size=8), min_size=n, max_size=n, unique=True)
    )
    cams = []
    for name in names:
        rvec = np.array(draw(st.tuples(*[_finite(-3.0, 3.0)] * 3)))
        fx, fy = draw(_finite(50.0, 5000.0)), draw(_finite(50.0, 5000.0))
        cx, cy = draw(_finite(0.0, 4000.0)), draw(_finite(0.0, 4000.0))
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        t = np.array(draw(st.tuples(*[_finite(-20.0, 20.0)] * 3)))
        dist = np.zeros(5)
        if distortion:
            k1, k2, k3 = (draw(_finite(-1.0, 1.0)) for _ in range(3))
            p1, p2 = draw(_finite(-0.05, 0.05)), draw(_finite(-0.05, 0.05))
            dist = np.array([k1, k2, p1, p2, k3])
        size = draw(st.none() | st.tuples(st.integers(1, 8000), st.integers(1, 8000)))
        cams.append(Camera(K, rodrigues(rvec), t, dist, size, name))
    return Rig(tuple(cams))


def assert_same_rig(got: Rig, want: Rig, sizes: bool = True) -> None:
    assert got.names == want.names
    np.testing.assert_allclose(got.K, want.K, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(got.R, want.R, atol=1e-9)
    np.testing.assert_allclose(got.t, want.t, atol=1e-9)
    np.testing.assert_allclose(got.dist, want.dist, atol=1e-12)
    if sizes:
        assert [c.size for c in got] == [c.size for c in want]


@pytest.mark.parametrize("fmt", sorted(OUTPUT_NAMES))
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_write_then_read_gives_the_same_rig(fmt, data):
    rig = data.draw(rigs(distortion=fmt not in NO_DISTORTION))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / OUTPUT_NAMES[fmt]
        save_rig(rig, path, fmt)
        assert detect_format(path) == fmt
        back = load_rig(path)
    assert_same_rig(back, rig, sizes=fmt not in NO_SIZE)
    if fmt in NO_SIZE:
        assert all(c.size is None for c in back)


@pytest.mark.parametrize("fmt", ["rmpl-toml", "rmpl-json", "anipose", "panoptic", "easymocap"])
def test_units_are_written_and_read_back(tmp_path, fmt):
    rig = Rig((Camera(np.diag([800.0, 800.0, 1.0]), np.eye(3), [0.1, -0.2, 3.0], name="a"),))
    path = tmp_path / OUTPUT_NAMES[fmt]
    save_rig(rig, path, fmt, units="mm")
    if fmt in ("rmpl-toml", "rmpl-json", "anipose"):  # the file records its unit
        assert_same_rig(load_rig(path), rig)
    assert_same_rig(load_rig(path, units="mm"), rig)
    np.testing.assert_allclose(load_rig(path, units="m").t[0], rig.t[0] * 1000)


def test_default_output_format_follows_the_extension(tmp_path):
    rig = Rig((Camera(np.diag([800.0, 800.0, 1.0]), np.eye(3), [0.0, 0.0, 3.0], name="a"),))
    for name, fmt in [("a.toml", "rmpl-toml"), ("a.json", "rmpl-json"), ("cams", "easymocap")]:
        save_rig(rig, tmp_path / name)
        assert detect_format(tmp_path / name) == fmt
        assert_same_rig(load_rig(tmp_path / name), rig)


# ---------------------------------------------------------------------------------------
# Hand-written files in each tool's own layout, with values known by construction

QUARTER_TURN_Z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def test_reads_a_pose2sim_style_toml(tmp_path):
    path = tmp_path / "Calib.toml"
    path.write_text(
        "[cam_01]\n"
        'name = "cam01"\n'
        "size = [ 1088.0, 1920.0,]\n"
        "matrix = [ [ 1500.0, 0.0, 540.0,], [ 0.0, 1510.0, 960.0,], [ 0.0, 0.0, 1.0,],]\n"
        "distortions = [ -0.1, 0.02, 0.001, -0.002,]\n"
        "rotation = [ 0.0, 0.0, 1.5707963267948966,]\n"
        "translation = [ 0.5, -0.25, 4.0,]\n"
        "fisheye = false\n\n"
        "[metadata]\nadjusted = false\nerror = 0.0\n"
    )
    assert detect_format(path) == "anipose"
    (cam,) = load_rig(path)
    assert cam.name == "cam01" and cam.size == (1088, 1920)
    np.testing.assert_allclose(cam.K, [[1500, 0, 540], [0, 1510, 960], [0, 0, 1]])
    np.testing.assert_allclose(cam.dist, [-0.1, 0.02, 0.001, -0.002, 0.0])
    np.testing.assert_allclose(cam.R, QUARTER_TURN_Z, atol=1e-12)
    np.testing.assert_allclose(cam.t, [0.5, -0.25, 4.0])


def test_reads_opencv_filestorage_yaml(tmp_path):
    (tmp_path / "intri.yml").write_text(
        "%YAML:1.0\n---\n"
        'names:\n   - "01"\n'
        "K_01: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
        "   data: [ 1.1000000000000000e+03, 0., 5.4e+02, 0., 1.2e+03,\n"
        "       9.6e+02, 0., 0., 1. ]\n"
        "dist_01: !!opencv-matrix   # five coefficients\n   rows: 1\n   cols: 5\n   dt: d\n"
        "   data: [ -1.0e-01, 1.0e-02, 0., 0., 0. ]\n"
    )
    (tmp_path / "extri.yml").write_text(
        "%YAML:1.0\n---\n"
        'names: [ "01" ]\n'
        "R_01: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
        "   data: [ 0., 0., 1.5707963267948966 ]\n"
        "T_01: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 1., 2., 3. ]\n"
    )
    for path in (tmp_path, tmp_path / "intri.yml", tmp_path / "extri.yml"):
        (cam,) = load_rig(path)
        assert cam.name == "01" and cam.size is None
        np.testing.assert_allclose(cam.K, [[1100, 0, 540], [0, 1200, 960], [0, 0, 1]])
        np.testing.assert_allclose(cam.dist, [-0.1, 0.01, 0, 0, 0])
        np.testing.assert_allclose(cam.R, QUARTER_TURN_Z, atol=1e-12)
        np.testing.assert_allclose(cam.t, [1, 2, 3])


def test_voxelpose_T_is_the_camera_centre_in_mm(tmp_path):
    path = tmp_path / "calibration_campus.json"
    R = QUARTER_TURN_Z.tolist()
    cam = {
        "R": R,
        "T": [[1000.0], [-2000.0], [1500.0]],
        "fx": 400.0,
        "fy": 410.0,
        "cx": 180.0,
        "cy": 140.0,
        "k": [[0.1], [0.01], [0.001]],
        "p": [[0.002], [0.003]],
    }
    path.write_text(json.dumps({"0": cam}))
    (got,) = load_rig(path)
    np.testing.assert_allclose(got.center, [1.0, -2.0, 1.5])
    np.testing.assert_allclose(got.dist, [0.1, 0.01, 0.002, 0.003, 0.001])
    np.testing.assert_allclose(got.K, [[400, 0, 180], [0, 410, 140], [0, 0, 1]])


# ---------------------------------------------------------------------------------------
# Real fixtures (skipped without ../shared/data)


def _assert_plausible(rig: Rig, max_distance: float = 10.0) -> None:
    """Focal lengths > 0, principal points inside the image, centres metres away."""
    assert np.all(rig.K[:, 0, 0] > 0) and np.all(rig.K[:, 1, 1] > 0)
    for cam in rig:
        if cam.size is not None:
            assert 0 < cam.K[0, 2] < cam.size[0] and 0 < cam.K[1, 2] < cam.size[1]
    distance = np.linalg.norm(rig.centers, axis=-1)
    assert np.all(distance > 1.0) and np.all(distance < max_distance), distance


@pytest.mark.shared
def test_shelf4d_fixture(shared_data):
    rig = load_rig(shared_data / "shelf_dev" / "calibration.json")
    assert rig.names == ["0", "1", "2", "3", "4"]
    assert all(c.size == (1032, 776) for c in rig)
    _assert_plausible(rig)


@pytest.mark.shared
def test_voxelpose_shelf_agrees_with_4d_association_shelf(shared_data):
    ours = load_rig(shared_data / "shelf_dev" / "calibration.json")
    voxel = load_rig(shared_data / "fixtures" / "shelf" / "calibration_shelf.json")
    assert voxel.names == ours.names
    assert np.abs(voxel.centers - ours.centers).max() < 0.003  # metres
    assert np.abs(voxel.R - ours.R).max() < 1e-3
    np.testing.assert_allclose(voxel.K, ours.K, rtol=1e-3)


@pytest.mark.shared
def test_voxelpose_campus_fixture(shared_data):
    rig = load_rig(shared_data / "fixtures" / "campus" / "calibration_campus.json")
    assert len(rig) == 3
    _assert_plausible(rig, max_distance=20.0)  # an outdoor scene


PANOPTIC = ["160906_band1", "160906_band2"]


@pytest.mark.parametrize("seq", PANOPTIC)
@pytest.mark.shared
def test_panoptic_ground_truth_projects_into_the_hd_images(shared_data, seq):
    root = shared_data / "fixtures" / "panoptic_body3d" / seq
    rig = load_rig(root / f"calibration_{seq}.json")
    assert len(rig) == 31 and all(c.size == (1920, 1080) for c in rig)
    _assert_plausible(rig)
    # Panoptic's y axis points down and the floor is y = 0: every dome camera is above it.
    assert np.all(rig.centers[:, 1] < -0.3)
    w, h = rig.sizes[:, 0, None], rig.sizes[:, 1, None]
    for frame in sorted((root / "hdPose3d_stage1_coco19").glob("*.json")):
        bodies = json.loads(frame.read_text())["bodies"]
        joints = np.array([b["joints19"] for b in bodies]).reshape(len(bodies), 19, 4)
        seen = joints[..., 3] > 0
        uv = rig.project(joints[..., :3] / 100.0)  # cm -> m; (bodies, V, 19, 2)
        inside = (uv[..., 0] >= 0) & (uv[..., 0] < w) & (uv[..., 1] >= 0) & (uv[..., 1] < h)
        share = (inside & seen[:, None]).sum(-1) / seen.sum(-1)[:, None]  # (bodies, V)
        assert share.mean() > 0.8
        assert np.all((share >= 0.5).mean(axis=1) >= 0.75)  # each body, most cameras
        neck_above_pelvis = uv[:, :, 0, 1] < uv[:, :, 2, 1]  # coco19: 0 neck, 2 pelvis
        assert neck_above_pelvis.mean() > 0.9


@pytest.mark.shared
def test_panoptic_camera_types(shared_data, tmp_path):
    seq = PANOPTIC[0]
    path = shared_data / "fixtures" / "panoptic_body3d" / seq / f"calibration_{seq}.json"
    types = [c["type"] for c in json.loads(path.read_text())["cameras"]]
    for kind in ("vga", "kinect-color"):
        rig = load_rig(path, camera_type=kind)
        assert len(rig) == types.count(kind)
        _assert_plausible(rig)
    everything = load_rig(path, camera_type="all")
    assert len(everything) == len(types)
    # Written with camera_type="all", each camera's type follows from its Panoptic name.
    save_rig(everything, tmp_path / "all.json", "panoptic", camera_type="all")
    assert_same_rig(load_rig(tmp_path / "all.json", camera_type="all"), everything)
    assert len(load_rig(tmp_path / "all.json", camera_type="vga")) == types.count("vga")
    with pytest.raises(InputError, match="camera_type"):
        load_rig(path, camera_type="thermal")


@pytest.mark.parametrize("fmt", sorted(OUTPUT_NAMES))
@pytest.mark.shared
def test_real_calibrations_survive_every_writer(shared_data, tmp_path, fmt):
    if fmt in NO_DISTORTION:
        rig = load_rig(shared_data / "shelf_dev" / "calibration.json")
    else:
        seq = PANOPTIC[0]
        rig = load_rig(
            shared_data / "fixtures" / "panoptic_body3d" / seq / f"calibration_{seq}.json"
        )
    path = tmp_path / OUTPUT_NAMES[fmt]
    save_rig(rig, path, fmt)
    assert_same_rig(load_rig(path, fmt), rig, sizes=fmt not in NO_SIZE)


H36M_SUBJECTS = ["S1", "S5", "S6", "S7", "S8", "S9", "S11"]


@pytest.mark.shared
def test_h36m_json_and_pickle_agree(shared_data):
    for subject in H36M_SUBJECTS:
        js = load_rig(shared_data / "h36m_cameras" / "camera-parameters.json", subject=subject)
        pk = load_rig(shared_data / "fixtures" / "h36m" / "cameras.pkl", subject=subject)
        assert js.names == pk.names
        assert_same_rig(pk, js)
        _assert_plausible(js)
        # The subject stands near the world origin (z up): every camera sees it.
        uv = js.project(np.array([[0.0, 0.0, 0.9]]))[:, 0]  # (V, 2)
        assert np.all((uv > 0) & (uv < js.sizes)), uv


@pytest.mark.shared
def test_h36m_intrinsics_reproduce_the_2d_annotations(shared_data):
    data = np.load(shared_data / "fixtures" / "h36m" / "test_h36m_body3d.npz")
    for name, joints, pixels in zip(data["imgname"], data["S"], data["part"], strict=True):
        subject, cam_id = str(name).split("/")[0], str(name).split(".")[1].split("/")[0]
        rig = load_rig(shared_data / "h36m_cameras" / "camera-parameters.json", subject=subject)
        cam = rig[rig.names.index(cam_id)]
        # `S` holds the joints in camera coordinates (metres): project with K and distortion.
        uv = project(joints[:, :3], cam.K, np.eye(3), np.zeros(3), cam.dist)
        assert np.abs(uv - pixels[:, :2]).max() < 1.0


@pytest.mark.shared
def test_h36m_unknown_subject(shared_data):
    path = shared_data / "h36m_cameras" / "camera-parameters.json"
    with pytest.raises(InputError) as err:
        load_rig(path, subject="S42")
    assert err.value.field == "extrinsics.S42" and str(path) in str(err.value)


QCA = Path("pose2sim_demo/Pose2Sim/S01_Demo_SingleTrial")


def _openpose_person(path: Path) -> np.ndarray:
    """The most confident person of an OpenPose JSON: (J, 3) x, y, score."""
    people = json.loads(path.read_text())["people"]
    kp = np.array([np.reshape(p["pose_keypoints_2d"], (-1, 3)) for p in people])
    return kp[np.argmax(kp[..., 2].mean(-1))]


@pytest.mark.shared
def test_qualisys_pose2sim_demo_triangulates_consistently(shared_data):
    trial = shared_data / QCA
    rig = load_rig(trial / "calibration" / "Calib.qca.txt")
    assert rig.names == ["cam_01", "cam_02", "cam_03", "cam_04"]
    assert all(c.size == (1088, 1920) for c in rig)
    _assert_plausible(rig)
    for frame in (0, 45, 90):
        kp = np.stack(
            [
                _openpose_person(
                    trial
                    / "pose"
                    / f"{n.replace('_', '')}_json"
                    / f"{n.replace('_', '')}.{frame:04d}.json"
                )
                for n in rig.names
            ]
        )  # (V, J, 3)
        result = triangulate(kp[..., :2], kp[..., 2], rig, min_score=0.3)
        # A wrong axis convention or unit puts the views hundreds of pixels apart.
        assert np.nanmedian(result.error) < 25.0
        height = result.points[:, 2]  # Qualisys z is up, the floor z = 0
        assert 0.3 < np.nanmedian(height) < 1.5 and np.nanmin(height) > -0.3


# ---------------------------------------------------------------------------------------
# Bad input: one InputError naming the file and the field


def _rig() -> Rig:
    K = np.array([[800.0, 0.0, 320.0], [0.0, 810.0, 240.0], [0.0, 0.0, 1.0]])
    return Rig(
        (
            Camera(K, np.eye(3), [0.0, 0.0, 3.0], np.zeros(5), (640, 480), "a"),
            Camera(K, QUARTER_TURN_Z, [0.5, 0.0, 3.0], np.zeros(5), (640, 480), "b"),
        )
    )


def _expect_error(path: Path, field: str | None, **kwargs) -> InputError:
    with pytest.raises(InputError) as err:
        load_rig(path, **kwargs)
    assert str(path) in str(err.value)
    if field is not None:
        assert err.value.field == field and repr(field) in str(err.value)
    return err.value


def _mutate_json(path: Path, fmt: str, change) -> None:
    save_rig(_rig(), path, fmt)
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))


NOT_A_ROTATION = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]

JSON_CASES = [
    ("rmpl-json", lambda d: d["cameras"][0].pop("R"), "cameras[0].R"),
    ("rmpl-json", lambda d: d["cameras"][1].update(K=[[1, 0], [0, 1]]), "cameras[1].K"),
    ("rmpl-json", lambda d: d["cameras"][0].update(t=[0.0, float("nan"), 1.0]), "cameras[0].t"),
    ("rmpl-json", lambda d: d["cameras"][0].update(R=NOT_A_ROTATION), "cameras[0].R"),
    ("rmpl-json", lambda d: d["cameras"][0].update(dist=[0.1, 0.2, 0.3]), "cameras[0].dist"),
    ("rmpl-json", lambda d: d["cameras"][1].update(name="a"), "cameras"),
    ("rmpl-json", lambda d: d["metadata"].update(units="furlong"), "metadata.units"),
    ("panoptic", lambda d: d["cameras"][1].pop("t"), "cameras[1].t"),
    ("panoptic", lambda d: d["cameras"][0].update(R=NOT_A_ROTATION), "cameras[0].R"),
    ("panoptic", lambda d: d["cameras"][0].update(distCoef=[0.0] * 3), "cameras[0].distCoef"),
    ("panoptic", lambda d: d["cameras"][0]["K"][2].__setitem__(2, 2.0), "cameras[0].K"),
    ("shelf4d", lambda d: d["a"].update(RT=d["a"]["RT"][:11]), "a.RT"),
    ("shelf4d", lambda d: d["b"]["RT"].__setitem__(0, 3.0), "b.RT"),
    ("shelf4d", lambda d: d["a"].pop("K"), "a.K"),
    ("shelf4d", lambda d: d["a"].update(imgSize=[640.5, 480]), "a.imgSize"),
    ("voxelpose", lambda d: d["b"].pop("fx"), "b.fx"),
    ("voxelpose", lambda d: d["a"].update(T=[[1.0], [2.0]]), "a.T"),
    ("voxelpose", lambda d: d["a"].update(fy=-3.0), "a.fx/fy"),
]


@pytest.mark.parametrize(("fmt", "change", "field"), JSON_CASES)
def test_bad_json_fields(tmp_path, fmt, change, field):
    path = tmp_path / OUTPUT_NAMES[fmt]
    _mutate_json(path, fmt, change)
    _expect_error(path, field)


TOML_CASES = [
    (
        "matrix = [[800.0, 0.0, 320.0], [0.0, 810.0, 240.0], [0.0, 0.0, 1.0]]",
        "matrix = [[800.0, 0.0, 320.0], [0.0, 810.0, 240.0]]",
        "a.matrix",
    ),
    ("rotation = [0.0, 0.0, 0.0]\n", "", "a.rotation"),
    ("translation = [0.0, 0.0, 3.0]", "translation = [0.0, nan, 3.0]", "a.translation"),
    ("fisheye = false", "fisheye = true", "a.fisheye"),
    ('units = "m"', 'units = "feet"', "metadata.units"),
]


@pytest.mark.parametrize(("old", "new", "field"), TOML_CASES)
def test_bad_anipose_fields(tmp_path, old, new, field):
    path = tmp_path / "calib.toml"
    save_rig(_rig(), path, "anipose")
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    _expect_error(path, field)


def test_bad_easymocap_fields(tmp_path):
    save_rig(_rig(), tmp_path, "easymocap")
    intri = (tmp_path / "intri.yml").read_text()
    (tmp_path / "intri.yml").write_text(
        intri.replace("K_b: !!opencv-matrix\n   rows: 3", "K_b: !!opencv-matrix\n   rows: 1")
    )
    _expect_error(tmp_path / "intri.yml", "K_b")
    (tmp_path / "intri.yml").write_text(intri)
    extri = (tmp_path / "extri.yml").read_text()
    rot = extri.index("Rot_a")
    (tmp_path / "extri.yml").write_text(extri[:rot] + extri[rot:].replace("1.0", "2.0", 1))
    _expect_error(tmp_path / "extri.yml", "Rot_a")
    (tmp_path / "extri.yml").unlink()
    _expect_error(tmp_path / "extri.yml", None)


@pytest.mark.shared
def test_bad_qualisys_fields(shared_data, tmp_path):
    text = (shared_data / QCA / "calibration" / "Calib.qca.txt").read_text()
    path = tmp_path / "Calib.qca.txt"
    path.write_text(text.replace('r11="', 'q11="', 1))
    _expect_error(path, "camera[cam_01].transform.r11")
    path.write_text(text.replace('r11="', 'r11="3', 1))
    _expect_error(path, "camera[cam_01].transform")
    path.write_text(text.replace("<transform", "<broken", 1))
    _expect_error(path, "camera[cam_01].transform")
    path.write_text(text.replace("</camera>", "", 1))
    assert "valid XML" in str(_expect_error(path, None))


def test_h36m_json_bad_fields(tmp_path):
    intr = {
        "calibration_matrix": [[1000.0, 0, 500], [0, 1000, 500], [0, 0, 1]],
        "distortion": [0.0] * 5,
    }
    doc = {
        "intrinsics": {"c1": intr},
        "extrinsics": {"S1": {"c1": {"R": NOT_A_ROTATION, "t": [[0.0], [0.0], [5000.0]]}}},
    }
    path = tmp_path / "camera-parameters.json"
    path.write_text(json.dumps(doc))
    _expect_error(path, "extrinsics.S1.c1.R")


@pytest.mark.parametrize("name", ["c.toml", "c.json", "intri.yml", "c.pkl", "c.qca.txt"])
def test_empty_file(tmp_path, name):
    path = tmp_path / name
    path.write_text("   \n")
    err = _expect_error(path, None)
    assert "empty" in str(err)


def test_missing_file(tmp_path):
    assert "no such file" in str(_expect_error(tmp_path / "nope.json", None))


def test_unknown_format(tmp_path):
    path = tmp_path / "calib.xyz"
    path.write_text("cameras")
    _expect_error(path, "format")
    _expect_error(path, "format", format="colmap")
    (tmp_path / "other.json").write_text('{"hello": 1}')
    _expect_error(tmp_path / "other.json", "format")
    (tmp_path / "folder").mkdir()
    _expect_error(tmp_path / "folder", None)


def test_malformed_text(tmp_path):
    (tmp_path / "a.json").write_text('{"cameras": [')
    assert "valid JSON" in str(_expect_error(tmp_path / "a.json", None))
    (tmp_path / "a.toml").write_text("[cam_0\nname = 1")
    assert "valid TOML" in str(_expect_error(tmp_path / "a.toml", None))
    (tmp_path / "a.yml").write_text("names: [a]\n")
    assert "%YAML" in str(_expect_error(tmp_path / "a.yml", None))


class _Boom:
    def __reduce__(self):
        return (print, ("this must never run",))


def test_pickle_with_code_is_refused(tmp_path, capsys):
    path = tmp_path / "cameras.pkl"
    path.write_bytes(pickle.dumps({("S1", "1"): _Boom()}))
    assert "builtins.print" in str(_expect_error(path, None))
    assert "never run" not in capsys.readouterr().out


def test_h36m_pickle_missing_field(tmp_path):
    cam = {
        "R": np.eye(3),
        "T": np.zeros((3, 1)),
        "f": np.ones((2, 1)),
        "c": np.ones((2, 1)),
        "k": np.zeros((3, 1)),
        "w": 100,
        "h": 100,
        "id": "1",
    }
    path = tmp_path / "cameras.pkl"
    path.write_bytes(pickle.dumps({("S1", "1"): cam}))
    _expect_error(path, "('S1', '1').p")
    _expect_error(path, "('S2', camera)", subject="S2")


# ---------------------------------------------------------------------------------------
# Writers refuse what a format cannot hold, and leave no file behind


def test_writers_refuse_what_the_format_cannot_store(tmp_path):
    K = np.array([[800.0, 2.0, 320.0], [0.0, 810.0, 240.0], [0.0, 0.0, 1.0]])
    cam = Camera(K, np.eye(3), [0, 0, 3.0], [0.1, 0, 0, 0, 0], (640, 480), "a b")
    rig = Rig((cam,))
    for fmt, field in [
        ("shelf4d", "a b.dist"),
        ("voxelpose", "a b.K"),
        ("easymocap", "name"),
        ("h36m", "format"),
    ]:
        path = tmp_path / OUTPUT_NAMES.get(fmt, "out.json")
        with pytest.raises(InputError) as err:
            save_rig(rig, path, fmt)
        assert err.value.field == field
        assert not path.exists()
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------
# A repeated key in a JSON calibration is refused, not silently dropped (issue 13, item 8)


def _repeat_camera_key(text: str) -> str:
    """The JSON text with camera "b"'s key renamed to "a": two entries under one key."""
    assert text.count('"b"') == 1
    return text.replace('"b"', '"a"')


@pytest.mark.parametrize("fmt", ["shelf4d", "voxelpose"])
def test_repeated_camera_key_is_refused(tmp_path, fmt):
    path = tmp_path / OUTPUT_NAMES[fmt]
    save_rig(_rig(), path, fmt)
    path.write_text(_repeat_camera_key(path.read_text()))
    err = _expect_error(path, "a")
    assert "repeated" in str(err)
    with pytest.raises(InputError, match="repeated"):
        load_rig(path, fmt)


def test_repeated_h36m_camera_id_is_refused(tmp_path):
    intr = (
        '{"calibration_matrix": [[1000, 0, 500], [0, 1000, 500], [0, 0, 1]], '
        '"distortion": [0, 0, 0, 0, 0]}'
    )
    extr = '{"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [[0], [0], [5000]]}'
    text = (
        f'{{"intrinsics": {{"c1": {intr}, "c1": {intr}}}, '
        f'"extrinsics": {{"S1": {{"c1": {extr}}}}}}}'
    )
    path = tmp_path / "camera-parameters.json"
    path.write_text(text)
    assert "repeated" in str(_expect_error(path, "c1"))


def test_repeated_key_in_rmpl_json_is_refused(tmp_path):
    path = tmp_path / "calib.json"
    save_rig(_rig(), path, "rmpl-json")
    doc = path.read_text()
    cameras = doc[doc.index('"cameras"') :].rstrip().removesuffix("}")
    path.write_text(doc.rstrip().removesuffix("}") + ", " + cameras + "}\n")
    assert "repeated" in str(_expect_error(path, "cameras"))


# ---------------------------------------------------------------------------------------
# A two-file output (EasyMocap) changes as a pair or not at all (issue 13, item 3)


def _easymocap_pair(folder: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted(folder.iterdir())}


def test_easymocap_pair_survives_a_failed_move(tmp_path, monkeypatch):
    save_rig(_rig(), tmp_path, "easymocap")
    old = _easymocap_pair(tmp_path)
    new_rig = Rig(tuple(Camera(c.K, c.R, c.t + 1.0, c.dist, c.size, c.name) for c in _rig()))
    real_replace, calls = os.replace, []

    def replace_failing_second(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace_failing_second)
    with pytest.raises(OSError):
        save_rig(new_rig, tmp_path, "easymocap")
    monkeypatch.undo()
    assert _easymocap_pair(tmp_path) == old  # the old pair, whole; no temporary files left
    save_rig(new_rig, tmp_path, "easymocap")
    assert _easymocap_pair(tmp_path) != old
    assert_same_rig(load_rig(tmp_path), new_rig)


def test_easymocap_pair_survives_a_failed_serialisation(tmp_path, monkeypatch):
    save_rig(_rig(), tmp_path, "easymocap")
    old = _easymocap_pair(tmp_path)
    real_write, calls = Path.write_text, []

    def write_failing_second(self, *args, **kwargs):
        calls.append(self)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real_write(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", write_failing_second)
    new_rig = Rig(tuple(Camera(c.K, c.R, c.t + 1.0, c.dist, c.size, c.name) for c in _rig()))
    with pytest.raises(OSError):
        save_rig(new_rig, tmp_path, "easymocap")
    monkeypatch.undo()
    assert _easymocap_pair(tmp_path) == old


def test_easymocap_output_onto_a_folder_is_refused_before_anything_moves(tmp_path):
    save_rig(_rig(), tmp_path, "easymocap")
    (tmp_path / "intri.yml").unlink()
    (tmp_path / "intri.yml").mkdir()
    extri = (tmp_path / "extri.yml").read_text()
    new_rig = Rig(tuple(Camera(c.K, c.R, c.t + 1.0, c.dist, c.size, c.name) for c in _rig()))
    with pytest.raises(InputError) as err:
        save_rig(new_rig, tmp_path, "easymocap")
    assert str(tmp_path / "intri.yml") in str(err.value) and "folder" in str(err.value)
    assert (tmp_path / "extri.yml").read_text() == extri
    assert sorted(p.name for p in tmp_path.iterdir()) == ["extri.yml", "intri.yml"]


# ---------------------------------------------------------------------------------------
# A file that cannot be read is one InputError, not a PermissionError traceback (issue 13, 6)


def _refuse_reading(monkeypatch, path: Path) -> None:
    """Make reading ``path`` fail as it does for a file the user may not read."""
    real_read_text, real_read_bytes = Path.read_text, Path.read_bytes

    def guard(real):
        def read(self, *args, **kwargs):
            if self == path:
                raise PermissionError(13, "Permission denied", str(self))
            return real(self, *args, **kwargs)

        return read

    monkeypatch.setattr(Path, "read_text", guard(real_read_text))
    monkeypatch.setattr(Path, "read_bytes", guard(real_read_bytes))


@pytest.mark.parametrize("name", ["calib.json", "calib.toml", "cameras.pkl"])
def test_unreadable_file(tmp_path, monkeypatch, name):
    path = tmp_path / name
    if name.endswith(".pkl"):
        path.write_bytes(pickle.dumps({}))
    else:
        save_rig(_rig(), path)
    _refuse_reading(monkeypatch, path)
    assert "Permission denied" in str(_expect_error(path, None))


# ---------------------------------------------------------------------------------------
# true/false where numbers belong is refused (they would read as 1 and 0)


@pytest.mark.parametrize(
    ("fmt", "change", "field"),
    [
        (
            "rmpl-json",
            lambda d: d["cameras"][0].update(R=[[True, False, False]] * 3),
            "cameras[0].R",
        ),
        ("rmpl-json", lambda d: d["cameras"][1].update(t=[0.0, 0.0, True]), "cameras[1].t"),
        ("shelf4d", lambda d: d["a"].update(imgSize=[640, True]), "a.imgSize"),
        ("voxelpose", lambda d: d["b"].update(fx=True), "b.fx"),
    ],
)
def test_booleans_are_not_numbers(tmp_path, fmt, change, field):
    path = tmp_path / OUTPUT_NAMES[fmt]
    _mutate_json(path, fmt, change)
    assert "true/false" in str(_expect_error(path, field))
