"""Multi-view runs give a lifter that reads the floor the user's floor or one estimated from
the run's own people (``run(floor=)``), say which (``run_with_floor``, the report), and
estimate nothing for a lifter that does not read it."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest
import torch

import rmpl
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.floor import Floor
from rmpl.inference import Lifter
from rmpl.inference_temporal import TemporalLifter
from rmpl.model.lifter import RMPL, RMPLConfig
from rmpl.model.temporal import TemporalConfig, TemporalRMPL
from rmpl.pipeline import runner
from rmpl.pipeline.inputs import Inputs
from rmpl.pipeline.report import build_report
from rmpl.pipeline.runner import RunConfig, run, run_with_floor
from rmpl.training.loop import save_checkpoint
from rmpl.training.temporal import save_temporal

WALK = Path(rmpl.__file__).parent / "examples" / "walk" / "ground_truth.npz"
FLOOR_Z = 0.3  # the scene's floor: z = 0.3 m, z up


def _scene(views: int = 4, seed: int = 0):
    """The example's walk (an anny body on z = 0) raised onto the floor z = FLOOR_Z, seen
    by ``views`` cameras around it, 1 px of detector noise: (rig, keypoints (T, V, 1, J, 2),
    scores)."""
    rng = np.random.default_rng(seed)
    X = np.load(WALK)["points"][:, 0].astype(float) + [0.0, 0.0, FLOOR_Z]  # (T, 17, 3)
    centre = np.nanmean(X, (0, 1)) * [1, 1, 0] + [0, 0, FLOOR_Z + 1.0]
    K = np.array([[1000.0, 0, 640], [0, 1000, 480], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views + 0.4
        eye = centre + [5 * np.cos(a), 5 * np.sin(a), 1.5]
        R, t = look_at(eye, centre)
        cams.append(Camera(K, R, t, size=(1280, 960), name=f"c{v}"))
    rig = Rig(tuple(cams))
    kp = rig.project(X)[:, :, None] + rng.normal(0, 1.0, (len(X), views, 1, 17, 2))
    return rig, kp, np.full(kp.shape[:-1], 0.9)


def _random_weights(model: torch.nn.Module, seed: int = 0) -> None:
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in model.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.05)


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> dict[str, str]:
    """Tiny per-frame checkpoints with and without the floor input, and a temporal one on a
    floor-reading frame model."""
    root = tmp_path_factory.mktemp("models")
    out = {}
    for name, floor in (("floor", True), ("plain", False)):
        m = RMPL(RMPLConfig(dim=32, depth_view=1, depth_pose=1, heads=2, floor=floor))
        _random_weights(m)
        save_checkpoint(m, root / name, {"model": m.config.to_dict()})
        out[name] = str(root / name)
    torch.manual_seed(0)
    frame = RMPL(RMPLConfig(dim=32, depth_view=1, depth_pose=1, heads=2, floor=True))
    _random_weights(frame)
    save_temporal(TemporalRMPL(frame, TemporalConfig(dim=16, depth=1, window=8)), root / "temp")
    out["temporal"] = str(root / "temp")
    return out


@pytest.fixture()
def lift_floors(monkeypatch) -> list:
    """The ``floor`` of every per-frame ``Lifter.lift`` call."""
    seen = []
    real = Lifter.lift

    def spy(self, *args, **kwargs):
        seen.append(kwargs.get("floor"))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Lifter, "lift", spy)
    return seen


def test_estimate_finds_the_floor_and_the_lifter_reads_it(models, lift_floors, caplog):
    rig, kp, sc = _scene()
    cfg = RunConfig(model=models["floor"])
    with caplog.at_level(logging.INFO, logger="rmpl.pipeline.runner"):
        poses, floor = run_with_floor(kp, sc, rig, config=cfg, progress=False)
    assert floor is not None
    assert floor.height == pytest.approx(FLOOR_Z, abs=0.1)  # the ankle sits ~4 cm higher
    assert np.degrees(np.arccos(floor.n @ [0, 0, 1])) < 3
    assert "triangulated from the run's 4 cameras" in floor.source
    assert lift_floors and all(f is floor for f in lift_floors)
    assert "floor given to the lifter" in caplog.text and floor.describe() in caplog.text
    lift_floors.clear()
    again = run(kp, sc, rig, config=cfg, progress=False, floor=floor)  # the same, given
    assert all(f is floor for f in lift_floors)
    np.testing.assert_allclose(again.points, poses.points)
    none = run(kp, sc, rig, config=cfg, progress=False, floor=None)
    assert np.abs(none.points - poses.points)[np.isfinite(none.points)].max() > 1e-3


def test_floor_none_gives_the_lifter_no_floor(models, lift_floors, monkeypatch):
    called = []
    monkeypatch.setattr(runner, "estimate_floor", lambda *a, **k: called.append(1))
    rig, kp, sc = _scene()
    poses, floor = run_with_floor(
        kp, sc, rig, config=RunConfig(model=models["floor"]), progress=False, floor=None
    )
    assert floor is None and not called
    assert lift_floors and all(f is None for f in lift_floors)
    assert np.isfinite(poses.points).any()


def test_a_floor_above_the_cameras_is_refused_naming_the_floor(models, lift_floors):
    rig, kp, sc = _scene()
    high = Floor((0.0, 0.0, 1.0), 10.0, "mine")
    with pytest.raises(InputError) as e:
        run(kp, sc, rig, config=RunConfig(model=models["floor"]), progress=False, floor=high)
    assert e.value.field == "floor" and "10.000 m (mine)" in str(e.value)
    with pytest.raises(InputError, match="'estimate' or None"):
        run(kp, sc, rig, config=RunConfig(model=models["floor"]), progress=False, floor="z=0")
    assert not lift_floors  # refused before any lifting


@pytest.mark.parametrize("method", ["rmpl", "triangulate"])
def test_no_estimate_for_a_lifter_that_does_not_read_the_floor(
    models, lift_floors, monkeypatch, method
):
    called = []
    monkeypatch.setattr(runner, "estimate_floor", lambda *a, **k: called.append(1))
    rig, kp, sc = _scene()
    cfg = RunConfig(method=method, model=models["plain"])
    for given in ("estimate", Floor((0.0, 0.0, 1.0), FLOOR_Z)):
        poses, floor = run_with_floor(kp, sc, rig, config=cfg, progress=False, floor=given)
        assert floor is None and np.isfinite(poses.points).any()
    assert not called
    assert all(f is None for f in lift_floors)  # empty for triangulation


def test_whole_tracks_get_the_estimated_floor(models, monkeypatch):
    seen = []
    real = TemporalLifter.lift_track

    def spy(self, *args, **kwargs):
        seen.append(kwargs.get("floor"))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(TemporalLifter, "lift_track", spy)
    rig, kp, sc = _scene()
    cfg = RunConfig(model=models["temporal"])
    poses, floor = run_with_floor(kp, sc, rig, fps=30.0, config=cfg, progress=False)
    assert floor is not None and floor.height == pytest.approx(FLOOR_Z, abs=0.1)
    assert seen and all(f is floor for f in seen)
    assert poses.uncertainty is not None
    seen.clear()
    assert run_with_floor(kp, sc, rig, fps=30.0, config=cfg, progress=False, floor=None)[1] is None
    assert seen and all(f is None for f in seen)


def test_too_few_poses_go_on_without_a_floor(models, lift_floors, caplog):
    rig, kp, sc = _scene()
    with caplog.at_level(logging.INFO, logger="rmpl.pipeline.runner"):
        _, floor = run_with_floor(
            kp[:5], sc[:5], rig, config=RunConfig(model=models["floor"]), progress=False
        )
    assert floor is None and all(f is None for f in lift_floors)
    assert "floor: not estimated" in caplog.text


def test_a_joint_set_without_coco17_first_is_one_clear_error(models):
    # The floor is estimated before the lifter reads the joint set: 14-joint 2D must not
    # fail inside the estimate (a reshape), but as the lifter's one InputError.
    rig, kp, sc = _scene()
    with pytest.raises(InputError, match="coco17 or halpe26"):
        run_with_floor(kp[..., :14, :], sc[..., :14], rig, joints="shelf14",
                       config=RunConfig(model=models["floor"]), progress=False)  # fmt: skip


def test_the_report_names_the_floor(models):
    rig, kp, sc = _scene()
    poses, floor = run_with_floor(kp, sc, rig, config=RunConfig(model=models["floor"]),
                                  progress=False)  # fmt: skip
    inputs = Inputs(rig, kp, sc, np.arange(len(kp)), None)
    r = build_report(poses, inputs, floor=floor)
    entry = json.loads(json.dumps(r.to_json(), allow_nan=False))["floor"]
    assert entry["given"] is True and entry["description"] == floor.describe()
    assert entry["height_m"] == pytest.approx(floor.height, abs=1e-6)
    assert entry["spread_m"] is not None and "triangulated" in entry["source"]
    assert f"Floor: {floor.describe()}." in r.to_markdown()
    none = build_report(poses, inputs, floor=None)
    assert none.to_json()["floor"] == {"given": False, "description": "none"}
    assert "Floor: none." in none.to_markdown()
    unsaid = build_report(poses, inputs)
    assert unsaid.to_json()["floor"] is None and "Floor given" not in unsaid.to_markdown()
