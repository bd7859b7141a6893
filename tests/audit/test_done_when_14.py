"""Audit of issue 14's "Done when" tests: what the existing temporal tests left out.

- masking one joint (the existing tests mask a view of a frame and a whole frame);
- frame times honoured when frames are dropped from the input (irregular times);
- the sliding-window stitching checked exactly against its own windows, independent of
  how many windows run per batch, and, for the shipped model, against one long window;
- bad frame rates (negative, NaN, infinite) and a temporal lift without any frame rate.

Every input is built for ``lifter.num_joints`` joints, so the tests hold for any joint set.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import rmpl
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.inference_temporal import TemporalLifter
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.model.temporal import TemporalConfig, TemporalRMPL

SHIPPED_FLAGS = {"interpolate_valid": True, "body_token": True, "fused_start": True}
FLAGS = pytest.mark.parametrize("flags", [{}, SHIPPED_FLAGS], ids=["first", "shipped"])
WALK = Path(rmpl.__file__).parent / "examples" / "walk"


def _model(window: int, flags: dict, seed: int = 0) -> TemporalRMPL:
    """A tiny temporal model whose per-frame and temporal heads are not zero."""
    torch.manual_seed(seed)
    frame = RMPL(PRESETS["tiny"].with_(robust_anchor=2))
    with torch.no_grad():
        frame.head.weight.normal_(0, 0.02)
    m = TemporalRMPL(frame, TemporalConfig(dim=32, depth=2, window=window, **flags))
    with torch.no_grad():
        m.head.weight.normal_(0, 0.05)
    return m.eval()


def _lifter(window: int, flags: dict) -> TemporalLifter:
    return TemporalLifter(_model(window, flags), onnx=False, assemble="network")


def _rig(views: int = 3) -> Rig:
    K = np.array([[800.0, 0, 640], [0, 800, 360], [0, 0, 1]])
    eyes = [[4, 0, 1.5], [0, 4, 1.5], [-3, -3, 2.0], [3, -3, 1.0]][:views]
    cams = (Camera(K, *look_at(np.array(e, float), np.array([0, 0, 1.0])), name=f"c{i}")
            for i, e in enumerate(eyes))  # fmt: skip
    return Rig(tuple(cams))


def _track(J: int, T: int = 20, views: int = 3, seed: int = 0):
    """A person-sized cloud of J points drifting and swaying over T frames, projected with
    1 px noise: keypoints (T, V, J, 2), scores (T, V, J)."""
    rng = np.random.default_rng(seed)
    body = rng.normal(0, [0.15, 0.15, 0.4], (J, 3)) + [0, 0, 1.0]
    t = np.arange(T)[:, None, None]
    X = body[None] + 0.01 * t * np.array([1.0, 0.5, 0]) + 0.05 * np.sin(t / 3 + body)
    rig = _rig(views)
    kp = np.stack([c.project(X) for c in rig], 1) + rng.normal(0, 1.0, (T, views, J, 2))
    return kp, np.full(kp.shape[:-1], 0.9), rig


def _inputs(J: int, B=2, T=8, V=3, seed=1):
    g = torch.Generator().manual_seed(seed)
    origin = torch.randn(B, 1, V, 1, 3, generator=g) * 3
    target = torch.randn(B, T, 1, J, 3, generator=g) * 0.3 + torch.tensor([0, 0, 1.0])
    d = target - origin + 0.01 * torch.randn(B, T, V, J, 3, generator=g)
    d = d / d.norm(dim=-1, keepdim=True)
    rays = torch.cat([origin.expand(B, T, V, J, 3), d], -1)
    scores = 0.5 + 0.5 * torch.rand(B, T, V, J, generator=g)
    times = torch.arange(T, dtype=torch.float32)[None].repeat(B, 1) / 25
    return rays, scores, times


# --------------------------------------------------------------------------- masking


@FLAGS
def test_a_masked_joint_is_never_read(flags):
    """One joint of one view in one frame under a zero score: garbage or NaN there gives the
    same answer and uncertainty everywhere; masking it does change the answer."""
    m = _model(8, flags)
    J = m.frame_model.config.num_joints
    rays, scores, times = _inputs(J)
    ref, _ = m(rays, scores, times)
    masked = scores.clone()
    masked[0, 2, 1, 5] = 0  # batch 0, frame 2, view 1, joint 5
    masked[1, 6, 0, J - 1] = 0  # batch 1, frame 6, view 0, the last joint
    base, base_s = m(rays, masked, times)
    for junk in (float("nan"), 1e3):
        garbage = rays.clone()
        garbage[0, 2, 1, 5] = junk
        garbage[1, 6, 0, J - 1] = -junk
        out, out_s = m(garbage, masked, times)
        assert torch.allclose(out, base, atol=1e-6) and torch.allclose(out_s, base_s, atol=1e-6)
    assert not torch.allclose(base, ref, atol=1e-5)


@FLAGS
def test_a_masked_keypoint_is_never_read_by_the_track_lifter(flags):
    """The same through TemporalLifter.lift_track: a keypoint with score 0 may hold anything."""
    lifter = _lifter(32, flags)
    kp, sc, rig = _track(lifter.num_joints, T=12)
    sc[4, 2, 3] = 0
    sc[7, 0] = 0  # every joint of view 0 in frame 7
    kw = dict(fps=30, joints=lifter.skeleton.name)
    clean = kp.copy()
    clean[4, 2, 3] = np.nan
    clean[7, 0] = np.nan
    a = lifter.lift_track(clean, sc, rig, **kw)
    junk = kp.copy()
    junk[4, 2, 3] = [1e6, -1e6]
    junk[7, 0] = 5e4
    b = lifter.lift_track(junk, sc, rig, **kw)
    assert np.isfinite(a.points).all()
    assert np.allclose(a.points, b.points, atol=1e-6) and np.allclose(a.sigma, b.sigma, atol=1e-6)


# --------------------------------------------------------------------------- frame rate


@FLAGS
def test_frames_dropped_from_the_input_equal_masked_frames_at_their_times(flags):
    """Irregular frame times are honoured: frames left out of the input (times skip over them)
    give, in one window, exactly what the full track gives with those frames masked. Frame
    numbers taken for times (the gap ignored) give another answer."""
    lifter = _lifter(32, flags)
    kp, sc, rig = _track(lifter.num_joints, T=20)
    t = np.arange(20) / 30
    keep = np.ones(20, bool)
    keep[8:11] = False
    kw = dict(joints=lifter.skeleton.name)
    dropped = lifter.lift_track(kp[keep], sc[keep], rig, times=t[keep], **kw).points
    k2, s2 = kp.copy(), sc.copy()
    k2[~keep], s2[~keep] = np.nan, 0
    masked = lifter.lift_track(k2, s2, rig, times=t, **kw).points
    assert np.isfinite(masked).all()
    assert np.allclose(dropped, masked[keep], atol=1e-5)
    ignored = lifter.lift_track(kp[keep], sc[keep], rig, fps=30, **kw).points
    assert np.abs(ignored - masked[keep]).max() > 1e-3


# --------------------------------------------------------------------------- stitching


def _starts(T: int, W: int) -> list[int]:
    """The documented windows: overlapping by half, the last one ending at the track's end."""
    s = list(range(0, T - W + 1, W // 2))
    return s if s[-1] == T - W else [*s, T - W]


@FLAGS
def test_stitching_is_the_triangle_weighted_mean_of_its_windows(flags):
    """A 30-frame track in windows of 8 equals each window lifted alone (a track exactly one
    window long), averaged with weights highest in a window's middle; and it does not depend
    on how many windows run per batch (the group seams)."""
    W, T = 8, 30
    lifter = _lifter(W, flags)
    kp, sc, rig = _track(lifter.num_joints, T=T)
    t = np.arange(T) / 30
    kw = dict(joints=lifter.skeleton.name)
    acc, weight = 0.0, np.zeros(T)
    tri = np.minimum(np.arange(W) + 1, W - np.arange(W)).astype(float)
    for a in _starts(T, W):
        r = lifter.lift_track(kp[a : a + W], sc[a : a + W], rig, times=t[a : a + W], **kw)
        part = np.zeros((T, *r.points.shape[1:]))
        part[a : a + W] = tri[:, None, None] * r.points
        acc, weight[a : a + W] = acc + part, weight[a : a + W] + tri
    expected = acc / weight[:, None, None]
    for batch in (1, 2, 32):
        got = lifter.lift_track(kp, sc, rig, times=t, batch_windows=batch, **kw).points
        assert np.allclose(got, expected, atol=1e-4), (batch, np.abs(got - expected).max())


def test_the_shipped_model_stitched_agrees_with_one_long_window():
    """The trained model: the embedded 60-frame walk in windows of 16 (and its own window)
    agrees with one 60-frame window to millimetres, with 2 views (where the network answers
    most) and with 4."""
    from rmpl.inference_temporal import PRETRAINED_TEMPORAL

    if not (PRETRAINED_TEMPORAL["temporal"] / "config.json").is_file():
        pytest.skip("no shipped temporal model in this checkout")
    rig = rmpl.load_rig(WALK / "calibration.toml")
    k2d = rmpl.load_keypoints(WALK / "keypoints.json")
    lifter = TemporalLifter.from_pretrained()
    lifter.assemble = "network"  # the stitched network itself, before the filters
    config = lifter.model.config
    T = len(k2d.keypoints)
    for views in ([0, 2], [0, 1, 2, 3]):
        kp, sc = k2d.keypoints[:, views, 0], k2d.scores[:, views, 0]
        sub = Rig(tuple(rig[i] for i in views))
        try:
            long = _lift_in_windows(lifter, T, kp, sc, sub, k2d)
            for window in (16, config.window):
                got = _lift_in_windows(lifter, window, kp, sc, sub, k2d)
                d = np.linalg.norm(got - long, axis=-1)
                assert np.isfinite(d).all()
                assert d.mean() < 0.003 and d.max() < 0.02, (views, window, d.mean(), d.max())
        finally:
            lifter.model.config = config


def _lift_in_windows(lifter, window, kp, sc, rig, k2d) -> np.ndarray:
    lifter.model.config = lifter.model.config.with_(window=window)
    return lifter.lift_track(kp, sc, rig, fps=k2d.fps, joints=k2d.skeleton).points


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("fps", [-30.0, 0.0, float("nan"), float("inf")])
def test_a_frame_rate_that_is_not_positive_and_finite_is_one_clear_error(fps):
    lifter = _lifter(8, {})
    kp, sc, rig = _track(lifter.num_joints, T=6)
    with pytest.raises(InputError) as e:
        lifter.lift_track(kp, sc, rig, fps=fps, joints=lifter.skeleton.name)
    assert "fps" in str(e.value) and "> 0" in str(e.value)


def test_a_track_of_zero_frames_and_tracks_of_mismatched_length_name_the_field():
    lifter = _lifter(8, {})
    kp, sc, rig = _track(lifter.num_joints, T=6)
    kw = dict(joints=lifter.skeleton.name)
    with pytest.raises(InputError, match="at least one frame"):
        lifter.lift_track(kp[:0], sc[:0], rig, fps=30, **kw)
    with pytest.raises(InputError, match="scores"):
        lifter.lift_track(kp[:5], sc, rig, fps=30, **kw)  # keypoints shorter than scores
    with pytest.raises(InputError, match="times"):
        lifter.lift_track(kp, sc, rig, times=np.arange(7) / 30, **kw)  # one time too many


def test_a_temporal_lift_without_a_frame_rate_is_one_line_naming_fps(tmp_path, capsys):
    """rmpl lift --model temporal on keypoints that state no frame rate, --fps not given."""
    from rmpl.cli import main
    from rmpl.io.calibration import save_rig
    from rmpl.io.keypoints import Keypoints2D, save_keypoints

    kp, sc, rig = _track(17, T=6)
    save_rig(rig, tmp_path / "calib.toml")
    doc = Keypoints2D(kp[:, :, None], sc[:, :, None], "coco17", rig.names, np.arange(6), None)
    save_keypoints(doc, tmp_path / "kp.json")
    out = tmp_path / "out.json"
    argv = ["lift", "--calib", str(tmp_path / "calib.toml"), "--keypoints",
            str(tmp_path / "kp.json"), "--model", "temporal", "--out", str(out)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and "--fps" in err, err
    assert not out.exists()
