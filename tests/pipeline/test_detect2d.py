"""2D detection from videos and image folders (rmpl.pipeline.detect2d) and ``rmpl run --videos``.

The bad-input and cache tests need only OpenCV and use a stand-in detector. The end-to-end
test runs the real MediaPipe detector on videos of an anny body rendered here, so it needs
mediapipe, moderngl (EGL) and anny (rmpl[synth]); anny's cache is $ANNY_CACHE_DIR or is
built on first use (tests.conftest.synth_ready).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.skeleton import COCO17
from tests.conftest import synth_ready

cv2 = pytest.importorskip("cv2")

from rmpl.pipeline.detect2d import (  # noqa: E402  (after the importorskip)
    check_image_folders,
    check_videos,
    detect_images,
    detect_videos,
)


def write_video(path: Path, frames: list[np.ndarray], fps: float = 25.0) -> Path:
    """RGB uint8 frames (H, W, 3) -> an mp4 (MPEG-4 part 2, which OpenCV's wheels encode)."""
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    assert writer.isOpened()
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    writer.release()
    return path


def _frames(n: int, seed: int = 0, size=(96, 64)) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8) for _ in range(n)]


class CountingDetector:
    """A stand-in Detector: the mean brightness of each image as every joint's x."""

    name = "counting"
    skeleton = COCO17

    def __init__(self) -> None:
        self.images = 0

    def __call__(self, images):
        self.images += len(images)
        kp = np.zeros((len(images), 17, 2))
        kp[..., 0] = np.array([im.mean() for im in images])[:, None]
        kp[..., 1] = np.arange(17)
        return kp, np.full((len(images), 17), 0.5)


def _rig(n: int) -> Rig:
    K = np.array([[100.0, 0, 48], [0, 100, 32], [0, 0, 1]])
    cams = []
    for v in range(n):
        a = 2 * np.pi * v / n
        R, t = look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 1.5]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(96, 64), name=f"cam{v}"))
    return Rig(tuple(cams))


# --------------------------------------------------------------------------- readers


def test_detect_videos_shapes_names_fps_and_resume(tmp_path):
    paths = [write_video(tmp_path / f"c{v}.mp4", _frames(4, v), fps=30) for v in range(2)]
    det = CountingDetector()
    kp = detect_videos(paths, det, batch=3, cache_dir=tmp_path / "cache", progress=False)
    assert kp.keypoints.shape == (4, 2, 1, 17, 2) and kp.scores.shape == (4, 2, 1, 17)
    assert kp.views == ["c0", "c1"] and kp.fps == pytest.approx(30)
    assert kp.frames.tolist() == [0, 1, 2, 3] and det.images == 8
    # The two videos differ, so do the detections (frames are not mixed up between views).
    assert not np.allclose(kp.keypoints[:, 0], kp.keypoints[:, 1])
    again = detect_videos(paths, det, cache_dir=tmp_path / "cache", progress=False)
    assert det.images == 8  # every view came from the resume cache
    np.testing.assert_array_equal(again.keypoints, kp.keypoints)
    write_video(paths[1], _frames(4, 7), fps=30)  # a new video under the same name
    detect_videos(paths, det, cache_dir=tmp_path / "cache", progress=False)
    assert det.images == 12  # only that view ran again


def test_videos_not_started_together_are_detected_whole(tmp_path, caplog):
    """Cameras started at other instants or filming at other rates give videos of other
    lengths: each is detected whole, the shorter ending in empty frames, with one warning
    that points to rmpl sync."""
    a = write_video(tmp_path / "a.mp4", _frames(6, 1), fps=30)
    b = write_video(tmp_path / "b.mp4", _frames(4, 2), fps=25)
    det = CountingDetector()
    with caplog.at_level("WARNING"):
        kp = detect_videos([a, b], det, progress=False)
    assert kp.keypoints.shape[:2] == (6, 2) and det.images == 10
    assert (kp.scores[:4, 1] > 0).all() and (kp.scores[4:, 1] == 0).all()
    assert np.isnan(kp.keypoints[4:, 1]).all() and (kp.scores[:, 0] > 0).all()
    assert "rmpl sync" in caplog.text and "b.mp4 4 frames at 25/s" in caplog.text


def test_detect_images_natural_order(tmp_path):
    for v in range(2):
        d = tmp_path / f"cam{v}"
        d.mkdir()
        for i, im in enumerate(_frames(11, v)):
            cv2.imwrite(str(d / f"img{i}.png"), im)
        (d / "notes.txt").write_text("not an image")
    det = CountingDetector()
    kp = detect_images([tmp_path / "cam0", tmp_path / "cam1"], det, fps=10, progress=False)
    assert kp.keypoints.shape == (11, 2, 1, 17, 2) and kp.views == ["cam0", "cam1"]
    # img10 is frame 10, not frame 2 (natural order): its brightness is at row 10.
    want = cv2.imread(str(tmp_path / "cam1" / "img10.png")).mean()
    assert kp.keypoints[10, 1, 0, 0, 0] == pytest.approx(want)


def test_bad_videos_name_the_file(tmp_path):
    a = write_video(tmp_path / "a.mp4", _frames(5))
    short = write_video(tmp_path / "short.mp4", _frames(3))
    slow = write_video(tmp_path / "slow.mp4", _frames(5), fps=12.5)
    junk = tmp_path / "junk.mp4"
    junk.write_text("this is not a video")
    with pytest.raises(InputError, match=r"short\.mp4.*5 frames.*got 3 frames"):
        check_videos([a, short])
    with pytest.raises(InputError, match=r"slow\.mp4.*25 frames/s.*got 12\.5 frames/s"):
        check_videos([a, slow])
    with pytest.raises(InputError, match=r"junk\.mp4"):
        check_videos([a, junk])
    with pytest.raises(InputError, match=r"nope\.mp4.*no such file"):
        check_videos([a, tmp_path / "nope.mp4"])


def test_bad_image_folders(tmp_path):
    for name, n in (("a", 3), ("b", 2)):
        (tmp_path / name).mkdir()
        for i, im in enumerate(_frames(n)):
            cv2.imwrite(str(tmp_path / name / f"{i}.jpg"), im)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match=r"empty.*image files"):
        check_image_folders([tmp_path / "a", tmp_path / "empty"])
    with pytest.raises(InputError, match=r"b.*3 images.*got 2 images"):
        check_image_folders([tmp_path / "a", tmp_path / "b"])
    (tmp_path / "b" / "2.jpg").write_text("broken")
    with pytest.raises(InputError, match=r"2\.jpg.*OpenCV can read"):
        check_image_folders([tmp_path / "a", tmp_path / "b"])


@pytest.mark.parametrize(
    "case, message",
    [
        ("lengths", "got 3 frames"),
        ("fps", "got 12.5 frames/s"),
        ("unreadable", "junk.mp4"),
        ("cameras", "3 cameras for"),
        ("empty", "image files"),
    ],
)
def test_run_bad_input_is_one_line_and_leaves_nothing(tmp_path, capsys, case, message):
    save_rig(_rig(3 if case != "cameras" else 2), tmp_path / "calib.toml")
    videos = [write_video(tmp_path / f"v{v}.mp4", _frames(5, v)) for v in range(3)]
    source = ["--videos", *map(str, videos)]
    if case == "lengths":
        write_video(videos[2], _frames(3))
    elif case == "fps":
        write_video(videos[1], _frames(5), fps=12.5)
    elif case == "unreadable":
        videos[2] = tmp_path / "junk.mp4"
        videos[2].write_bytes(b"\x00" * 1000)
        source = ["--videos", *map(str, videos)]
    elif case == "empty":
        for v in range(3):
            (tmp_path / f"im{v}").mkdir()
        source = ["--images", *(str(tmp_path / f"im{v}") for v in range(3))]
    out = tmp_path / "out"
    code = main(["run", "--calib", str(tmp_path / "calib.toml"), *source, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rmpl run: error:"), err
    assert message in lines[0]
    assert not out.exists() or not any(out.rglob("*"))


def test_cache_is_not_reused_for_other_inputs(tmp_path, monkeypatch):
    from rmpl.pipeline import detect2d
    from rmpl.pipeline.inputs import InputSpec, _load_2d

    det = CountingDetector()
    monkeypatch.setitem(detect2d.DETECTORS, "counting", lambda: det)
    det.close = lambda: None
    save_rig(_rig(2), tmp_path / "calib.toml")
    videos = [str(write_video(tmp_path / f"v{v}.mp4", _frames(4, v))) for v in range(2)]
    args = InputSpec(calib=str(tmp_path / "calib.toml"), videos=videos, detector="counting")
    cache = tmp_path / "out" / "keypoints2d.npz"
    first = _load_2d(args, cache)
    assert det.images == 8 and cache.is_file()
    assert not (tmp_path / "out" / ".detect2d").exists()  # the resume files are cleared
    _load_2d(args, cache)
    assert det.images == 8  # same inputs: cached
    write_video(tmp_path / "v1.mp4", _frames(4, 9))
    second = _load_2d(args, cache)
    assert det.images == 16  # one video changed: everything is detected again
    assert not np.allclose(first.keypoints[:, 1], second.keypoints[:, 1])


class OracleDetector:
    """A stand-in Detector that reads (view, frame) from an image's uniform grey level and
    returns the true projections: the whole ``rmpl run --videos`` path without mediapipe."""

    name = "oracle"
    skeleton = COCO17

    def __init__(self, pixels: np.ndarray) -> None:
        self.pixels = pixels  # (T, V, J, 2)

    def __call__(self, images):
        code = np.array([int(round(im.mean() / 20)) - 1 for im in images])
        t, v = code // self.pixels.shape[1], code % self.pixels.shape[1]
        return self.pixels[t, v].copy(), np.full((len(images), 17), 0.9)

    def close(self) -> None:
        pass


def test_run_videos_end_to_end_with_a_stand_in_detector(tmp_path, monkeypatch):
    from rmpl.io.poses import load_poses
    from rmpl.pipeline import detect2d

    T, V = 3, 3
    rig = _rig(V)
    X = np.random.default_rng(0).uniform(-0.3, 0.3, (T, 17, 3)) + [0, 0, 1]
    monkeypatch.setitem(detect2d.DETECTORS, "oracle", lambda: OracleDetector(rig.project(X)))
    save_rig(rig, tmp_path / "calib.toml")
    # Videos named after the cameras but given in another order: matched by name.
    for v in range(V):
        grey = [np.full((64, 96, 3), 20 * (t * V + v + 1), np.uint8) for t in range(T)]
        write_video(tmp_path / f"cam{v}.mp4", grey, fps=20)
    videos = [str(tmp_path / f"cam{v}.mp4") for v in (2, 0, 1)]
    out = tmp_path / "out"
    args = ["run", "--calib", str(tmp_path / "calib.toml"), "--videos", *videos, "--out"]
    args += [str(out), "--detector", "oracle", "--method", "triangulate", "--filter", "none"]
    args += ["--formats", "npz,json,bvh", "--no-pictures"]
    assert main(args) == 0
    poses = load_poses(out / "poses.npz")
    assert poses.fps == pytest.approx(20)
    np.testing.assert_allclose(poses.points[:, 0], X, atol=1e-6)
    names = {p.name for p in out.iterdir()}
    # The detections (with their inputs' fingerprint) and one overlay per camera; the
    # per-view resume files are gone. (Other outputs of rmpl run are tested elsewhere.)
    assert {
        "keypoints2d.inputs.json",
        "keypoints2d.npz",
        "overlay_cam0.mp4",
        "overlay_cam1.mp4",
        "overlay_cam2.mp4",
        "poses.bvh",
        "poses.json",
        "poses.npz",
    } <= names, names
    assert ".detect2d" not in names


# --------------------------------------------------------------------------- real detector


def _anny_cache() -> Path:
    return synth_ready("mediapipe", "moderngl", "anny")


def render_walk(folder: Path, num_frames: int = 5, views: int = 3, fps: float = 10.0):
    """Videos of an anny body stepping forward, seen by ``views`` cameras around it.

    Writes ``cam<v>.mp4`` and ``calib.toml`` into ``folder``; returns the rig and the
    ground-truth COCO-17 keypoints regressed from the mesh, shape (T, 17, 3), metres.
    """
    from rmpl.synth.body import BodyModel, place_bodies
    from rmpl.synth.render import Renderer, random_lighting, random_outfits

    model = BodyModel(cache_dir=_anny_cache())
    pose = model.identity_pose(num_frames)
    # Arms down from the A-pose a little more, and the legs swinging: a stride per second.
    phase = 2 * np.pi * np.arange(num_frames) / fps
    for side, sign in ((".L", 1.0), (".R", -1.0)):
        swing = np.deg2rad(20) * sign * np.sin(phase)
        c, s = np.cos(swing), np.sin(swing)
        hip = model.bone_index("upperleg01" + side)
        pose[:, hip, 1, 1], pose[:, hip, 1, 2] = c, -s
        pose[:, hip, 2, 1], pose[:, hip, 2, 2] = s, c
    bodies = model(pose, np.full((num_frames, 6), 0.5))
    yaw = np.full(num_frames, 0.3)
    position = np.stack([np.linspace(0, 0.4, num_frames), np.zeros(num_frames)], -1)
    vertices, keypoints = place_bodies(bodies.vertices, bodies.keypoints, yaw, position)
    width, height = 480, 360
    K = np.array([[420.0, 0, (width - 1) / 2], [0, 420, (height - 1) / 2], [0, 0, 1]])
    centre = np.array([0.2, 0.0, 0.9])
    cams = []
    for v in range(views):
        a = -np.pi / 2 + (v - (views - 1) / 2) * np.deg2rad(60)  # in front of the body (-y)
        eye = centre + [3.6 * np.cos(a), 3.6 * np.sin(a), 0.4]
        R, t = look_at(eye, centre)
        cams.append(Camera(K, R, t, size=(width, height), name=f"cam{v}"))
    rig = Rig(tuple(cams))
    save_rig(rig, folder / "calib.toml")
    colors = np.repeat(random_outfits(model.vertex_parts, 1, rng=3), num_frames, axis=0)
    light = random_lighting(3)
    B = num_frames
    with Renderer(model.faces, model.num_vertices) as renderer:
        images = renderer.render(
            vertices,
            colors,
            np.broadcast_to(rig.K, (B, views, 3, 3)),
            np.broadcast_to(rig.R, (B, views, 3, 3)),
            np.broadcast_to(rig.t, (B, views, 3)),
            np.broadcast_to(rig.sizes, (B, views, 2)),
            lighting=[light] * B,
            rng=0,
        )
    for v in range(views):
        write_video(folder / f"cam{v}.mp4", [images[b * views + v] for b in range(B)], fps)
    return rig, keypoints


#: Bound on the mean 3D joint error against the mesh's regressed keypoints, metres.
#: MediaPipe's joints are not the regressor's (ears especially sit elsewhere), so this
#: bounds detector bias plus lifting error, not the lifter alone. Measured (the command in
#: the module docstring, with -s): 0.021 m with rmpl, 0.018 m with triangulation.
MAX_MPJPE = 0.06


@pytest.mark.parametrize(
    "method, detector",
    [("rmpl", "mediapipe"), ("triangulate", "mediapipe"), ("rmpl", "blazepose-multi")],
)
def test_run_on_rendered_videos_with_mediapipe(tmp_path, method, detector):
    from rmpl.io.poses import load_poses

    rig, gt = render_walk(tmp_path)
    out = tmp_path / "out"
    args = ["run", "--calib", str(tmp_path / "calib.toml"), "--out", str(out)]
    args += ["--videos", *(str(tmp_path / f"cam{v}.mp4") for v in range(len(rig)))]
    args += ["--method", method, "--filter", "none", "--formats", "npz", "--no-pictures"]
    args += ["--detector", detector]
    assert main(args) == 0
    assert (out / "keypoints2d.npz").is_file() and (out / "keypoints2d.inputs.json").is_file()
    poses = load_poses(out / "poses.npz")
    # COCO-17, or HALPE-26 (whose first 17 joints are COCO-17) when the 2D has the feet
    assert poses.points.shape in ((len(gt), 1, 17, 3), (len(gt), 1, 26, 3))
    err = np.linalg.norm(poses.points[:, 0, :17] - gt, axis=-1)  # (T, 17)
    assert np.isfinite(err).mean() > 0.9
    per_joint = np.nanmean(err, 0).round(3)
    print(f"\n{method}, {detector}: MPJPE {np.nanmean(err):.3f} m, per joint {per_joint}")
    assert np.nanmean(err) < MAX_MPJPE, np.nanmean(err, axis=0).round(3)


# --------------------------------------------------------------------------- people axis


class PeopleDetector:
    """A stand-in multi-person Detector: image brightness b says how many people are in it
    (b // 40, at most ``max_people``); person n has every joint at x = 10 n + b / 100.
    Counts its resets and images."""

    name = "people"
    skeleton = COCO17

    def __init__(self, max_people: int = 3) -> None:
        self.max_people = max_people
        self.images = self.resets = 0

    def reset(self) -> None:
        self.resets += 1

    def __call__(self, images):
        self.images += len(images)
        B, N = len(images), self.max_people
        kp, sc = np.full((B, N, 17, 2), np.nan), np.zeros((B, N, 17))
        for b, im in enumerate(images):
            for n in range(min(int(im.mean() // 40), N)):
                kp[b, n] = [10 * n + im.mean() / 100, 5.0]
                sc[b, n] = 0.8
        return kp, sc


def _grey(levels: list[int]) -> list[np.ndarray]:
    return [np.full((64, 96, 3), g, np.uint8) for g in levels]


def test_single_and_multi_person_detectors_share_the_path(tmp_path):
    # View 0: 1, 2 then 1 people; view 1: nobody, 1, 1.
    paths = [
        write_video(tmp_path / "a.mp4", _grey([50, 90, 50])),
        write_video(tmp_path / "b.mp4", _grey([10, 50, 60])),
    ]
    multi = PeopleDetector(max_people=4)
    kp = detect_videos(paths, multi, batch=2, progress=False)
    # Four slots, only two ever used: trimmed to P = 2.
    assert kp.keypoints.shape == (3, 2, 2, 17, 2) and kp.scores.shape == (3, 2, 2, 17)
    people = (kp.scores > 0).any(-1).sum(-1)  # (T, V)
    assert people.tolist() == [[1, 0], [2, 1], [1, 1]]
    assert np.isnan(kp.keypoints[0, 1]).all() and (kp.scores[0, 1] == 0).all()
    assert multi.resets == 2  # once per view: frames of one view are one video
    single = CountingDetector()
    one = detect_videos(paths, single, batch=2, progress=False)
    assert one.keypoints.shape == (3, 2, 1, 17, 2)


def test_cache_keeps_single_and_multi_person_results_apart(tmp_path):
    paths = [write_video(tmp_path / f"c{v}.mp4", _grey([90, 90])) for v in range(2)]
    cache = tmp_path / "cache"
    multi = PeopleDetector(max_people=3)
    kp = detect_videos(paths, multi, cache_dir=cache, progress=False)
    assert kp.keypoints.shape[2] == 2 and multi.images == 4
    detect_videos(paths, multi, cache_dir=cache, progress=False)
    assert multi.images == 4  # reused
    # A detector of the same name with one person per image does not read that cache.
    single = PeopleDetector(max_people=1)
    one = detect_videos(paths, single, cache_dir=cache, progress=False)
    assert single.images == 4 and one.keypoints.shape[2] == 1
    # Nor does the multi-person one read the single-person cache that replaced it.
    again = detect_videos(paths, PeopleDetector(max_people=3), cache_dir=cache, progress=False)
    assert again.keypoints.shape[2] == 2


def test_a_view_with_nobody_is_named_and_nobody_anywhere_is_an_error(tmp_path, caplog):
    full = write_video(tmp_path / "full.mp4", _grey([90, 90, 90]))
    empty = write_video(tmp_path / "empty.mp4", _grey([10, 10, 10]))
    with caplog.at_level("WARNING", logger="rmpl.pipeline.detect2d"):
        kp = detect_videos([full, empty], PeopleDetector(), progress=False)
    assert "nobody was detected in any of the 3 frames of" in caplog.text
    assert "empty.mp4" in caplog.text and "full.mp4" not in caplog.text
    assert (kp.scores[:, 1] == 0).all() and (kp.scores[:, 0] > 0).any()
    other = write_video(tmp_path / "other.mp4", _grey([20, 20, 20]))
    with pytest.raises(InputError, match=r"empty\.mp4, .*other\.mp4.*at least one person"):
        detect_videos([empty, other], PeopleDetector(), progress=False)


def test_videos_of_different_lengths_with_a_multi_person_detector(tmp_path):
    """Every frame of each video is seen once; the shorter view ends in empty frames."""
    a = write_video(tmp_path / "a.mp4", _grey([90] * 5))
    short = write_video(tmp_path / "short.mp4", _grey([90] * 3))
    det = PeopleDetector()
    kp = detect_videos([a, short], det, progress=False)
    assert det.images == 8 and kp.keypoints.shape[:2] == (5, 2)
    assert (kp.scores[3:, 1] == 0).all() and (kp.scores[:3, 1].max(-1) > 0).any()


def test_a_detector_breaking_the_protocol_is_named(tmp_path):
    class Broken(PeopleDetector):
        name = "broken"

        def __call__(self, images):
            kp, sc = super().__call__(images)
            return kp[:, :, :5], sc[:, :, :5]  # 5 joints, not 17

    paths = [write_video(tmp_path / "a.mp4", _grey([90, 90]))]
    with pytest.raises(ValueError, match=r"detector 'broken' returned keypoints \(2, 3, 5, 2\)"):
        detect_videos(paths, Broken(), progress=False)


def test_registry_names_and_default(tmp_path):
    from rmpl.pipeline.detect2d import DEFAULT_DETECTOR, DETECTORS

    assert DEFAULT_DETECTOR in DETECTORS
    assert {"mediapipe", "blazepose-multi", "blazepose-multi-static"} <= set(DETECTORS)
    video = write_video(tmp_path / "a.mp4", _grey([90]))
    with pytest.raises(ValueError, match="detector must be one of"):
        detect_videos([video], "nope", progress=False)
