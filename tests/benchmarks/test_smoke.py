"""Each benchmark on tiny inputs made here (seconds): it runs to the end and prints its table.

The figures are not checked: these are smoke tests of the protocols, whose own logic has
its unit tests (test_foot_eval, test_scene_eval) or lives in the package's tested modules.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from rmpl.benchmarks import run
from rmpl.skeleton import HALPE26
from rmpl.synth.motion.bank import PoseSet, save_pose_set
from tests.data.test_mhp_sequences import _fake_sequences
from tests.data.test_sequences import _bank

WEIGHTS = Path(__file__).resolve().parents[2] / "src" / "rmpl" / "weights"


def _log(run_dir: Path, records: list[dict], config: dict | None = None) -> Path:
    run_dir.mkdir(parents=True)
    (run_dir / "log.jsonl").write_text("\n".join(json.dumps(r) for r in records) + "\n")
    (run_dir / "config.json").write_text(json.dumps(config or {}))
    return run_dir


def test_runs_table(tmp_path, capsys):
    rec = {"step": 600, "seconds": 180.0, "kpstar_2v": 167.4, "triangulation_kpstar_2v": 165.2}
    a = _log(tmp_path / "base", [{"step": 200, "seconds": 60.0}, rec])
    b = _log(tmp_path / "maxv2", [dict(rec, kpstar_2v=159.0)], {"training": {"parameters": 8e5}})
    assert run("runs_table", [str(a), str(b), "--views", "2"]) == 0
    out = capsys.readouterr().out
    assert "| base | 0.00M | 600 | 3.0 | 167.4 |" in out and "| maxv2 | 0.80M" in out
    assert "| DLT (triangulable joints only) | | | | 165.2 |" in out


def test_runs_table_refuses_an_empty_log(tmp_path, capsys):
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "log.jsonl").write_text("")
    with pytest.raises(ValueError, match="log.jsonl"):
        run("runs_table", [str(tmp_path / "r")])


def test_temporal_table(tmp_path, capsys):
    rec = {"step": 1200, "seconds": 960.0, **{f"kpstar_{v}v": 50.0 + v for v in (2, 3, 5)}}
    _log(tmp_path / "B_fused", [rec])
    assert run("temporal_table", [str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| B_fused | 1200 | 16 |" in out and "| per-frame model alone |" in out


@pytest.fixture(scope="module")
def sequences(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("mhp_seq")
    _fake_sequences(root, shards=1)
    return root


@pytest.fixture(scope="module")
def seqbank(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("bank") / "seqbank.npz"
    _bank().save(path)
    return path


def test_temporal_mhp(sequences, loaded_once, tmp_path, capsys):
    argv = [str(sequences), "--views", "2", "--subsets", "1", "--csv", str(tmp_path / "r.csv")]
    assert run("temporal_mhp", argv) == 0
    out = capsys.readouterr().out
    assert "rmpl:temporal" in out and "triangulate+filter" in out
    assert (tmp_path / "r.csv").read_text().count("\n") > 1


@pytest.fixture
def loaded_once(monkeypatch):
    """Each per-frame model loaded once, in torch (the protocols load one per track; the
    ONNX export it would redo costs seconds each time)."""
    from rmpl.inference import Lifter
    from rmpl.inference_temporal import TemporalLifter

    original, cache = Lifter.from_pretrained.__func__, {}

    def cached(cls, name_or_path="default", backend="auto"):
        key = str(name_or_path)
        if key not in cache:
            cache[key] = original(cls, name_or_path, "torch")
        return cache[key]

    monkeypatch.setattr(Lifter, "from_pretrained", classmethod(cached))
    temporal, loaded = TemporalLifter.from_pretrained.__func__, {}

    def cached_temporal(cls, name_or_path="temporal"):
        key = str(name_or_path)
        if key not in loaded:
            loaded[key] = temporal(cls, name_or_path)
        return loaded[key]

    monkeypatch.setattr(TemporalLifter, "from_pretrained", classmethod(cached_temporal))


def test_monocular_mhp(sequences, loaded_once, capsys):
    assert run("monocular_mhp", [str(sequences)]) == 0
    assert "MPJPE" in capsys.readouterr().out


def test_temporal_synthetic(seqbank, capsys):
    argv = [str(seqbank), str(WEIGHTS / "temporal"), "--windows", "2", "--views", "2"]
    assert run("temporal_synthetic", argv) == 0
    assert capsys.readouterr().out


def test_temporal_assemble(seqbank, capsys):
    assert run("temporal_assemble", [str(seqbank), "--windows", "2"]) == 0
    assert "| H2 |" in capsys.readouterr().out.replace("**", "")


def test_temporal_calibrate_writes_the_radii(seqbank, tmp_path, capsys):
    model = shutil.copytree(WEIGHTS / "temporal", tmp_path / "temporal")
    before = json.loads((model / "config.json").read_text())["calibration"]
    assert run("temporal_calibrate", [str(seqbank), str(model), "--windows", "2"]) == 0
    after = json.loads((model / "config.json").read_text())["calibration"]
    assert after != before


def test_monocular_synthetic(seqbank, capsys):
    assert run("monocular_synthetic", [str(seqbank), "--windows", "2", "--cues", "floor"]) == 0
    assert "floor" in capsys.readouterr().out


def test_halpe26_stats(tmp_path, capsys):
    rng = np.random.default_rng(0)
    poses = rng.normal([0, 0, 1.0], 0.3, (8, HALPE26.num_joints, 3)).astype(np.float32)
    names = np.array(["01"] * 8)
    bank = save_pose_set(tmp_path / "b.npz", PoseSet(poses, names, names, np.arange(8)))
    assert run("halpe26_stats", [str(bank)]) == 0
    assert "8 poses" in capsys.readouterr().out


def test_duplicate_sweep(tmp_path, capsys):
    from tests.benchmarks.test_scene_eval import _scene

    d = _scene(extra_slot=False)
    pad = np.concatenate  # a one-body set in the generator's shard format
    shard = {
        "joints3d": pad([d["joints3d"][:, 0], np.zeros((1, 9, 3))], 1),
        "keypoints": pad([d["keypoints"][:, :, 0], np.zeros((1, 4, 9, 2))], 2),
        "scores": pad([d["scores"][:, :, 0], np.ones((1, 4, 9))], 2),
        "projected": pad([d["projected"][:, :, 0], np.zeros((1, 4, 9, 2))], 2),
        **{k: d[k] for k in ("K", "R", "t", "size")},
    }
    np.savez(tmp_path / "shard_00000.npz", **shard)
    assert run("duplicate_sweep", [str(tmp_path), "3"]) == 0
    out = capsys.readouterr().out
    assert "| off | 100.00% of 4 |" in out and "| 0.5 |" in out


def test_bench_detect_tracks(tmp_path, capsys):
    from rmpl.cli import main
    from tests.cli.test_commands import make_scene

    make_scene(tmp_path, frames=8)
    out = tmp_path / "trial"
    argv = [
        "run",
        "--calib",
        str(tmp_path / "calib.toml"),
        "--keypoints",
        str(tmp_path / "kp.json"),
    ]
    assert main([*argv, "--method", "triangulate", "--no-pictures", "--out", str(out)]) == 0
    assert run("bench_detect", ["tracks", str(out)]) == 0
    assert '"frames_with_3plus_views": 8' in capsys.readouterr().out


def test_temporal_oracle(shared_data, capsys):
    root = shared_data / "fixtures" / "shelf"
    assert run("temporal_oracle", [str(root), "--views", "2"]) == 0
    assert capsys.readouterr().out


def _pose_bank(path: Path, n: int = 16) -> Path:
    """A COCO-17 pose bank of the held-out subject 03 (the selection rules' parametric set)."""
    from tests.data.test_sequences import _bank

    poses = _bank(segments=1, frames=n).poses  # a standing, walking figure
    names = np.array(["03"] * n)
    return save_pose_set(path, PoseSet(poses, names, names, np.arange(n)))


def test_halpe26_select(tmp_path, loaded_once, capsys):
    bank = _pose_bank(tmp_path / "bank.npz")
    assert run("halpe26_select", [str(bank), "halpe26", "--base", "default", "--samples", "8"]) == 0
    assert "parametric" in capsys.readouterr().out


def test_floor_select(tmp_path, loaded_once, capsys):
    from tests.data.test_mhp import _fake_mhp

    _fake_mhp(tmp_path / "renders", meshes=1, views=2, shards=1)
    _fake_sequences(tmp_path / "sequences", shards=1, views=2)
    bank = _pose_bank(tmp_path / "bank.npz")
    argv = ["floor26", "--renders", str(tmp_path / "renders"), "--sequences"]
    argv.append(str(tmp_path / "sequences"))
    assert run("floor_select", [*argv, "--bank", str(bank), "--samples", "8"]) in (0, 1)
    out = capsys.readouterr().out
    assert "(1) one camera" in out and "(2) two to five views" in out


def test_opensim_ik_names_its_venv_when_absent(tmp_path, capsys):
    argv = ["--poses", f"rmpl={tmp_path / 'poses.npz'}", "--out", str(tmp_path / "ik")]
    with pytest.raises(SystemExit) as e:
        run("opensim_ik", [*argv, "--opensim-venv", str(tmp_path / "none")])
    assert e.value.code == 2 and "setup_opensim.sh" in capsys.readouterr().err


def test_opensim_ik_on_a_tiny_run(tmp_path, capsys):
    venv = Path(__file__).resolve().parents[2] / ".venv-opensim"
    if not (venv / "bin" / "python").exists():
        pytest.skip(f"no OpenSim venv at {venv} (run scripts/setup_opensim.sh)")
    from rmpl.cli import main
    from tests.cli.test_commands import make_scene

    make_scene(tmp_path, frames=12)
    inputs = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    out = tmp_path / "trial"
    assert (
        main(["run", *inputs, "--method", "triangulate", "--no-pictures", "--out", str(out)]) == 0
    )
    argv = ["--poses", f"tri={out / 'poses.npz'}", "--out", str(tmp_path / "ik"), "--height", "1.7"]
    assert run("opensim_ik", [*argv, "--markerset", "fixed"]) == 0
    assert (tmp_path / "ik" / "results.json").exists()


def test_make_example_with_the_noise_model(shared_data, tmp_path):
    from rmpl.io.keypoints import load_keypoints

    argv = ["--poses", str(shared_data / "cmu_mocap"), "--out", str(tmp_path / "walk")]
    assert run("make_example", [*argv, "--frames", "6", "--detector", "parametric"]) == 0
    files = sorted(p.name for p in (tmp_path / "walk").iterdir())
    assert files == ["calibration.toml", "ground_truth.npz", "keypoints.json"]
    kp = load_keypoints(tmp_path / "walk" / "keypoints.json")
    assert kp.keypoints.shape[:2] == (6, 4)  # 6 frames, 4 cameras
