"""Temporal training: a tiny run, an exact resume, the checkpoint round trip, the track lifter."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.inference_temporal import TemporalLifter, frame_times, window_starts
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.model.temporal import TemporalConfig, TemporalRMPL
from rmpl.training import temporal as tt
from rmpl.training.loop import save_checkpoint
from tests.data.test_sequences import _bank


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("temporal")
    torch.manual_seed(0)
    save_checkpoint(RMPL(PRESETS["tiny"].with_(robust_anchor=1)), d / "frame")
    _bank().save(d / "seq.npz")
    cfg = tt.TemporalTrainConfig(
        sequences=str(d / "seq.npz"),
        frame_model=str(d / "frame"),
        steps=4,
        batch_size=2,
        val_every=2,
        val_size=3,
        min_views=2,
        max_views=3,
        model={"dim": 16, "depth": 1, "window": 6},
    )
    tt.train_temporal(cfg, d / "full")  # an uninterrupted run, shared by the tests below
    return d, cfg


def _weights(path):
    from safetensors.torch import load_file

    return load_file(str(path / "model.safetensors"))


def test_train_and_resume_equal_an_uninterrupted_run(setup, monkeypatch):
    d, cfg = setup
    real = tt._checkpoint
    calls = []

    def killed_after_first(run, *a):
        real(run, *a)
        calls.append(run.step)
        raise KeyboardInterrupt  # a kill right after the first checkpoint

    monkeypatch.setattr(tt, "_checkpoint", killed_after_first)
    with pytest.raises(KeyboardInterrupt):
        tt.train_temporal(cfg, d / "resumed")
    monkeypatch.setattr(tt, "_checkpoint", real)
    assert calls == [2]
    tt.train_temporal(cfg, d / "resumed")
    a, b = _weights(d / "full"), _weights(d / "resumed")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    steps = [json.loads(x)["step"] for x in (d / "resumed" / "log.jsonl").read_text().splitlines()]
    assert steps == [2, 4]


def test_a_log_line_without_its_checkpoint_is_not_duplicated(tmp_path):
    (tmp_path / "log.jsonl").write_text('{"step": 2}\n{"step": 4}\n')
    tt._write_log(tmp_path, {"step": 4, "x": 1})
    lines = [json.loads(x) for x in (tmp_path / "log.jsonl").read_text().split("\n") if x]
    assert lines == [{"step": 2}, {"step": 4, "x": 1}]


def test_checkpoint_round_trip(setup):
    d, cfg = setup
    model, meta = tt.load_temporal(d / "full")
    assert meta["format"] == tt.FORMAT and meta["temporal"]["window"] == 6
    assert meta["training"]["last"]["sigma_scale"] > 0
    torch.manual_seed(1)
    rays = torch.randn(1, 6, 2, 17, 6)
    rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    sc, times = torch.rand(1, 6, 2, 17), torch.arange(6.0)[None] / 30
    tt.save_temporal(model, d / "copy")
    again, _ = tt.load_temporal(d / "copy")
    with torch.no_grad():
        assert torch.equal(model(rays, sc, times)[0], again(rays, sc, times)[0])


def test_bad_training_input(setup, tmp_path):
    _, cfg = setup
    with pytest.raises(InputError, match="sequences"):
        tt._load_bank(tt.TemporalTrainConfig(sequences=str(tmp_path / "none.npz")))
    with pytest.raises(InputError, match="holdout"):
        tt._load_bank(tt.TemporalTrainConfig(sequences=cfg.sequences, holdout=("99",)))
    bad = tmp_path / "bad.toml"
    bad.write_text("stepz = 3\n")
    with pytest.raises(InputError, match="stepz"):
        tt.TemporalTrainConfig.from_toml(bad)


# --------------------------------------------------------------------------- track lifting


def _rig(n=3) -> Rig:
    K = np.array([[800.0, 0, 640], [0, 800, 360], [0, 0, 1]])
    eyes = [[4, 0, 1.5], [0, 4, 1.5], [-3, -3, 2.0], [3, -3, 1.0]][:n]
    return Rig(tuple(Camera(K, *look_at(np.array(e, float), np.array([0, 0, 1.0])), name=f"c{i}")
                     for i, e in enumerate(eyes)))  # fmt: skip


def _track(T=30, n=3, seed=0):
    rig = _rig(n)
    b = _bank(segments=1, frames=max(T, 60))
    joints = b.poses[:T].astype(float) - [0.6, 0, 0]
    kp = np.stack([c.project(joints) for c in rig], 1)  # (T, V, 17, 2)
    kp = kp + np.random.default_rng(seed).normal(0, 1.0, kp.shape)
    return kp, np.full(kp.shape[:-1], 0.9), rig, joints


def _lifter(window=8, head=False, seed=0) -> TemporalLifter:
    torch.manual_seed(seed)
    frame = RMPL(PRESETS["tiny"])
    m = TemporalRMPL(frame, TemporalConfig(dim=16, depth=1, window=window))
    if head:
        with torch.no_grad():
            m.head.weight.normal_(0, 0.02)
    return TemporalLifter(m, onnx=False)


def test_stitched_windows_equal_the_per_frame_model_when_the_head_is_zero():
    """With a zero correction every window gives the same per-frame answer, so stitching
    must reproduce it exactly (no seam, no weight error)."""
    kp, sc, rig, _ = _track(T=30)
    lifter = _lifter(window=8)
    from rmpl.inference import Lifter

    frame = Lifter(lifter.model.frame_model, backend="torch").lift(kp, sc, rig).points
    r = lifter.lift_track(kp, sc, rig, fps=30)
    assert r.points.shape == (30, 17, 3) and r.sigma.shape == (30, 17)
    assert np.allclose(r.points, frame, atol=1e-5)


def test_stitching_is_close_to_one_long_window():
    kp, sc, rig, _ = _track(T=24)
    short, long = _lifter(window=8, head=True), _lifter(window=24, head=True)
    a = short.lift_track(kp, sc, rig, fps=30).points
    b = long.lift_track(kp, sc, rig, fps=30).points
    # same weights, different windows: the answers differ by the small learned corrections
    assert np.nanmax(np.abs(a - b)) < 0.05


def test_missing_frames_are_filled_and_do_not_spread_nan():
    kp, sc, rig, _ = _track(T=20)
    kp[5:8] = np.nan
    sc[5:8] = 0
    r = _lifter().lift_track(kp, sc, rig, fps=30)
    assert np.isfinite(r.points).all() and np.isfinite(r.sigma).all()
    assert (r.num_views[5:8] == 0).all() and (r.num_views[0] == 3).all()


def test_fps_and_times_are_the_same_thing():
    kp, sc, rig, _ = _track(T=12)
    lifter = _lifter(head=True)
    a = lifter.lift_track(kp, sc, rig, fps=25).points
    b = lifter.lift_track(kp, sc, rig, times=np.arange(12) / 25 + 7.0).points
    assert np.allclose(a, b, atol=1e-4)


def test_bad_track_input():
    kp, sc, rig, _ = _track(T=10)
    lifter = _lifter()
    with pytest.raises(InputError, match="at least one frame"):
        lifter.lift_track(kp[:0], sc[:0], rig, fps=30)
    with pytest.raises(InputError, match="fps"):
        lifter.lift_track(kp, sc, rig, fps=0)
    with pytest.raises(InputError, match="fps / times"):
        lifter.lift_track(kp, sc, rig)
    with pytest.raises(InputError, match="scores"):
        lifter.lift_track(kp, sc[:-1], rig, fps=30)
    with pytest.raises(InputError, match="times"):
        lifter.lift_track(kp, sc, rig, times=np.arange(9.0))
    with pytest.raises(InputError, match="times"):
        lifter.lift_track(kp, sc, rig, times=np.zeros(10))
    with pytest.raises(InputError, match="one track"):
        lifter.lift_track(kp[None], sc[None], rig, fps=30)
    with pytest.raises(InputError, match="views"):
        lifter.lift_track(kp[:, :2], sc[:, :2], rig, fps=30)


def test_window_starts_cover_every_frame_once_or_more():
    for T, W in [(5, 8), (8, 8), (9, 8), (30, 8), (31, 7)]:
        starts = window_starts(T, W)
        covered = np.zeros(T, int)
        for a in starts:
            covered[a : a + min(W, T)] += 1
        assert (covered >= 1).all() and starts[-1] + min(W, T) == T
    assert np.allclose(frame_times(3, 10.0, None), [0, 0.1, 0.2])


def test_rmpl_train_runs_a_temporal_config(setup, tmp_path):
    from rmpl.cli import main

    d, cfg = setup
    toml = tmp_path / "t.toml"
    toml.write_text(
        f'sequences = "{cfg.sequences}"\nframe_model = "{cfg.frame_model}"\nsteps = 2\n'
        "batch_size = 2\nval_every = 2\nval_size = 2\nmin_views = 2\nmax_views = 2\n"
        "[model]\ndim = 16\ndepth = 1\nwindow = 4\n"
    )
    assert main(["train", str(toml), "--out", str(tmp_path / "run"), "--set", "seed=3"]) == 0
    model, meta = tt.load_temporal(tmp_path / "run")
    assert meta["training"]["train_config"]["seed"] == 3 and model.config.window == 4


def test_lift_and_run_with_a_temporal_model_write_the_uncertainty(setup, tmp_path):
    """rmpl lift / rmpl run with a temporal checkpoint: whole tracks, uncertainty in the files."""
    from rmpl.cli import main
    from rmpl.io.poses import load_poses
    from tests.cli.test_commands import make_scene

    d, _ = setup
    X = make_scene(tmp_path, views=3, frames=12)
    common = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    out = tmp_path / "lift.json"
    assert main(["lift", *common, "--model", str(d / "full"), "--out", str(out)]) == 0
    poses = load_poses(out)
    assert poses.points.shape == (12, 1, 17, 3) and poses.uncertainty.shape == (12, 1, 17)
    assert np.isfinite(poses.uncertainty).all() and (poses.uncertainty > 0).all()
    assert np.nanmean(np.linalg.norm(poses.points[:, 0] - X, axis=-1)) < 1.0
    run_dir = tmp_path / "run"
    assert main(["run", *common, "--model", str(d / "full"), "--out", str(run_dir),
                 "--no-pictures"]) == 0  # fmt: skip
    assert load_poses(run_dir / "poses.npz").uncertainty is not None


def test_damaged_or_wrong_temporal_checkpoints_are_one_clear_error(setup, tmp_path):
    import shutil

    d, cfg = setup
    with pytest.raises(InputError, match="format"):
        tt.load_temporal(cfg.frame_model)  # a per-frame checkpoint
    bad = tmp_path / "bad"
    shutil.copytree(d / "full", bad)
    (bad / "model.safetensors").write_bytes(b"garbage")
    with pytest.raises(InputError, match="model.safetensors"):
        tt.load_temporal(bad)
    with pytest.raises(InputError, match="config.json"):
        TemporalLifter.from_pretrained(tmp_path / "nowhere")
    damaged = tmp_path / "damaged_calibration"
    shutil.copytree(d / "full", damaged)
    meta = json.loads((damaged / "config.json").read_text())
    meta["calibration"] = {"r50": [1.0, 2.0], "r90": [0.5]}
    (damaged / "config.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="calibration"):
        TemporalLifter.from_pretrained(damaged)


def test_training_writes_a_per_view_count_radius_calibration(setup):
    """The checkpoint carries radius factors per number of views; the lifter uses them."""
    d, _ = setup
    lifter = TemporalLifter.from_pretrained(d / "full")
    c = lifter.calibration
    assert c is not None and len(c.r50) == len(c.r90) == 6
    assert all(b >= a > 0 for a, b in zip(c.r50, c.r90, strict=True))
    kp, sc, rig, _ = _track(T=12)
    r = lifter.lift_track(kp, sc, rig, fps=30)
    k = np.clip(r.num_views, 0, 5)
    assert np.allclose(r.radius(0.5), r.sigma * np.asarray(c.r50)[k])
    assert np.allclose(r.radius(0.9), r.sigma * np.asarray(c.r90)[k])


def test_radius_calibration_by_view_count():
    """Hand-computed: each joint's radius is its scale times its view count's factor."""
    from rmpl.inference_temporal import RadiusCalibration, TrackResult

    c = RadiusCalibration(r50=(1.0, 2.0, 3.0), r90=(2.0, 4.0, 5.0))
    sigma = np.array([[0.1, 0.1, 0.1, 0.2]])
    views = np.array([[0, 1, 2, 7]])  # 7 views: the last factor
    r = TrackResult(np.zeros((1, 4, 3)), sigma, views, c)
    assert np.allclose(r.radius(0.5), [[0.1, 0.2, 0.3, 0.6]])
    assert np.allclose(r.radius(0.9), [[0.2, 0.4, 0.5, 1.0]])
    plain = TrackResult(np.zeros((1, 4, 3)), sigma, views)  # no calibration: chi quantiles
    assert np.allclose(plain.radius(0.5), 1.5382 * sigma)
    for bad in [
        dict(r50=(1.0,), r90=(0.5,)),
        dict(r50=(), r90=()),
        dict(r50=(np.nan,), r90=(1.0,)),
    ]:
        with pytest.raises(ValueError):
            RadiusCalibration(**bad)
    with pytest.raises(ValueError, match="too few"):
        tt.radius_quantiles(np.ones(10), np.ones(10), np.zeros(10, int))


def test_the_shipped_temporal_model_lifts_the_embedded_walk():
    import rmpl
    from rmpl.inference_temporal import PRETRAINED_TEMPORAL

    ex = Path(rmpl.__file__).parent / "examples" / "walk"
    if not (PRETRAINED_TEMPORAL["temporal"] / "config.json").is_file():
        pytest.skip("no shipped temporal model in this checkout")
    rig = rmpl.load_rig(ex / "calibration.toml")
    kp = rmpl.load_keypoints(ex / "keypoints.json")
    truth = np.load(ex / "ground_truth.npz")["points"][:, 0]
    r = TemporalLifter.from_pretrained().lift_track(
        kp.keypoints[:, :, 0], kp.scores[:, :, 0], rig, fps=kp.fps
    )
    err = np.linalg.norm(r.points - truth, axis=-1)
    assert np.isfinite(err).all() and err.mean() < 0.06  # 4 views of MediaPipe: about 36 mm
    assert (r.sigma > 0).all() and np.isfinite(r.sigma).all()


def test_a_clock_origin_does_not_change_the_answer():
    """Times on a Unix clock (1.7e9 s) give what the frame rate gives: float32 would not."""
    kp, sc, rig, _ = _track(T=30)
    lifter = _lifter(head=True)
    a = lifter.lift_track(kp, sc, rig, fps=30).points
    b = lifter.lift_track(kp, sc, rig, times=1.7e9 + np.arange(30) / 30).points
    assert np.allclose(a, b, atol=1e-4)


def test_no_frames_are_invented_before_or_after_a_track():
    kp, sc, rig, _ = _track(T=40)
    kp[:15], sc[:15] = np.nan, 0
    kp[-5:], sc[-5:] = np.nan, 0
    r = _lifter(window=8).lift_track(kp, sc, rig, fps=30)
    assert np.isnan(r.points[:15]).all() and np.isnan(r.points[-5:]).all()
    assert np.isfinite(r.points[15:-5]).all() and np.isnan(r.sigma[:15]).all()


def test_temporal_training_config_values_are_checked():
    for bad in ({"val_every": 0}, {"steps": 0}, {"max_views": 1}, {"min_views": 4, "max_views": 3}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            tt.TemporalTrainConfig(**bad)


def test_temporal_run_edge_cases(setup, tmp_path, capsys):
    """Nobody anywhere is one clear error; 10 frames/s is a rate the model takes (the
    Butterworth cut-off check does not apply to it); several people write one BVH each."""
    from rmpl.cli import main
    from rmpl.io.poses import Poses3D
    from rmpl.pipeline.outputs import _write_bvh
    from rmpl.pipeline.runner import RunConfig, run
    from tests.cli.test_commands import make_scene

    d, _ = setup
    model = str(d / "full")
    make_scene(tmp_path, views=3, frames=8)
    far = tmp_path / "far.json"
    from rmpl.io.keypoints import load_keypoints, save_keypoints

    k = load_keypoints(tmp_path / "kp.json")
    k.keypoints[:] = 1e9
    save_keypoints(k, far)
    args = ["lift", "--calib", str(tmp_path / "calib.toml"), "--keypoints", str(far)]
    assert main([*args, "--model", model, "--out", str(tmp_path / "o.json")]) == 2
    assert "Traceback" not in capsys.readouterr().err
    k = load_keypoints(tmp_path / "kp.json")
    rig = rmpl_load_rig(tmp_path / "calib.toml")
    poses = run(k.keypoints, k.scores, rig, fps=10.0, config=RunConfig(model=model))
    assert np.isfinite(poses.points).any() and poses.uncertainty is not None
    two = Poses3D(np.repeat(poses.points, 2, axis=1), fps=10.0,
                  uncertainty=np.repeat(poses.uncertainty, 2, axis=1))  # fmt: skip
    _write_bvh(two, tmp_path / "bvh")
    assert sorted(p.name for p in (tmp_path / "bvh").iterdir()) == ["poses_p0.bvh", "poses_p1.bvh"]


def rmpl_load_rig(path):
    from rmpl.io.calibration import load_rig

    return load_rig(path)


def test_assemble_track_takes_the_per_frame_answer_where_two_views_see_the_joint():
    """Hand-checkable: constant answers pass the filters unchanged, so the result is the
    per-frame answer where two views see a joint and the network's where fewer do; a frame
    the network has no answer for stays empty and does not empty its neighbours."""
    from rmpl.inference_temporal import assemble_track

    T = 30
    network = np.tile([[4.0, 5.0, 6.0], [7.0, 8.0, 9.0]], (T, 1, 1))
    frame = np.tile([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]], (T, 1, 1))
    views = np.tile([2, 1], (T, 1))
    network[10] = np.nan
    out = assemble_track(network, frame, views, np.arange(T) / 30)
    assert np.isnan(out[10]).all() and np.isfinite(np.delete(out, 10, 0)).all()
    assert np.allclose(np.delete(out[:, 0], 10, 0), [1, 2, 3])
    assert np.allclose(np.delete(out[:, 1], 10, 0), [7, 8, 9])


def test_a_filtered_lifter_keeps_the_track_invariants():
    """The shipped assembly: view order does not matter, a missing frame does not spread NaN,
    and frames before the first keypoint stay empty."""
    kp, sc, rig, _ = _track(T=30)
    lifter = _lifter(window=8, head=True)
    lifter.assemble = "filtered"
    r = lifter.lift_track(kp, sc, rig, fps=30)
    perm = [2, 0, 1]
    rig_p = Rig(tuple(rig[i] for i in perm))
    rp = lifter.lift_track(kp[:, perm], sc[:, perm], rig_p, fps=30)
    assert np.allclose(r.points, rp.points, atol=1e-4)
    kp2, sc2 = kp.copy(), sc.copy()
    kp2[12], sc2[12] = np.nan, 0.0
    kp2[:3], sc2[:3] = np.nan, 0.0
    r2 = lifter.lift_track(kp2, sc2, rig, fps=30)
    assert np.isfinite(r2.points[3:]).all() and np.isnan(r2.points[:3]).all()


def test_a_checkpoint_naming_an_unknown_assembly_is_one_clear_error(setup, tmp_path):
    import shutil

    d, _ = setup
    bad = tmp_path / "bad_assemble"
    shutil.copytree(d / "full", bad)
    meta = json.loads((bad / "config.json").read_text())
    meta["inference"] = {"assemble": "magic"}
    (bad / "config.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="inference.assemble"):
        TemporalLifter.from_pretrained(bad)
    with pytest.raises(ValueError, match="assemble"):
        TemporalLifter(tt.load_temporal(d / "full")[0], assemble="magic")


def test_training_mixes_in_mhp_sequences_and_resumes_exactly(setup, tmp_path, monkeypatch):
    """mhp_sequences: batches come from both sources (the held-out subject's sequences left
    out), and a killed run resumed equals an uninterrupted one."""
    from tests.data.test_mhp_sequences import _fake_sequences

    d, cfg = setup
    _fake_sequences(tmp_path / "mhp")  # subjects 01 and 03, 10 frames, 4 views
    mix = tt.TemporalTrainConfig(**{**vars(cfg), "mhp_sequences": (str(tmp_path / "mhp"),),
                                    "mhp_weight": 0.5, "holdout": ("03",)})  # fmt: skip
    drawn = []
    real_batch = tt.SequenceSource.batch

    def spy(self, *a, **k):
        drawn.append("synthetic")
        return real_batch(self, *a, **k)

    monkeypatch.setattr(tt.SequenceSource, "batch", spy)
    from rmpl.data.mhp import SequenceShardSource

    real_mhp = SequenceShardSource.batch

    def spy_mhp(self, *a, **k):
        drawn.append("mhp")
        assert len(self.data["joints3d"]) == 3  # subject 03's 3 sequences held out
        return real_mhp(self, *a, **k)

    monkeypatch.setattr(SequenceShardSource, "batch", spy_mhp)
    tt.train_temporal(mix, tmp_path / "full")
    assert drawn.count("mhp") >= 1 and drawn.count("synthetic") >= 2  # 4 steps + validation
    real = tt._checkpoint

    def killed_after_first(run, *a):
        real(run, *a)
        raise KeyboardInterrupt

    monkeypatch.setattr(tt, "_checkpoint", killed_after_first)
    with pytest.raises(KeyboardInterrupt):
        tt.train_temporal(mix, tmp_path / "resumed")
    monkeypatch.setattr(tt, "_checkpoint", real)
    tt.train_temporal(mix, tmp_path / "resumed")
    a, b = _weights(tmp_path / "full"), _weights(tmp_path / "resumed")
    assert all(torch.equal(a[k], b[k]) for k in a)
    short = tt.TemporalTrainConfig(**{**vars(mix), "model": {**cfg.model, "window": 12}})
    with pytest.raises(InputError, match="mhp_sequences"):
        tt.train_temporal(short, tmp_path / "short")
