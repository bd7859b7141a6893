"""2D keypoint readers and the rmpl keypoint writer."""

from __future__ import annotations

import json
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rmpl.errors import InputError
from rmpl.io import keypoints as kp_module
from rmpl.io.keypoints import Keypoints2D, load_keypoints, save_keypoints
from rmpl.skeleton import BODY25, BODY25B, COCO17

# OpenPose COCO-18 order, written out here independently of the reader.
COCO18 = (
    "nose",
    "neck",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_hip",
    "right_knee",
    "right_ankle",
    "left_hip",
    "left_knee",
    "left_ankle",
    "right_eye",
    "left_eye",
    "right_ear",
    "left_ear",
)

DEMO = Path("pose2sim_demo/Pose2Sim/S01_Demo_SingleTrial")


def _person(num_joints: int, seed: int) -> np.ndarray:
    """A detection (J, 3): distinct pixel values away from 0, confidences in (0.1, 1)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(10.0, 900.0, size=(num_joints, 2))
    return np.concatenate([xy, rng.uniform(0.1, 1.0, size=(num_joints, 1))], axis=1)


def _write_openpose(d: Path, frame: int, people: list[np.ndarray], prefix: str = "") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    prefix = prefix or d.name.removesuffix("_json")
    doc = {
        "version": 1.3,
        "people": [
            {"person_id": [-1], "pose_keypoints_2d": p.reshape(-1).tolist()} for p in people
        ],
    }
    path = d / f"{prefix}.{frame:04d}.json"
    path.write_text(json.dumps(doc))
    return path


# --------------------------------------------------------------------------- real data


@pytest.mark.shared
def test_pose2sim_demo_loads_as_coco17(shared_data):
    pose_dir = shared_data / DEMO / "pose"
    kp = load_keypoints(pose_dir, to="coco17")

    assert kp.views == ["cam01", "cam02", "cam03", "cam04"]
    assert kp.skeleton == "coco17" and kp.num_joints == 17
    assert kp.fps == 60.0  # from the trial's Config.toml
    named = {
        int(m.group(1))
        for f in pose_dir.glob("cam0*_json/*.json")
        if (m := re.fullmatch(r"cam0\d\.(\d+)", f.stem))
    }
    assert kp.frames.tolist() == sorted(named)
    assert 90 <= kp.num_frames <= 110

    finite = np.isfinite(kp.keypoints).all(-1)
    assert finite.mean() > 0.2
    assert (np.isnan(kp.keypoints).all(-1) == ~finite).all()
    assert ((kp.scores > 0) == finite).all()
    xy = kp.keypoints[finite]
    assert (xy[:, 0] >= 0).all() and (xy[:, 0] <= 1088).all()  # portrait 1088 x 1920
    assert (xy[:, 1] >= 0).all() and (xy[:, 1] <= 1920).all()
    assert not (kp.keypoints == 0).all(-1).any()  # no (0, 0) sentinel survives

    # Pixels go down: noses sit above ankles, shoulders above hips, in every view.
    y = kp.keypoints[..., 1]
    for v in range(kp.num_views):
        nose = np.nanmedian(y[:, v, :, COCO17.index("nose")])
        ankles = np.nanmedian(y[:, v, :, COCO17.indices(["left_ankle", "right_ankle"])])
        hips = np.nanmedian(y[:, v, :, COCO17.indices(["left_hip", "right_hip"])])
        shoulders = np.nanmedian(y[:, v, :, COCO17.indices(["left_shoulder", "right_shoulder"])])
        assert nose < shoulders < hips < ankles


@pytest.mark.shared
def test_pose2sim_demo_matches_raw_body25b(shared_data):
    view_dir = shared_data / DEMO / "pose" / "cam01_json"
    raw = json.loads((view_dir / "cam01.0000.json").read_text())["people"]
    kp = load_keypoints(view_dir)
    assert kp.num_views == 1 and kp.num_people >= len(raw)
    for p, person in enumerate(raw):
        body = np.array(person["pose_keypoints_2d"], dtype=float).reshape(25, 3)
        for j, name in enumerate(COCO17.joints):
            x, y, c = body[BODY25B.index(name)]
            if c > 0:
                np.testing.assert_allclose(kp.keypoints[0, 0, p, j], [x, y])
                assert kp.scores[0, 0, p, j] == pytest.approx(c)
            else:
                assert np.isnan(kp.keypoints[0, 0, p, j]).all() and kp.scores[0, 0, p, j] == 0


@pytest.mark.shared
def test_skeleton_argument_and_config_tell_body25_from_body25b(shared_data, tmp_path):
    src = shared_data / DEMO / "pose" / "cam01_json"
    copy = tmp_path / "trial" / "pose" / "cam01_json"
    shutil.copytree(src, copy)
    body = np.array(
        json.loads((src / "cam01.0000.json").read_text())["people"][0]["pose_keypoints_2d"]
    ).reshape(25, 3)
    eye = COCO17.index("left_eye")

    default = load_keypoints(copy)  # no Config.toml: 25 points read as BODY_25
    np.testing.assert_allclose(default.keypoints[0, 0, 0, eye], body[BODY25.index("left_eye"), :2])
    assert default.fps is None

    explicit = load_keypoints(copy, skeleton="body25b")
    np.testing.assert_allclose(
        explicit.keypoints[0, 0, 0, eye], body[BODY25B.index("left_eye"), :2]
    )

    (tmp_path / "trial" / "Config.toml").write_text(
        "[project]\nframe_rate = 50\n[pose]\npose_model = 'BODY_25B'\n"
    )
    configured = load_keypoints(copy)
    np.testing.assert_array_equal(configured.keypoints, explicit.keypoints)
    assert configured.fps == 50.0
    native = load_keypoints(copy, to=None)
    assert native.skeleton == "body25b" and native.num_joints == 25


# --------------------------------------------------------------------------- OpenPose


def test_views_are_matched_by_frame_number(tmp_path):
    a, b = tmp_path / "a_json", tmp_path / "b_json"
    pa = {f: _person(17, f) for f in (0, 1, 2)}
    pb = {f: [_person(17, 10 + f), _person(17, 20 + f)] for f in (1, 2, 3)}
    for f, p in pa.items():
        _write_openpose(a, f, [p])
    for f, people in pb.items():
        _write_openpose(b, f, people)

    kp = load_keypoints([a, b])
    assert kp.views == ["a", "b"]
    assert kp.frames.tolist() == [0, 1, 2, 3]
    assert kp.keypoints.shape == (4, 2, 2, 17, 2)
    np.testing.assert_allclose(kp.keypoints[1, 0, 0], pa[1][:, :2])
    np.testing.assert_allclose(kp.scores[2, 0, 0], pa[2][:, 2])
    np.testing.assert_allclose(kp.keypoints[3, 1, 1], pb[3][1][:, :2])
    assert np.isnan(kp.keypoints[3, 0]).all() and (kp.scores[3, 0] == 0).all()  # a has no 3
    assert np.isnan(kp.keypoints[0, 1]).all() and (kp.scores[0, 1] == 0).all()  # b has no 0
    assert np.isnan(kp.keypoints[:3, 0, 1]).all()  # a never has a second person


def test_parent_directory_gives_one_view_per_subdirectory(tmp_path):
    for name in ("cam2_json", "cam1_json"):
        _write_openpose(tmp_path / "pose" / name, 5, [_person(17, 0)])
    kp = load_keypoints(tmp_path / "pose")
    assert kp.views == ["cam1", "cam2"] and kp.frames.tolist() == [5]


def test_mapping_names_views(tmp_path):
    _write_openpose(tmp_path / "x", 0, [_person(17, 1)])
    _write_openpose(tmp_path / "y", 0, [_person(17, 2)])
    kp = load_keypoints({"left": tmp_path / "y", "right": tmp_path / "x"})
    assert kp.views == ["left", "right"]
    np.testing.assert_allclose(kp.keypoints[0, 0, 0], _person(17, 2)[:, :2])


def test_openpose_default_file_names_and_stray_files(tmp_path):
    d = tmp_path / "v"
    d.mkdir()
    for f in (3, 12):
        doc = {"people": [{"pose_keypoints_2d": _person(17, f).reshape(-1).tolist()}]}
        (d / f"clip_{f:012d}_keypoints.json").write_text(json.dumps(doc))
    (d / "del_000001_0.json").write_text(json.dumps({"people": []}))
    kp = load_keypoints(d)
    assert kp.frames.tolist() == [3, 12]
    np.testing.assert_allclose(kp.keypoints[1, 0, 0], _person(17, 12)[:, :2])


def test_zero_points_become_nan_with_zero_score(tmp_path):
    p = _person(25, 3)
    p[4] = 0.0  # OpenPose's undetected joint
    p[7, :2] = 0.0  # a (0, 0) pixel with a confidence is a sentinel too
    p[10, 2] = 0.0  # a located joint with no confidence
    _write_openpose(tmp_path / "v", 0, [p])
    kp = load_keypoints(tmp_path / "v", to=None)
    assert kp.skeleton == "body25"
    for j in (4, 7, 10):
        assert np.isnan(kp.keypoints[0, 0, 0, j]).all() and kp.scores[0, 0, 0, j] == 0
    assert np.isfinite(kp.keypoints[0, 0, 0, 3]).all()


def test_coco18_becomes_coco17(tmp_path):
    p = _person(18, 4)
    _write_openpose(tmp_path / "v", 0, [p])
    kp = load_keypoints(tmp_path / "v", to="coco17")
    assert kp.skeleton == "coco17"
    for j, name in enumerate(COCO17.joints):
        np.testing.assert_allclose(kp.keypoints[0, 0, 0, j], p[COCO18.index(name), :2])
        assert kp.scores[0, 0, 0, j] == pytest.approx(p[COCO18.index(name), 2])


def test_body25_to_coco17_by_name(tmp_path):
    p = _person(25, 5)
    _write_openpose(tmp_path / "v", 0, [p])
    kp = load_keypoints(tmp_path / "v")
    for j, name in enumerate(COCO17.joints):
        np.testing.assert_allclose(kp.keypoints[0, 0, 0, j], p[BODY25.index(name), :2])


def test_frames_without_people_are_kept(tmp_path):
    _write_openpose(tmp_path / "v", 0, [])
    _write_openpose(tmp_path / "v", 1, [_person(17, 0)])
    kp = load_keypoints(tmp_path / "v", fps=30)
    assert kp.frames.tolist() == [0, 1] and kp.num_people == 1 and kp.fps == 30.0
    assert np.isnan(kp.keypoints[0]).all()


# --------------------------------------------------------------------------- COCO / MMPose


def test_coco_dataset_with_image_names(tmp_path):
    people = [_person(17, 1), _person(17, 2), _person(17, 3)]
    doc = {
        "images": [
            {"id": 7, "file_name": "frame_000010.jpg"},
            {"id": 8, "file_name": "frame_000011.jpg"},
            {"id": 9, "file_name": "frame_000012.jpg"},
        ],
        "annotations": [
            {"image_id": 7, "keypoints": people[0].reshape(-1).tolist(), "score": 0.9},
            {"image_id": 9, "keypoints": people[1].reshape(-1).tolist(), "score": 0.8},
            {"image_id": 9, "keypoints": people[2].reshape(-1).tolist(), "score": 0.7},
        ],
    }
    path = tmp_path / "cam3.json"
    path.write_text(json.dumps(doc))
    kp = load_keypoints(path)
    assert kp.views == ["cam3"] and kp.frames.tolist() == [10, 11, 12]
    assert kp.num_people == 2
    np.testing.assert_allclose(kp.keypoints[0, 0, 0], people[0][:, :2])
    np.testing.assert_allclose(kp.scores[2, 0, 1], people[2][:, 2])
    assert np.isnan(kp.keypoints[1]).all()  # image 8: nobody


def test_coco_ground_truth_visibility_flags(tmp_path):
    p = _person(17, 6)
    p[:, 2] = 2
    p[3] = 0  # not labelled
    doc = {
        "images": [{"id": 1, "file_name": "a.jpg"}],
        "annotations": [{"image_id": 1, "num_keypoints": 16, "keypoints": p.reshape(-1).tolist()}],
    }
    (tmp_path / "gt.json").write_text(json.dumps(doc))
    kp = load_keypoints(tmp_path / "gt.json", format="coco")
    assert kp.frames.tolist() == [1]  # no digits in the file name: the image id
    assert kp.scores[0, 0, 0, 3] == 0 and np.isnan(kp.keypoints[0, 0, 0, 3]).all()
    assert (np.delete(kp.scores[0, 0, 0], 3) == 1.0).all()


def test_coco_results_list(tmp_path):
    anns = [
        {"image_id": 4, "category_id": 1, "keypoints": _person(17, 4).reshape(-1).tolist()},
        {"image_id": 2, "category_id": 1, "keypoints": _person(17, 2).reshape(-1).tolist()},
    ]
    (tmp_path / "res.json").write_text(json.dumps(anns))
    kp = load_keypoints(tmp_path / "res.json")
    assert kp.frames.tolist() == [2, 4]
    np.testing.assert_allclose(kp.keypoints[0, 0, 0], _person(17, 2)[:, :2])


def _instance(p: np.ndarray) -> dict:
    return {
        "keypoints": p[:, :2].tolist(),
        "keypoint_scores": p[:, 2].tolist(),
        "bbox": [[0, 0, 1, 1]],
        "bbox_score": 0.9,
    }


def test_mmpose_video_predictions_halpe26(tmp_path):
    frames = [{"frame_id": f, "instances": [_instance(_person(26, f))]} for f in (0, 1, 2)]
    (tmp_path / "side.json").write_text(json.dumps(frames))
    (tmp_path / "front.json").write_text(json.dumps(frames[1:]))
    kp = load_keypoints([tmp_path / "front.json", tmp_path / "side.json"], to="coco17")
    assert kp.views == ["front", "side"] and kp.skeleton == "coco17"
    assert kp.frames.tolist() == [0, 1, 2]
    np.testing.assert_allclose(kp.keypoints[2, 1, 0], _person(26, 2)[:17, :2])  # body first
    assert np.isnan(kp.keypoints[0, 0]).all()


def test_mmpose_per_image_files(tmp_path):
    d = tmp_path / "cam1"
    d.mkdir()
    for f in (0, 1):
        (d / f"img_{f:05d}.json").write_text(json.dumps([_instance(_person(17, f))]))
    kp = load_keypoints(d)
    assert kp.frames.tolist() == [0, 1]
    np.testing.assert_allclose(kp.keypoints[1, 0, 0], _person(17, 1)[:, :2])


# --------------------------------------------------------------------------- rmpl format


@st.composite
def keypoint_sets(draw):
    T, V, P = draw(st.integers(1, 3)), draw(st.integers(1, 3)), draw(st.integers(0, 2))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-50.0, 2000.0, size=(T, V, P, 17, 2))
    scores = rng.uniform(0.0, 1.5, size=(T, V, P, 17))
    missing = rng.random((T, V, P, 17)) < 0.3
    xy[missing], scores[missing] = np.nan, 0.0
    start = draw(st.integers(-5, 1000))
    frames = start + np.cumsum(rng.integers(1, 4, size=T))
    fps = draw(st.one_of(st.none(), st.floats(1.0, 240.0)))
    views = [f"cam {v}" for v in range(V)]
    return Keypoints2D(xy, scores, "coco17", views, frames, fps)


@settings(max_examples=25, deadline=None)
@given(kp=keypoint_sets(), ext=st.sampled_from([".npz", ".json"]))
def test_rmpl_round_trip(kp, ext):
    with tempfile.TemporaryDirectory() as d:
        path = save_keypoints(kp, Path(d) / f"kp{ext}")
        back = load_keypoints(path)
    np.testing.assert_array_equal(back.keypoints, kp.keypoints)  # NaN == NaN here
    np.testing.assert_array_equal(back.scores, kp.scores)
    assert back.views == kp.views and back.skeleton == kp.skeleton
    np.testing.assert_array_equal(back.frames, kp.frames)
    assert back.fps == kp.fps


def test_rmpl_keeps_native_set_or_converts(tmp_path):
    p = _person(25, 9)
    _write_openpose(tmp_path / "v", 0, [p])
    native = load_keypoints(tmp_path / "v", skeleton="body25b", to=None)
    path = save_keypoints(native, tmp_path / "kp.json")
    assert load_keypoints(path, to=None).skeleton == "body25b"
    again = load_keypoints(path, to="coco17")
    assert again.skeleton == "coco17"
    np.testing.assert_allclose(again.keypoints[0, 0, 0], p[:17, :2])


# --------------------------------------------------------------------------- bad input


def _raises(match_path: Path, field: str | None, call):
    with pytest.raises(InputError) as info:
        call()
    err = info.value
    assert Path(err.path) == match_path
    assert err.field == field
    assert str(match_path) in str(err)
    return err


def test_empty_file(tmp_path):
    d = tmp_path / "v"
    _write_openpose(d, 0, [_person(17, 0)])
    empty = d / "v.0001.json"
    empty.write_text("")
    err = _raises(empty, None, lambda: load_keypoints(d))
    assert "empty" in str(err)


def test_wrong_keypoint_length(tmp_path):
    d = tmp_path / "v"
    _write_openpose(d, 0, [_person(17, 0)])
    bad = _write_openpose(d, 1, [_person(17, 1), _person(17, 2)[:16]])
    err = _raises(bad, "people[1].pose_keypoints_2d", lambda: load_keypoints(d))
    assert "51" in str(err) and "48" in str(err)


def test_count_not_matching_skeleton_argument(tmp_path):
    bad = _write_openpose(tmp_path / "v", 0, [_person(17, 0)])
    _raises(
        bad,
        "people[0].pose_keypoints_2d",
        lambda: load_keypoints(tmp_path / "v", skeleton="body25b"),
    )


def test_nan_score(tmp_path):
    p = _person(17, 0)
    p[2, 2] = np.nan
    bad = _write_openpose(tmp_path / "v", 0, [p])  # json writes NaN, Python reads it back
    err = _raises(bad, "people[0].pose_keypoints_2d", lambda: load_keypoints(tmp_path / "v"))
    assert "NaN" in str(err)


def test_missing_key(tmp_path):
    d = tmp_path / "v"
    _write_openpose(d, 0, [_person(17, 0)])
    bad = d / "v.0001.json"
    bad.write_text(json.dumps({"people": [{"face_keypoints_2d": []}]}))
    _raises(bad, "people[0].pose_keypoints_2d", lambda: load_keypoints(d))
    no_people = d / "v.0002.json"
    bad.unlink()
    no_people.write_text(json.dumps({"version": 1.3, "persons": []}))
    _raises(no_people, "people", lambda: load_keypoints(d, format="openpose"))


def test_missing_key_rmpl(tmp_path):
    kp = Keypoints2D(np.zeros((1, 1, 1, 17, 2)) + 5, np.ones((1, 1, 1, 17)))
    path = save_keypoints(kp, tmp_path / "kp.json")
    doc = json.loads(path.read_text())
    del doc["scores"]
    path.write_text(json.dumps(doc))
    _raises(path, "scores", lambda: load_keypoints(path))


def test_non_existent_directory(tmp_path):
    missing = tmp_path / "nowhere" / "cam01_json"
    _raises(missing, None, lambda: load_keypoints([missing]))


def test_directory_without_json(tmp_path):
    (tmp_path / "empty").mkdir()
    _raises(tmp_path / "empty", None, lambda: load_keypoints(tmp_path / "empty"))


def test_not_json(tmp_path):
    bad = tmp_path / "x.json"
    bad.write_text("{people: ]")
    _raises(bad, None, lambda: load_keypoints(bad))


def test_bad_npz(tmp_path):
    bad = tmp_path / "x.npz"
    bad.write_bytes(b"not a zip archive")
    _raises(bad, None, lambda: load_keypoints(bad))


def test_constructor_checks_shapes_and_missing():
    with pytest.raises(InputError, match="shape"):
        Keypoints2D(np.zeros((1, 1, 17, 2)), np.zeros((1, 1, 17)))
    with pytest.raises(InputError, match="score 0"):
        Keypoints2D(np.full((1, 1, 1, 17, 2), np.nan), np.ones((1, 1, 1, 17)))
    with pytest.raises(InputError, match="17 joints"):
        Keypoints2D(np.zeros((1, 1, 1, 17, 2)), np.ones((1, 1, 1, 17)), skeleton="body25")


# --------------------------------------------------------------------------- atomic save


def test_failed_save_leaves_no_file(tmp_path, monkeypatch):
    kp = Keypoints2D(np.ones((2, 1, 1, 17, 2)), np.ones((2, 1, 1, 17)))
    with pytest.raises(InputError):
        save_keypoints(kp, tmp_path / "kp.csv")

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(kp_module.json, "dumps", boom)
    monkeypatch.setattr(kp_module.np, "savez_compressed", boom)
    for name in ("kp.json", "kp.npz"):
        with pytest.raises(OSError, match="disk full"):
            save_keypoints(kp, tmp_path / name)
    kp.scores = np.full((2, 1, 1, 17), np.nan)  # invalid after construction
    monkeypatch.undo()
    with pytest.raises(InputError):
        save_keypoints(kp, tmp_path / "kp.npz")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- array types


def _npz_with(path: Path, **arrays) -> Path:
    T, V, P, J = 2, 2, 1, 17
    fields = dict(
        format=np.array("rmpl.keypoints2d"),
        keypoints=np.full((T, V, P, J, 2), 100.0),
        scores=np.full((T, V, P, J), 0.9),
        skeleton=np.array("coco17"),
        views=np.array(["a", "b"]),
        frames=np.arange(T),
        fps=np.array(30.0),
    )
    with open(path, "wb") as f:
        np.savez(f, **{**fields, **arrays})
    return path


@pytest.mark.parametrize(
    "name, value",
    [
        ("keypoints", np.ones((2, 2, 1, 17, 2), bool)),
        ("keypoints", np.full((2, 2, 1, 17, 2), 100 + 1j)),
        ("scores", np.ones((2, 2, 1, 17), bool)),
        ("scores", np.full((2, 2, 1, 17), "0.9")),
    ],
)
def test_bool_complex_and_text_arrays_are_refused_by_name(tmp_path, name, value):
    path = _npz_with(tmp_path / "kp.npz", **{name: value})
    with pytest.raises(InputError, match=rf"kp\.npz: field '{name}': expected an array of real"):
        load_keypoints(path)


def test_object_array_is_refused_naming_the_array(tmp_path):
    obj = np.empty((2, 2, 1, 17, 2), object)
    obj[...] = 1.0
    path = _npz_with(tmp_path / "kp.npz", keypoints=obj)
    with pytest.raises(InputError, match=r"field 'keypoints'.*object array") as e:
        load_keypoints(path)
    assert "allow_pickle" not in str(e.value)


def test_garbage_npz_message_has_no_numpy_advice(tmp_path):
    (tmp_path / "kp.npz").write_bytes(b"\x80\x04 not an archive" * 20)
    with pytest.raises(InputError, match="not a zip") as e:
        load_keypoints(tmp_path / "kp.npz")
    assert "allow_pickle" not in str(e.value)


def test_api_arrays_of_bools_are_refused():
    with pytest.raises(InputError, match="field 'keypoints'.*bool"):
        Keypoints2D(np.ones((1, 1, 1, 17, 2), bool), np.ones((1, 1, 1, 17)))
