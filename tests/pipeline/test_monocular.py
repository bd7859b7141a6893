"""One camera: depth from the floor, body size and time (rmpl.pipeline.monocular)."""

import warnings
from pathlib import Path

import numpy as np
import pytest

import rmpl
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.floor import Floor, parse_floor, signed_distance
from rmpl.geometry.rays import rays_from_keypoints
from rmpl.pipeline.monocular import (
    FrameCues,
    MonocularConfig,
    floor_from_poses,
    floor_log_scale,
    may_touch_floor,
    monocular_people,
    per_frame_log_scale,
    stature_proxy,
    track_log_depth,
)

WALK = Path(rmpl.__file__).parent / "examples" / "walk" / "ground_truth.npz"
UP = np.array([0.0, 0.0, 1.0])


def walk() -> np.ndarray:
    """The shipped example's walking person, (60, 17, 3) metres, z up, ankles ~0.1 m up."""
    return np.load(WALK)["points"][:, 0].astype(float)


def one_camera(height=2.5) -> Rig:
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    R, t = look_at(np.array([5.0, 0.5, height]), np.array([0.0, 0, 1]))
    return Rig((Camera(K, R, t, size=(1280, 720), name="cam"),))


def resting_floor(points: np.ndarray, c: float = 0.07) -> Floor:
    """The floor under the lowest ankle of each frame (its median), ``c`` below."""
    low = np.nanmin(points[:, [15, 16], 2], axis=1)
    return Floor((0.0, 0.0, 1.0), float(np.median(low)) - c)


def fake_lifter(truth: np.ndarray, factors: np.ndarray, center: np.ndarray):
    """A "lifter" whose poses project exactly like the truth but stand ``factors`` times as
    far from the camera (the one-view ambiguity), rows in the order they are asked for."""
    wrong = center + factors[:, None, None] * (truth - center)

    def fn(kp, sc, rig):
        n = len(kp)
        out, fn.done = wrong[fn.done : fn.done + n], fn.done + n
        return out, (sc > 0).sum(-2)

    fn.done = 0
    return fn


def test_stature_proxy_scales_and_ignores_posture():
    x = walk()
    h = stature_proxy(x)
    assert np.all((h > 1.3) & (h < 2.2))
    assert np.allclose(stature_proxy(1.1 * x), 1.1 * h)
    R = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.0]])  # lying down: same bones
    assert np.allclose(stature_proxy(x @ R.T), h)


def test_collapsed_pose_has_no_size_and_no_cue():
    # An untrained lifter can put every joint on one point: no stature, so no size cue
    # (NaN, ignored by the combination) rather than an infinite scale and a warning.
    x = walk()[:3].copy()
    x[1] = x[1, :1]  # every joint at the nose
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        h = stature_proxy(x)
        cues = FrameCues(np.full(3, np.nan), np.full(3, np.nan), h, np.ones(3, bool))
        log_s, sd = per_frame_log_scale(cues, MonocularConfig())
    assert np.isfinite(h[[0, 2]]).all() and np.isnan(h[1])
    assert np.isfinite(log_s).all() and np.isfinite(sd).all()  # the lifter's own depth


def test_posture_gate_lying_and_seated():
    x = walk()[:5]
    cfg = MonocularConfig()
    assert may_touch_floor(x, UP, cfg).all()
    lying = x @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.0]]).T
    assert not may_touch_floor(lying, UP, cfg).any()
    seated = x.copy()
    for hip, knee, ankle in ((11, 13, 15), (12, 14, 16)):  # thighs forward, horizontal
        thigh = np.linalg.norm(x[:, knee] - x[:, hip], axis=-1)
        seated[:, knee] = x[:, hip] + thigh[:, None] * [1.0, 0, 0]
        seated[:, ankle] = seated[:, knee] - [0, 0, 0.45]
    assert not may_touch_floor(seated, UP, cfg).any()


def test_floor_scale_recovers_the_true_depth():
    x = walk()
    rig = one_camera()
    C = rig.centers[0]
    floor = resting_floor(x)
    kp = rig.project(x)  # (60, 1, 17, 2)
    rays = rays_from_keypoints(kp, rig)[:, 0]
    sc = np.ones((60, 17))
    k = np.random.default_rng(0).uniform(0.7, 1.4, 60)
    lifted = C + k[:, None, None] * (x - C)
    log_s, sd = floor_log_scale(lifted, rays, sc, C, floor, MonocularConfig())
    # Truth = scale 1/k. Exact where the lower ankle rests at the contact height; the
    # ankle's own height varies over a step, which is what the noise model's sd covers.
    low = np.nanmin(signed_distance(x[:, [15, 16]], floor), axis=1)
    rests = np.abs(low - 0.07) < 0.005
    assert rests.sum() > 10
    assert np.allclose(log_s[rests], -np.log(k[rests]), atol=2e-3)
    err = np.abs(log_s + np.log(k))
    assert np.all(err < 3 * sd)
    sc[:, [15, 16]] = 0.1  # ankles unseen: no contact
    assert np.isnan(floor_log_scale(lifted, rays, sc, C, floor, MonocularConfig())[0]).all()


def test_no_floor_cue_from_a_camera_at_the_feet():
    x = walk()
    rig = one_camera(height=0.15)
    C = rig.centers[0]
    rays = rays_from_keypoints(rig.project(x), rig)[:, 0]
    log_s, _ = floor_log_scale(x, rays, np.ones((60, 17)), C, resting_floor(x), MonocularConfig())
    assert np.isnan(log_s).all()


def _cues(x, rig, floor, cfg, lifted):
    C = rig.centers[0]
    rays = rays_from_keypoints(rig.project(x), rig)[:, 0]
    f, fsd = floor_log_scale(lifted, rays, np.ones((len(x), 17)), C, floor, cfg)
    return FrameCues(f, fsd, stature_proxy(lifted), np.ones(len(x), bool))


def test_track_detects_a_jump_and_keeps_the_stature():
    x = walk()
    x[25:35] += [0, 0, 0.4]  # airborne for 10 frames (1/3 s at 30 frames/s)
    rig = one_camera()
    C = rig.centers[0]
    floor = resting_floor(walk())
    cfg = MonocularConfig()
    k = np.random.default_rng(1).uniform(0.8, 1.25, 60)
    lifted = C + k[:, None, None] * (x - C)
    cues = _cues(x, rig, floor, cfg, lifted)
    depth = track_log_depth(lifted, cues, C, floor, np.arange(60) / 30.0, cfg)
    assert not depth.contact[27:33].any()  # the jump is not forced onto the floor
    assert depth.contact[:20].mean() > 0.8 and depth.contact[40:].mean() > 0.8
    true_stature = float(np.median(stature_proxy(x)))
    assert depth.stature == pytest.approx(true_stature, rel=0.04)
    root = np.nanmean(x[:, 11:13], axis=1)
    true_log = np.log(np.linalg.norm(root - C, axis=-1))
    assert np.abs(depth.log_depth - true_log)[27:33].max() < 0.06  # from size and time


def test_without_contacts_the_track_keeps_the_prior():
    x = walk()
    rig = one_camera()
    C = rig.centers[0]
    cfg = MonocularConfig()
    cues = _cues(x, rig, resting_floor(x), cfg, x)
    cues.floor[:] = np.nan
    depth = track_log_depth(x, cues, C, None, np.arange(60) / 30.0, cfg)
    assert depth.stature == cfg.stature and not depth.contact.any()


def test_a_floor_that_implies_a_giant_is_dropped():
    x = walk()
    rig = one_camera()
    C = rig.centers[0]
    cfg = MonocularConfig()
    raised = resting_floor(x)
    raised = Floor(raised.normal, raised.height - 0.8)  # 0.8 m below the feet: a stage
    cues = _cues(x, rig, raised, cfg, x)
    depth = track_log_depth(x, cues, C, raised, np.arange(60) / 30.0, cfg)
    assert depth.floor_dropped and not depth.contact.any()


@pytest.mark.parametrize("cues", ["floor", "floor+size", "floor+size+time"])
def test_monocular_people_with_a_floor_fix_the_depth(cues):
    x = walk()
    rig = one_camera()
    C = rig.centers[0]
    k = np.random.default_rng(2).uniform(0.75, 1.35, 60)
    kp = rig.project(x)  # (60, 1, 17, 2): one person per frame, in the one view
    sc = np.ones((60, 1, 17))
    cfg = MonocularConfig.from_cues(cues)
    frame = np.arange(60)
    res = monocular_people(
        kp, sc, frame, 60, rig, 30.0, resting_floor(x), cfg, lift=fake_lifter(x, k, C)
    )
    err = np.linalg.norm(res.points[:, 0] - x, axis=-1).mean()
    before = np.linalg.norm(C + k[:, None, None] * (x - C) - x, axis=-1).mean()
    assert err < 0.1 * before and err < 0.06
    r50 = res.radius(C)[:, 0]
    assert np.isfinite(r50).all() and (r50 > 0).all()
    none = monocular_people(kp, sc, frame, 60, rig, 30.0, None, cfg, lift=fake_lifter(x, k, C))
    assert np.linalg.norm(none.points[:, 0] - x, axis=-1).mean() > 3 * err  # floor absent


def test_floor_from_poses_finds_the_floor_under_the_ankles():
    x = np.concatenate([walk() + [dx, dy, 0.3] for dx in (-1, 1) for dy in (-1, 0.5)])
    floor = floor_from_poses(x, UP)
    expected = float(np.median(np.nanmin(x[:, [15, 16], 2], axis=1))) - 0.07
    assert floor.height == pytest.approx(expected, abs=0.01)
    assert np.allclose(floor.normal, (0, 0, 1), atol=0.02)
    assert floor_from_poses(x).height == pytest.approx(expected, abs=0.02)  # up from trunks


def test_config_refuses_unknown_cues():
    from rmpl.errors import InputError

    with pytest.raises(InputError, match="floor, size, time"):
        MonocularConfig.from_cues("floor+depth")
    assert MonocularConfig.from_cues("size+time").cues == ("size", "time")
    assert parse_floor("z=0").height == 0
