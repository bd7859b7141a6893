"""The temporal model that reads the floor: model, data, training, the track lifter and the
one-camera path (issue 16)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from rmpl.data.sequences import SequenceSource
from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.geometry.floor import Floor
from rmpl.inference_temporal import TemporalLifter
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.model.temporal import TemporalConfig, TemporalRMPL
from rmpl.training import temporal as tt
from rmpl.training.loop import save_checkpoint
from tests.data.test_sequences import _bank
from tests.training.test_temporal import _track


def _model(seed=0, floor=True, perturb=True) -> TemporalRMPL:
    torch.manual_seed(seed)
    frame = RMPL(PRESETS["tiny"].with_(floor=True))
    m = TemporalRMPL(frame, TemporalConfig(dim=16, depth=1, window=8, floor=floor)).eval()
    if perturb:  # trained weights: the floor input and the head do something
        with torch.no_grad():
            m.head.weight.normal_(0, 0.05)
            if m.floor_in is not None:
                m.floor_in.weight.normal_(0, 0.5)
    return m


def _window(B=2, T=8, V=1, seed=0):
    g = torch.Generator().manual_seed(seed)
    d = torch.randn(B, T, V, 17, 3, generator=g) * 0.1 + torch.tensor([1.0, 0.0, -0.3])
    d = d / d.norm(dim=-1, keepdim=True)
    o = torch.tensor([-3.0, 0.0, 1.5]).expand(B, T, V, 17, 3)
    rays = torch.cat([o, d], -1)
    return rays, torch.full((B, T, V, 17), 0.9), torch.arange(T, dtype=torch.float32)[None] / 25


def test_an_unknown_floor_is_no_floor_and_a_known_one_changes_the_answer():
    m = _model()
    rays, scores, times = _window()
    times = times.expand(2, -1)
    with torch.no_grad():
        none, _ = m(rays, scores, times)
        unknown, _ = m(rays, scores, times, torch.full((2, 4), float("nan")))
        known, _ = m(rays, scores, times, torch.tensor([[0.0, 0, 1, 0], [0.0, 0, 1, 0]]))
    assert torch.equal(none, unknown)
    assert (known - none).abs().max() > 1e-3


def test_a_new_floor_input_starts_at_zero_so_the_temporal_stage_is_unchanged():
    m = _model(perturb=False)
    rays, scores, times = _window()
    times = times.expand(2, -1)
    floor = torch.tensor([[0.0, 0, 1, 0], [0.0, 0, 1, 0.3]])
    with torch.no_grad():
        m.head.weight.normal_(0, 0.05)
        enc = m.encode_frames(rays, scores, floor)
        a, _ = m.forward_encoded(*enc, times, floor)
        b, _ = m.forward_encoded(*enc, times)
        m.floor_in.weight.normal_(0, 0.5)
        c, _ = m.forward_encoded(*enc, times, floor)
    assert torch.equal(a, b)
    assert (c - b).abs().max() > 1e-4  # and it is read once it has weights


def test_the_temporal_floor_needs_a_floor_reading_frame_model():
    with pytest.raises(ValueError, match="reads the floor"):
        TemporalRMPL(RMPL(PRESETS["tiny"]), TemporalConfig(floor=True))


def test_onnx_encoder_with_the_floor_matches_torch():
    pytest.importorskip("onnxruntime")
    m = _model()
    rays, scores, times = _window()
    times = times.expand(2, -1)
    floor = torch.tensor([[0.0, 0, 1, 0.05], [float("nan")] * 4])
    with torch.no_grad():
        a, sa = m(rays, scores, times, floor)
        m.use_onnx(1)
        b, sb = m(rays, scores, times, floor)
    assert np.allclose(a.numpy(), b.numpy(), atol=2e-3)
    assert np.allclose(sa.numpy(), sb.numpy(), rtol=2e-2, atol=1e-4)


def test_sequence_windows_carry_their_floor_only_when_asked():
    bank = _bank()
    plain = SequenceSource(bank, seed=3).batch(4, 8, 2)
    none = SequenceSource(bank, seed=3, floor=(0.0, 0.02, 1.0)).batch(4, 8, 2)
    assert plain.floor is None and none.floor is None
    assert np.array_equal(plain.rays, none.rays)  # no floor: nothing else drawn
    given = SequenceSource(bank, seed=3, floor=(1.0, 0.02, 1.0)).batch(4, 8, 2)
    assert np.isfinite(given.floor).all() and given.floor.shape == (4, 4)
    assert np.abs(given.floor[:, 3]).max() < 0.2 and (given.floor[:, 2] > 0.99).all()
    exact = SequenceSource(bank, seed=3, floor=(1.0, 0.02, 1.0)).batch(4, 8, 2, train=False)
    assert np.array_equal(exact.floor, np.tile([0, 0, 1, 0], (4, 1)).astype(np.float32))
    half = SequenceSource(bank, seed=3, floor=(0.5, 0.0, 0.0)).batch(200, 2, 2)
    assert 0.3 < np.isnan(half.floor[:, 0]).mean() < 0.7
    with pytest.raises(ValueError, match="floor"):
        SequenceSource(bank, floor=(1.5, 0.0, 0.0))


@pytest.fixture(scope="module")
def floor_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("temporal_floor")
    torch.manual_seed(0)
    save_checkpoint(RMPL(PRESETS["tiny"].with_(robust_anchor=1)), d / "plain")
    save_checkpoint(RMPL(PRESETS["tiny"].with_(robust_anchor=1, floor=True)), d / "frame")
    _bank().save(d / "seq.npz")
    base = dict(
        sequences=str(d / "seq.npz"), steps=2, batch_size=2, val_every=2, val_size=3,
        min_views=1, max_views=3, single_view_rate=0.5,
    )  # fmt: skip
    model = {"dim": 16, "depth": 1, "window": 6}
    cfg = tt.TemporalTrainConfig(**base, frame_model=str(d / "plain"), model=model)
    tt.train_temporal(cfg, d / "plain_run")
    cfg = tt.TemporalTrainConfig(
        **base, frame_model=str(d / "frame"), model=model | {"floor": True},
        init=str(d / "plain_run"), floor_rate=0.8,
    )  # fmt: skip
    tt.train_temporal(cfg, d / "floor_run")
    return d, cfg


def test_init_copies_the_temporal_stage_and_training_writes_a_floor_model(floor_run):
    d, cfg = floor_run
    source, _ = tt.load_temporal(d / "plain_run")
    fresh = tt.build_temporal(cfg)  # starts from plain_run's temporal stage
    for k, v in source.state_dict().items():
        if not k.startswith("frame_model."):
            assert torch.equal(fresh.state_dict()[k], v), k
    assert torch.count_nonzero(fresh.floor_in.weight) == 0
    model, meta = tt.load_temporal(d / "floor_run")
    assert meta["temporal"]["floor"] and model.floor_in is not None
    assert TemporalLifter(model, meta, onnx=False).reads_floor


def test_init_from_another_architecture_is_one_clear_error(floor_run):
    d, cfg = floor_run
    bad = dataclasses.replace(cfg, model=cfg.model | {"dim": 32})
    with pytest.raises(InputError, match="init"):
        tt.build_temporal(bad)


def _floor_lifter(seed=0) -> TemporalLifter:
    return TemporalLifter(_model(seed), onnx=False)


def test_lift_track_takes_the_floor_and_checks_it():
    kp, sc, rig, _ = _track(T=12, n=1)
    lifter = _floor_lifter()
    plain = lifter.lift_track(kp, sc, rig, fps=25)
    ground = Floor((0.0, 0.0, 1.0), 0.0, "test")
    given = lifter.lift_track(kp, sc, rig, fps=25, floor=ground)
    assert np.isfinite(given.points).all()
    assert np.abs(given.points - plain.points).max() > 1e-4
    with pytest.raises(InputError, match="floor"):
        lifter.lift_track(kp, sc, rig, fps=25, floor=Floor((0.0, 0.0, 1.0), 5.0, "test"))
    with pytest.raises(InputError, match="floor"):
        lifter.lift_track(kp, sc, rig, fps=25, floor=(0, 0, 1, 0))


def test_one_camera_with_a_temporal_floor_model_lifts_whole_tracks(floor_run, monkeypatch):
    from rmpl.pipeline import monocular
    from rmpl.pipeline.runner import RunConfig

    d, _ = floor_run
    kp, sc, rig, _ = _track(T=20, n=1)
    kp[5:8] = np.nan  # the view misses the person for three frames
    sc[5:8] = 0
    calls = []
    real = TemporalLifter.lift_track

    def spy(self, *a, **k):
        calls.append(k.get("floor"))
        return real(self, *a, **k)

    monkeypatch.setattr(TemporalLifter, "lift_track", spy)
    ground = Floor((0.0, 0.0, 1.0), 0.0, "test")
    cfg = RunConfig(model=str(d / "floor_run"))
    poses = monocular.lift_single_view(
        kp[:, :, None], sc[:, :, None], Rig((rig[0],)), None, 25.0, ground, cfg
    )
    assert calls and calls[0] is ground
    assert poses.points.shape[:2] == (20, 1)
    inside = np.isfinite(poses.points[:, 0]).all((-1, -2))
    assert inside.all()  # the missed frames are the network's fill, flagged as such
    assert (poses.flags[5:8, 0] == 3).all() and (poses.flags[8:, 0] == 1).all()
    assert (poses.num_views[5:8, 0] == 0).all()
    assert np.isfinite(poses.uncertainty[:, 0]).all()
    with pytest.raises(InputError, match="fps"):
        monocular.lift_single_view(kp[:, :, None], sc[:, :, None], Rig((rig[0],)), None, None,
                                   ground, cfg)  # fmt: skip


def test_one_camera_temporal_tracks_are_cut_at_gaps_longer_than_max_gap(floor_run):
    # Beyond max_gap frames of misses the track is two pieces, each lifted on its own: the
    # frames between stay empty (no invented poses), as in the multi-view path.
    from rmpl.pipeline import monocular
    from rmpl.pipeline.runner import RunConfig

    d, _ = floor_run
    kp, sc, rig, _ = _track(T=40, n=1)
    kp[10:30], sc[10:30] = np.nan, 0  # a 20-frame miss
    ground = Floor((0.0, 0.0, 1.0), 0.0, "test")
    args = (kp[:, :, None], sc[:, :, None], Rig((rig[0],)), None, 25.0, ground)
    short = monocular.lift_single_view(*args, RunConfig(model=str(d / "floor_run"), max_gap=5))
    seen = np.isfinite(short.points[:, 0]).all((-1, -2))
    assert seen[:10].all() and seen[30:].all() and not seen[10:30].any()
    assert (short.num_views[10:30] == 0).all() and (short.flags[10:30] == 0).all()
    # A max_gap that covers the miss bridges it: the network fills what its windows reach
    # (up to a window from the seen frames), flagged so.
    long = monocular.lift_single_view(*args, RunConfig(model=str(d / "floor_run"), max_gap=25))
    filled = np.isfinite(long.points[10:30, 0]).all((-1, -2))
    assert filled.any() and (long.flags[10:30, 0][filled] == 3).all()


def test_rmpl_run_one_camera_temporal_at_a_low_frame_rate(floor_run, tmp_path):
    # The Butterworth --cutoff (default 6 Hz) is not used by a temporal model: 10 frames/s
    # (Nyquist 5 Hz) is not refused.
    from rmpl.cli import main
    from rmpl.io.poses import load_poses
    from tests.cli.test_commands import _one_camera_walk

    d, _ = floor_run
    _one_camera_walk(tmp_path, fps=10.0)
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    out = tmp_path / "run"
    code = main(["run", *io, "--out", str(out), "--model", str(d / "floor_run"),
                 "--floor", "z=0", "--no-pictures", "--formats", "npz"])  # fmt: skip
    assert code in (0, 3)  # 3: the view check may flag an untrained model's answer
    assert load_poses(out / "poses.npz").fps == 10


def test_one_camera_refuses_a_temporal_model_that_does_not_read_the_floor(floor_run):
    from rmpl.pipeline import monocular
    from rmpl.pipeline.runner import RunConfig

    d, _ = floor_run
    kp, sc, rig, _ = _track(T=10, n=1)
    with pytest.raises(InputError, match="reads the floor"):
        monocular.lift_single_view(
            kp[:, :, None], sc[:, :, None], Rig((rig[0],)), None, 25.0, None,
            RunConfig(model=str(d / "plain_run")),
        )  # fmt: skip


def test_rmpl_run_one_camera_with_a_temporal_floor_model(floor_run, tmp_path, caplog):
    import json

    from rmpl.cli import main
    from rmpl.io.poses import load_poses
    from tests.cli.test_commands import _one_camera_walk

    d, _ = floor_run
    _one_camera_walk(tmp_path)
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    out = tmp_path / "run"
    with caplog.at_level("INFO"):
        code = main(["run", *io, "--out", str(out), "--model", str(d / "floor_run"),
                     "--floor", "z=0", "--no-pictures", "--formats", "npz,json"])  # fmt: skip
    assert code in (0, 3)  # 3: the view check may flag an untrained model's answer
    assert "whole tracks lifted by the temporal model" in caplog.text
    poses = load_poses(out / "poses.npz")
    assert poses.points.shape[:2] == (60, 1) and np.isfinite(poses.points).all()
    assert poses.uncertainty is not None and np.isfinite(poses.uncertainty).all()
    report = json.loads((out / "report.json").read_text())
    assert report["one_camera"]["uncertainty_50_mm_median"] > 0


def test_evaluate_takes_a_temporal_floor_model_as_a_sequence_method_only(floor_run, capsys):
    # rmpl+floor@TEMPORAL lifts whole tracks: a sequence method (refused where there is no
    # time), with the time cue, and only with a model that reads the floor - never quietly
    # its per-frame model.
    from rmpl.cli import main
    from rmpl.evaluate.registry import parse_methods
    from rmpl.evaluate.sequences import needs_time

    d, _ = floor_run
    run, plain = str(d / "floor_run"), str(d / "plain_run")
    assert needs_time(f"rmpl+floor@{run}") and needs_time(f"rmpl+floor:time@{run}")
    assert not needs_time("rmpl+floor@floor26") and not needs_time("rmpl+floor")
    (method,) = parse_methods(f"rmpl+floor@{run}").values()
    assert method.sequence
    with pytest.raises(InputError, match="time cue"):
        parse_methods(f"rmpl+floor:none@{run}")
    with pytest.raises(InputError, match="reads the floor"):
        parse_methods(f"rmpl+floor@{plain}")
    code = main(["evaluate", "--dataset", "synthetic", "--root", str(d / "seq.npz"),
                 "--methods", f"rmpl+floor@{run}", "--views", "1"])  # fmt: skip
    assert code == 2 and "per-frame methods" in capsys.readouterr().err
