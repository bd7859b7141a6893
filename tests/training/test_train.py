"""The trainer: a tiny real run, resume after a stop, config errors, ablation variants and
MHP shards as a source (the last skipped without anny, moderngl and mediapipe)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from rmpl.errors import InputError
from rmpl.training.loop import TrainConfig, load_checkpoint, train
from tests.conftest import synth_ready

EXAMPLE = Path(__file__).parents[2] / "src/rmpl/examples/walk/ground_truth.npz"


@pytest.fixture(scope="module")
def poses():
    """Real walking poses (COCO-17, metres) from the embedded example: train / validation."""
    p = np.load(EXAMPLE)["points"][:, 0]
    return p[:40], p[40:]


def tiny_config(**kw) -> TrainConfig:
    base = dict(
        preset="tiny",
        steps=6,
        batch_size=8,
        val_every=3,
        val_size=8,
        threads=1,
        lr=1e-3,
    )
    return TrainConfig.from_dict({**base, **kw})


def read_log(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]


def test_train_writes_checkpoint_and_resumes(poses, tmp_path):
    run = tmp_path / "run"
    train(tiny_config(steps=3), run, *poses)
    assert [r["step"] for r in read_log(run)] == [3]
    first, _ = load_checkpoint(run)
    # Same command with more steps: continues at step 3, does not start again.
    train(tiny_config(steps=6), run, *poses)
    log = read_log(run)
    assert [r["step"] for r in log] == [3, 6]
    assert all(np.isfinite(r["kpstar_2v"]) for r in log)
    assert torch.load(run / "state.pt", weights_only=False)["step"] == 6
    second, meta = load_checkpoint(run)
    assert meta["training"]["last"]["step"] == 6
    a, b = first.state_dict(), second.state_dict()
    assert any(not torch.equal(a[k], b[k]) for k in a)
    assert not list(run.glob("*.part*")) and not list(run.glob("*.tmp*"))


@pytest.mark.parametrize(
    "model",
    [
        {"inputs": "pixels+calib", "recenter": False, "geometric": False},
        {"architecture": "mlp", "geometric": False},
        {"confidence": False},
    ],
)
def test_ablation_variants_train(poses, tmp_path, model):
    run = train(tiny_config(steps=2, val_every=2, model=model), tmp_path / "run", *poses)
    rec = read_log(run)[-1]
    assert np.isfinite([rec[f"kpstar_{v}v"] for v in (1, 2, 3)]).all()
    loaded, meta = load_checkpoint(run)
    assert meta["model"] == loaded.config.to_dict()
    for key, value in model.items():
        assert getattr(loaded.config, key) == value


def test_config_errors_are_clear(tmp_path):
    with pytest.raises(ValueError, match="unknown training config keys"):
        TrainConfig.from_dict({"stepz": 3})
    with pytest.raises(ValueError, match="mhp_weight"):
        TrainConfig.from_dict({"mhp": ["somewhere"], "mhp_weight": 1.5})
    with pytest.raises(ValueError, match="recenter=false"):
        TrainConfig.from_dict({"model": {"inputs": "pixels"}})
    bad = tmp_path / "c.toml"
    bad.write_text("steps = 3\n")
    with pytest.raises(ValueError, match="key=value"):
        TrainConfig.from_toml(bad, ["steps"])


def test_noise_file(tmp_path):
    """A fitted [noise] table (rmpl generate --stats) feeds the noise model; explicit
    ``noise`` overrides win; a file without the table is one clear error."""
    from rmpl.synth.noise import NoiseConfig

    fitted = tmp_path / "noise.toml"
    fitted.write_text("[noise]\noutlier_rate = 0.125\nswap_rate = 0.25\n")
    cfg = TrainConfig.from_dict({"noise_file": str(fitted), "noise": {"swap_rate": 0.5}})
    noise = cfg.noise_config()
    assert noise.outlier_rate == 0.125 and noise.swap_rate == 0.5
    assert noise.conf_visible == NoiseConfig().conf_visible
    empty = tmp_path / "empty.toml"
    empty.write_text("steps = 3\n")
    with pytest.raises(InputError, match=r"empty\.toml.*\[noise\] table"):
        TrainConfig.from_dict({"noise_file": str(empty)})
    wrong = tmp_path / "wrong.toml"
    wrong.write_text("[noise]\nloudness = 3\n")
    with pytest.raises(InputError, match="loudness"):
        TrainConfig.from_dict({"noise_file": str(wrong)})
    with pytest.raises(InputError, match="nope.toml"):
        TrainConfig.from_dict({"noise_file": str(tmp_path / "nope.toml")})


def test_validation_batches_keep_the_true_cameras(poses):
    """Calibration-noise augmentation perturbs training rays only: validation is clean."""
    from rmpl.data.synthetic import PairSource, SamplerConfig

    def draw(noisy: bool, train: bool):
        cfg = SamplerConfig(drop_rate=0.0, calib_noise_deg=5.0 * noisy, calib_noise_m=0.1 * noisy)
        return PairSource(poses[0], cfg, seed=0).batch(16, 3, train=train)

    for train_batch in (True, False):
        a, b = draw(True, train_batch), draw(False, train_batch)
        assert np.array_equal(a.keypoints, b.keypoints, equal_nan=True)  # same scenes
        assert np.allclose(a.R, b.R) != train_batch
        assert np.allclose(a.rays, b.rays) != train_batch


def test_trains_on_mhp_shards(poses, tmp_path):
    synth_ready("anny", "moderngl", "mediapipe")
    from rmpl.synth.generate import GenerateConfig, generate

    shards = tmp_path / "mhp"
    generate(
        GenerateConfig.from_dict(
            {
                "poses": "random",
                "num_meshes": 2,
                "views": 4,
                "shard_size": 1,
                "batch_size": 1,
                "camera_preset": "h36m",
                "image_size": [400, 400],
                "seed": 3,
            }
        ),
        shards,
        progress=False,
    )
    # Random poses have subject "random"; nothing is held out of these tiny shards.
    cfg = tiny_config(
        steps=2,
        val_every=2,
        holdout=["nobody"],
        mhp=[str(shards)],
        mhp_weight=0.5,
        mhp_val=str(shards),
        max_views=4,
    )
    rec = read_log(train(cfg, tmp_path / "run", *poses))[-1]
    assert np.isfinite([rec[f"mhp_kpstar_{v}v"] for v in (1, 2, 3, 4)]).all()
    assert "mhp_kpstar_5v" not in rec  # the shards have 4 views
    assert np.isfinite(rec["mhp_triangulation_kpstar_4v"])
    # Holding out the only subject leaves nothing to train on: a clear error.
    with pytest.raises((ValueError, InputError), match="random|subject"):
        train(
            TrainConfig.from_dict({**cfg.__dict__, "holdout": ["random"], "mhp_weight": 1.0}),
            tmp_path / "bad",
            *poses,
        )


def test_noise_randomization_varies_the_detector_per_training_batch(poses):
    """noise_randomize draws a detector per training batch; validation and s=0 are unchanged."""
    from rmpl.data.synthetic import PairSource, SamplerConfig, randomized_noise
    from rmpl.synth.noise import NoiseConfig

    base = NoiseConfig()
    rng = np.random.default_rng(0)
    assert randomized_noise(base, 0.0, rng) is base
    draws = [randomized_noise(base, 1.0, rng) for _ in range(200)]
    scale = np.array([d.joint_sigma[0] / base.joint_sigma[0] for d in draws])
    assert 0.5 <= scale.min() < 0.6 and 1.8 < scale.max() <= 2.0
    assert all(0 <= d.outlier_rate <= 0.5 and 0 <= d.swap_rate <= 0.5 for d in draws)
    assert len({d.swap_rate for d in draws}) == len(draws)

    def error(batch):  # median 2D error of the detected keypoints, pixels
        from rmpl.geometry.camera import project

        truth = project(
            batch.target[:, None].astype(float),
            batch.K[:, :, None],
            batch.R[:, :, None],
            batch.t[:, :, None],
        )
        ok = batch.scores > 0
        return np.median(np.linalg.norm(batch.keypoints - truth, axis=-1)[ok])

    plain = PairSource(poses[0], SamplerConfig(drop_rate=0.0), seed=0)
    rand = PairSource(poses[0], SamplerConfig(drop_rate=0.0, noise_randomize=1.0), seed=0)
    val_a, val_b = plain.batch(64, 3, train=False), rand.batch(64, 3, train=False)
    assert np.array_equal(val_a.keypoints, val_b.keypoints, equal_nan=True)
    errs = [error(rand.batch(128, 3)) for _ in range(8)]
    assert max(errs) / min(errs) > 1.5  # batches see different detectors
    with pytest.raises(ValueError, match="noise_randomize"):
        SamplerConfig(noise_randomize=-1.0)


def test_mhp_with_too_few_views_is_refused_at_start(poses, tmp_path):
    """max_views above the MHP directories' views per mesh fails before training, clearly."""
    from rmpl.errors import InputError
    from rmpl.training.loop import _training_source
    from tests.data.test_mhp import _fake_mhp

    _fake_mhp(tmp_path / "mhp", views=3)
    cfg = TrainConfig.from_dict({"mhp": [str(tmp_path / "mhp")], "mhp_weight": 0.5, "max_views": 5})
    with pytest.raises(InputError, match="views per mesh"):
        _training_source(cfg, poses[0])
    ok = TrainConfig.from_dict({"mhp": [str(tmp_path / "mhp")], "mhp_weight": 0.5, "max_views": 3})
    assert _training_source(ok, poses[0]).batch(4, 3).rays.shape == (4, 3, 17, 6)


def _weights(run: Path) -> dict[str, torch.Tensor]:
    model, _ = load_checkpoint(run)
    return model.state_dict()


def _without_time(log: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "seconds"} for r in log]


def test_resumed_run_is_bit_identical_to_an_uninterrupted_one(poses, tmp_path, monkeypatch):
    """A kill after a validation is logged and before its checkpoint: the resumed run has
    the uninterrupted run's weights, bit for bit, and its log (no duplicate records)."""
    from rmpl.training import loop

    cfg = tiny_config(steps=8, val_every=2, model={"drop_path": 0.2})
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    train(cfg, whole, *poses)
    real = loop.save_checkpoint
    calls = []

    def killed_at_the_third(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:  # step 6 is in log.jsonl, its checkpoint is not written
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(loop, "save_checkpoint", killed_at_the_third)
    with pytest.raises(KeyboardInterrupt):
        train(cfg, cut, *poses)
    assert [r["step"] for r in read_log(cut)] == [2, 4, 6]
    monkeypatch.setattr(loop, "save_checkpoint", real)
    train(cfg, cut, *poses)
    assert [r["step"] for r in read_log(cut)] == [2, 4, 6, 8]
    assert _without_time(read_log(cut)) == _without_time(read_log(whole))
    a, b = _weights(whole), _weights(cut)
    assert all(torch.equal(a[k], b[k]) for k in a)
