"""``rmpl simulate``: the rig, the clocks, the lens warp, a tiny recording whose truth is
checked against the videos, and the chain scored (recomputed here independently).

The recordings need anny and a headless OpenGL context (tests.conftest.synth_ready); the
chain needs the shipped detector too (rmpl[detect])."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera
from rmpl.simulate.capture import SimulateConfig, parse_offsets, simulate, timing_of
from rmpl.simulate.rig import RigSpec, build_rig, fov_to_focal, volume_of
from tests.conftest import synth_ready

# --------------------------------------------------------------------------- the rig


@pytest.mark.parametrize("preset", ["ring", "arc", "corners"])
def test_presets_look_at_the_volume(preset):
    spec = RigSpec(preset, cameras=5, radius=3.5, height=2.0, fov=70.0, resolution=(800, 600))
    rig = build_rig(spec)
    assert len(rig) == 5 and rig.names == [f"cam{v}" for v in range(1, 6)]
    centre = np.array([0.0, 0.0, spec.aim])
    for cam in rig:
        uv = cam.project(centre)  # the aim point is the image centre (distortion: none there)
        assert np.allclose(uv, [(800 - 1) / 2, (600 - 1) / 2], atol=1e-6)
        assert cam.K[0, 0] == pytest.approx(fov_to_focal(70.0, 800))
        flat = np.linalg.norm(cam.center[:2])
        if preset != "corners":
            assert flat == pytest.approx(3.5) and cam.center[2] == pytest.approx(2.0)
    xs, ys, counts = volume_of(rig)
    mid = counts[np.argmin(np.abs(ys)), np.argmin(np.abs(xs))]
    assert mid == 5  # every camera sees the centre


def test_bad_rigs_are_refused_in_one_line(tmp_path):
    with pytest.raises(InputError, match="ring, arc, corners"):
        build_rig(RigSpec("dome"))
    with pytest.raises(InputError, match="--cameras"):
        build_rig(RigSpec(cameras=17))
    with pytest.raises(InputError, match="--fov"):
        build_rig(RigSpec(fov=170.0))


def test_a_calibration_file_is_a_rig(tmp_path):
    from rmpl.io.calibration import save_rig

    rig = build_rig(RigSpec(cameras=3, distortion=(-0.1, 0.01)))
    save_rig(rig, tmp_path / "calib.toml")
    again = build_rig(RigSpec(str(tmp_path / "calib.toml")))
    assert again.names == rig.names
    assert np.allclose(again.dist, rig.dist) and np.allclose(again.K, rig.K)


# --------------------------------------------------------------------------- the clocks


def test_offsets_are_in_each_cameras_frames():
    cfg = SimulateConfig(fps=(30.0, 30.0, 25.0, 60.0), offsets=(0, 3, -5, 11), seconds=4.0)
    timing = timing_of(cfg, 4, np.random.default_rng(0))
    assert timing.frames.tolist() == [120, 120, 100, 240]
    # A camera's offset-th frame is the instant of the reference's frame 0.
    for v, o in enumerate((0, 3, -5, 11)):
        assert timing.start[v] + o / timing.fps[v] == pytest.approx(timing.start[0])
    # sync.json's convention: offset_seconds * fps is the offset in the camera's frames.
    assert np.allclose(timing.offsets_seconds * timing.fps, [0, 3, -5, 11])


def test_bad_clocks_are_refused():
    with pytest.raises(InputError, match="--offsets.*half the recording"):
        timing_of(SimulateConfig(offsets=(0, 80), seconds=4.0), 2, np.random.default_rng(0))
    with pytest.raises(InputError, match="--fps.*one per camera"):
        timing_of(SimulateConfig(fps=(30.0, 25.0)), 3, np.random.default_rng(0))
    with pytest.raises(InputError, match="4 offsets"):
        parse_offsets("0,1", 4)
    with pytest.raises(InputError, match="random:N"):
        parse_offsets("random:x", 4)
    a = timing_of(SimulateConfig(offsets="random:5"), 4, np.random.default_rng(3))
    b = timing_of(SimulateConfig(offsets="random:5"), 4, np.random.default_rng(3))
    assert a.offset_frames[0] == 0 and np.array_equal(a.offset_frames, b.offset_frames)
    assert np.abs(a.offset_frames).max() <= 5


# --------------------------------------------------------------------------- the lens


def test_the_lens_warp_puts_a_point_where_the_camera_projects_it():
    """A dot drawn on the pinhole canvas lands, after the warp, where the distorted camera
    projects the same 3D point (the renders and the truth agree through the lens)."""
    pytest.importorskip("cv2")
    from rmpl.simulate.render import CameraView, RoomStyle

    rig = build_rig(RigSpec(cameras=2, resolution=(640, 360), distortion=(-0.2, 0.05)))
    cam: Camera = rig[0]
    view = CameraView(cam, RoomStyle(np.random.default_rng(0), 6.0), blur=0.0, noise=0.0)
    assert view.canvas_size[0] > 640  # barrel distortion: the canvas reaches wider
    for X in ([1.2, 0.9, 1.6], [-1.0, -0.5, 0.3], [0.0, 0.0, 1.0]):
        pinhole = view.canvas_K @ (cam.R @ np.array(X) + cam.t)
        p = pinhole[:2] / pinhole[2]
        W, H = view.canvas_size
        rgb = np.zeros((H, W, 3), np.uint8)
        ids = np.full((H, W), -1, np.int16)
        y0, x0 = int(round(p[1])), int(round(p[0]))
        rgb[y0 - 1 : y0 + 2, x0 - 1 : x0 + 2] = 255
        ids[y0 - 1 : y0 + 2, x0 - 1 : x0 + 2] = 0
        _, shown = view.frame(rgb, ids, np.random.default_rng(0))
        ys, xs = np.nonzero(shown == 0)
        want = cam.project(np.array(X))
        assert np.hypot(xs.mean() - want[0], ys.mean() - want[1]) < 1.0, (X, want)


@pytest.mark.parametrize("spec", ["charuco:5x7:0.1:0.075", "checkerboard:6x8:0.06"])
def test_the_board_sweep_shows_the_corners_where_the_truth_puts_them(spec):
    """The board drawn through a distorted lens: OpenCV finds its corners within a fraction
    of a pixel of the true corners projected through the camera."""
    pytest.importorskip("cv2")
    from rmpl.calibration.detect import detect
    from rmpl.simulate.board import _board_layer, board_poses, check_board
    from rmpl.simulate.render import CameraView, RoomStyle

    rig = build_rig(RigSpec(cameras=3, radius=3.0, resolution=(1280, 720)))
    board = check_board(spec, rig)
    poses = board_poses(board, rig, 8, 2.0, 1.2, np.random.default_rng(1))
    cam = rig[0]
    view = CameraView(cam, RoomStyle(np.random.default_rng(0), 6.0))
    errors = []
    for pose in poses:
        image = _board_layer(board, cam, *view.grid, pose, view.room)
        found = detect(np.clip(image, 0, 255).astype(np.uint8), board)
        if found is None:
            continue
        R, t = pose
        n = len(board.points)  # a checkerboard reads the same turned half a turn
        ways = [found.ids, n - 1 - found.ids] if board.kind == "checkerboard" else [found.ids]
        errs = [np.linalg.norm(found.corners - cam.project(board.points[i] @ R.T + t), axis=-1)
                for i in ways]  # fmt: skip
        errors.append(min(errs, key=np.median))
    assert len(errors) >= 2
    errors = np.concatenate(errors)
    # (OpenCV's refinement misses a corner now and then on a steeply tilted board)
    assert np.median(errors) < 0.3 and np.percentile(errors, 95) < 1.0


def test_a_board_seen_from_behind_shows_no_pattern():
    pytest.importorskip("cv2")
    from rmpl.calibration.detect import detect
    from rmpl.simulate.board import _board_layer, check_board
    from rmpl.simulate.render import CameraView, RoomStyle

    rig = build_rig(RigSpec(cameras=2, radius=3.0, resolution=(1280, 720)))
    board = check_board("charuco:5x7:0.1:0.075", rig)
    cam = rig[0]
    view = CameraView(cam, RoomStyle(np.random.default_rng(0), 6.0))
    half = board.points.max(axis=0) / 2
    toward = cam.center - np.array([0.0, 0.0, 1.2])
    z = -toward / np.linalg.norm(toward)  # the printed side (-z) faces the camera
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    front = (R, np.array([0.0, 0.0, 1.2]) - R @ half)
    flip = np.diag([-1.0, 1.0, -1.0])  # the same board turned about its y axis
    back = (R @ flip, np.array([0.0, 0.0, 1.2]) - R @ flip @ half)
    seen = [_board_layer(board, cam, *view.grid, pose, view.room) for pose in (front, back)]
    assert detect(np.clip(seen[0], 0, 255).astype(np.uint8), board) is not None
    assert detect(np.clip(seen[1], 0, 255).astype(np.uint8), board) is None


def test_a_sweep_too_short_for_the_rig_is_refused():
    from rmpl.simulate.board import check_board

    rig = build_rig(RigSpec(cameras=6))
    with pytest.raises(InputError, match="--board-seconds"):
        check_board("charuco:5x7:0.1:0.075", rig, seconds=4.0)


# --------------------------------------------------------------------------- a recording


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """3 cameras (one at another rate and started 2 of its frames before the reference),
    one walking person and a bystander, 1.5 s."""
    synth_ready("anny", "moderngl")
    pytest.importorskip("cv2")
    out = tmp_path_factory.mktemp("sim") / "sim"
    cfg = SimulateConfig(
        rig=RigSpec(cameras=3, radius=3.5, resolution=(320, 240)),
        people=1,
        bystander=True,
        seconds=1.5,
        fps=(15.0, 15.0, 25.0),
        offsets=(0, 0, 2),
        seed=4,
    )
    simulate(cfg, out, progress=False)
    return out, cfg


def test_the_truth_agrees_with_the_videos(tiny):
    import cv2

    from rmpl.calibration.sync import read_sync
    from rmpl.io.calibration import load_rig
    from rmpl.io.poses import load_poses

    out, cfg = tiny
    rig = load_rig(out / "truth" / "calibration.toml")
    sync = read_sync(out / "truth" / "sync.json")
    poses = load_poses(out / "truth" / "poses.npz")
    # The reference's clock from its frame 0 to the last instant any camera recorded:
    # camera 3 (25 frames/s) started 2 of its frames early and records 38 frames.
    last = (38 - 1 - 2) / 25.0
    assert poses.skeleton == "halpe26" and poses.points.shape == (int(last * 15) + 1, 2, 26, 3)
    assert poses.fps == 15 and poses.frames.tolist() == list(range(int(last * 15) + 1))
    assert np.allclose(sync.offset_frames, [0, 0, 2])
    people = json.loads((out / "truth" / "people.json").read_text())["people"]
    assert [p["bystander"] for p in people] == [False, True]
    # The bystander stands still; the walker moves.
    moved = np.linalg.norm(poses.points[-1] - poses.points[0], axis=-1).mean(-1)
    assert moved[1] < 1e-3 and moved[0] > 0.2
    # Everyone stands on the floor and is of a human size.
    assert np.all(np.abs(np.nanmin(poses.points[..., 2], axis=-1)) < 0.12)
    assert np.all(np.nanmax(poses.points[..., 2], axis=-1) > 1.3)
    for v, cam in enumerate(rig):
        cap = cv2.VideoCapture(str(out / "videos" / f"{cam.name}.mp4"))
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        assert n == round(cfg.seconds * cfg.fps[v])
        assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(cfg.fps[v], rel=1e-3)
        ok, frame = cap.read()
        cap.release()
        assert ok and frame.shape == (240, 320, 3)
    # The reference camera's true pixels are the true 3D through the true camera.
    with np.load(out / "truth" / "projections" / "cam1.npz") as z:
        uv = z["uv"]
    mine = rig[0].project(poses.points[: len(uv)])
    both = np.isfinite(uv).all(-1)
    assert both.mean() > 0.5
    assert np.abs(mine[both] - uv[both]).max() < 0.05


def test_the_people_are_where_the_pixels_show_them(tiny):
    """Where the truth puts a person's visible hips, the video shows something other than
    the empty room (what a detector sees is where the truth says)."""
    import cv2

    from rmpl.io.calibration import load_rig
    from rmpl.simulate.render import CameraView, room_style

    out, cfg = tiny
    rig = load_rig(out / "truth" / "calibration.toml")
    room = CameraView(rig[1], room_style(np.random.default_rng([cfg.seed, 7]), rig.centers)).room
    with np.load(out / "truth" / "projections" / "cam2.npz") as z:
        uv, hidden = z["uv"], z["hidden"]
    cap = cv2.VideoCapture(str(out / "videos" / "cam2.mp4"))
    ok, frame = cap.read()
    cap.release()
    assert ok
    image = frame[..., ::-1].astype(float)
    assert np.abs(image - room).mean() < 25  # mostly the room
    checked = 0
    for p in range(uv.shape[1]):
        hips = uv[0, p, 11:13].mean(0)
        if np.isfinite(hips).all() and not hidden[0, p, 11:13].any():
            x, y = np.rint(hips).astype(int)
            diff = np.abs(image[y - 1 : y + 2, x - 1 : x + 2] - room[y - 1 : y + 2, x - 1 : x + 2])
            assert diff.mean() > 12, (p, diff.mean())
            checked += 1
    assert checked >= 1


def test_a_second_run_resumes_and_other_settings_are_refused(tiny):
    out, cfg = tiny
    video = out / "videos" / "cam1.mp4"
    stamp = video.stat().st_mtime_ns
    simulate(cfg, out, progress=False)
    assert video.stat().st_mtime_ns == stamp  # kept, not rendered again
    other = SimulateConfig(**{**cfg.__dict__, "seed": 5})
    with pytest.raises(InputError, match="another simulation"):
        simulate(other, out, progress=False)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--rig", "dome"], "ring, arc, corners"),
        (["--cameras", "1", "--run"], "two or more cameras"),
        (["--offsets", "0,0,0,200"], "half the recording"),
        (["--board", "charuco:5x7:0.01:0.0075"], "squares of at least"),
        (["--board", "charuco:5x7:0.9:0.7"], "fits in"),
        (["--motion", "swim"], "--motion"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, message):
    out = tmp_path / "sim"
    code = main(["simulate", *argv, "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


# --------------------------------------------------------------------------- the chain


@pytest.fixture(scope="module")
def chain(tiny):
    pytest.importorskip("ai_edge_litert")
    from rmpl.simulate.chain import run_chain
    from rmpl.simulate.report import write_report

    out, _ = tiny
    scores = run_chain(out, methods=("robust",))
    write_report(out, scores)
    return out, scores


def test_the_chain_scores_every_stage(chain):
    out, scores = chain
    for stage in ("calibration", "sync", "detection", "3d", "steps"):
        assert stage in scores
    assert set(scores["3d"]) == {"robust (found cameras)", "robust (true cameras)"}
    text = (out / "report.md").read_text()
    assert "## The error of each stage" in text and "## What limits this rig" in text
    assert (out / "report.png").stat().st_size > 10_000
    json.dumps(scores, allow_nan=False)  # every figure is a number or None


def test_the_3d_score_is_recomputed_independently(chain):
    """MPJPE of the run through the true cameras, from the files, by nearest person per
    frame: the figure in scores.json cannot drift from the truth file."""
    from rmpl.io.poses import load_poses

    out, scores = chain
    got = scores["3d"]["robust (true cameras)"]
    truth = load_poses(out / "truth" / "poses.npz")
    run = load_poses(out / "chain" / "run_robust_true" / "poses.npz")
    errors = []
    for i, f in enumerate(run.frames):
        if f not in truth.frames:  # after every camera stopped: nothing there
            assert np.isnan(run.points[i]).all()
            continue
        t = int(np.flatnonzero(truth.frames == f)[0])
        for person in truth.points[t]:
            d = [np.nanmean(np.linalg.norm(q - person, axis=-1)) for q in run.points[i]]
            q = run.points[i][int(np.nanargmin(d))]
            ok = np.isfinite(q).all(-1)
            errors.extend(np.linalg.norm(q[ok] - person[ok], axis=-1))
    assert got["overall"]["mpjpe_mm"] == pytest.approx(1000 * np.mean(errors), rel=0.02)


@pytest.mark.filterwarnings("ignore:All-NaN slice")
def test_the_detection_score_is_recomputed_independently(chain):
    """The detector's median pixel error, from the cached 2D and the projections file."""
    from rmpl.io.keypoints import load_keypoints

    out, scores = chain
    kp = load_keypoints(out / "chain" / "keypoints2d.npz")
    errors = []
    for v, name in enumerate(kp.views):
        with np.load(out / "truth" / "projections" / f"{name}.npz") as z:
            uv, hidden = z["uv"][..., :17, :], z["hidden"][..., :17]
        for t in range(len(uv)):
            for person, gone in zip(uv[t], hidden[t], strict=True):
                seen = np.isfinite(person).all(-1) & ~gone
                if seen.sum() < 4:
                    continue
                det = kp.keypoints[t, v, :, :17]
                d = np.nanmedian(np.linalg.norm(det - person, axis=-1), axis=-1)
                if np.isfinite(d).any() and np.nanmin(d) < 30:
                    best = det[int(np.nanargmin(d))]
                    ok = (
                        seen
                        & np.isfinite(best).all(-1)
                        & (kp.scores[t, v, int(np.nanargmin(d)), :17] >= 0.5)
                    )
                    errors.extend(np.linalg.norm(best[ok] - person[ok], axis=-1))
    got = scores["detection"]["error_px"]["median"]
    assert got == pytest.approx(float(np.median(errors)), rel=0.1)


# --------------------------------------------------------------------------- the people


@pytest.mark.parametrize("activities", [["walk", "walk"], ["run", "turn", "bend"]])
def test_people_walk_back_and_forth_inside_the_area_apart(activities):
    """Planned paths (no body needed): every sample covered, the hips within the walking
    area (a piece is cut where it would leave it), the people mostly apart."""
    from rmpl.simulate.motion import load_motion_library
    from rmpl.simulate.people import _hips, _rz, plan_people

    bank, kinds = load_motion_library()
    S, area = 600, 1.8
    P = len(activities)
    plans = plan_people(bank, kinds, activities, True, S, area, np.full(P + 1, 0.85),
                        np.full((P + 1, 6), 0.5), np.random.default_rng(2))  # fmt: skip
    assert [p.bystander for p in plans] == [False] * P + [True]
    tracks = np.full((S, P, 2), np.nan)
    for i, person in enumerate(plans[:P]):
        covered = np.zeros(S, bool)
        for piece in person.pieces:
            n = len(piece.rows)
            covered[piece.start : piece.start + n] = True
            xy = piece.origin + _hips(bank, piece.rows) @ _rz(piece.yaw).T
            tracks[piece.start : piece.start + n, i] = xy[: S - piece.start]
        assert covered.all()
        r = np.linalg.norm(tracks[:, i], axis=-1)
        assert np.percentile(r, 95) < area + 0.5, (activities[i], r.max())
    if P > 1:
        gap = np.linalg.norm(tracks[:, 0] - tracks[:, 1], axis=-1)
        assert np.mean(gap > 0.5) > 0.8
