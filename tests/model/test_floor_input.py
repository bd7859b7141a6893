"""The floor as a model input (issue 16): given, absent, estimated and bad floors, the
single-view anchor it moves, fine-tuning from a model without it, and ONNX."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.geometry.floor import Floor, fit_floor
from rmpl.geometry.rays import rays_from_keypoints
from rmpl.inference import Lifter, checkpoint_reads_floor
from rmpl.model.lifter import RMPL, RMPLConfig, anchors_from_rays, floor_parts
from rmpl.training.loop import init_from_checkpoint, save_checkpoint

EXAMPLE = Path(__file__).parents[2] / "src/rmpl/examples/walk/ground_truth.npz"
TINY = dict(dim=32, depth_view=1, depth_pose=1, heads=2)
K = np.array([[1000.0, 0, 960], [0, 1000, 540], [0, 0, 1]])


@pytest.fixture(scope="module")
def walk():
    """Real walking poses (T, 17, 3), metres, z up, standing on z ~ 0."""
    return np.load(EXAMPLE)["points"][:, 0].astype(float)


def _camera(eye, target, name: str = "cam") -> Camera:
    R, t = look_at(np.asarray(eye, float), np.asarray(target, float))
    return Camera(K, R, t, size=(1920, 1080), name=name)


def _rays(poses, cams):
    """(T, V, J, 6) rays and (T, V, J) scores of poses seen exactly by cams."""
    rig = Rig(tuple(cams))
    kp = np.stack([rig[v].project(poses.reshape(-1, 3)).reshape(*poses.shape[:-1], 2)
                   for v in range(len(rig))], 1)  # fmt: skip
    return rays_from_keypoints(kp, rig).astype(np.float32), np.ones(kp.shape[:-1], np.float32), kp


def _random_weights(model: torch.nn.Module, seed: int = 0) -> torch.nn.Module:
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in model.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.05)
    return model.eval()


def test_floor_needs_the_geometric_transformer():
    with pytest.raises(ValueError, match="floor"):
        RMPLConfig(floor=True, geometric=False, recenter=True)
    RMPLConfig(floor=True)  # the default geometry takes it


def test_floor_parts_unknown_rows_and_shape():
    like = torch.zeros(1)
    f = floor_parts(torch.tensor([[0.0, 0, 2, 0.1], [np.nan, 0, 1, 0]]), 2, like)
    assert f.known.tolist() == [True, False]
    assert torch.allclose(f.n[0], torch.tensor([0.0, 0, 1]))  # normalised
    assert f.h[0].item() == pytest.approx(0.1)
    assert not floor_parts(None, 3, like).known.any()
    with pytest.raises(ValueError, match="shape"):
        floor_parts(torch.zeros(2, 3), 2, like)


def test_the_floor_fixes_a_single_view_anchor_that_body_size_cannot(walk):
    """A tall person (x1.25) seen from 2.5 m: the angular-size anchor puts them too near;
    with the floor, the anchor's depth is within a few percent."""
    # Each pose at the origin, scaled about its own spot on the floor.
    poses = (walk[::10] - walk[::10, 11:13].mean(1, keepdims=True) * np.array([1, 1, 0])) * 1.25
    cam = _camera([5.0, 0.0, 2.5], [0.0, 0.0, 1.0])
    rays, scores, _ = _rays(poses, [cam])
    rays, scores = torch.from_numpy(rays), torch.from_numpy(scores)
    root = poses[:, 11:13].mean(1)
    C = cam.center

    def depth_error(floor):
        P = anchors_from_rays(rays, scores, floor=floor)[2].numpy()
        return np.abs(np.log(np.linalg.norm(P - C, axis=-1) / np.linalg.norm(root - C, axis=-1)))

    given = floor_parts(torch.tensor([[0.0, 0, 1, 0]]).expand(len(poses), 4), len(poses), rays)
    without, with_floor = depth_error(None), depth_error(given)
    assert np.median(with_floor) < 0.06
    assert np.median(with_floor) < 0.5 * np.median(without)
    # An unknown floor is the anchor without one.
    unknown = floor_parts(torch.full((len(poses), 4), float("nan")), len(poses), rays)
    assert np.allclose(depth_error(unknown), without)


def test_fine_tuning_from_a_model_without_the_floor_starts_at_its_answers(walk, tmp_path):
    """New input columns start at zero: with several views the answers are the old model's
    whatever the floor; with one view and no floor too."""
    old = _random_weights(RMPL(RMPLConfig(**TINY)))
    save_checkpoint(old, tmp_path / "old", {"model": old.config.to_dict()})
    new = RMPL(RMPLConfig(**TINY, floor=True))
    init_from_checkpoint(new, tmp_path / "old")
    new.eval()
    cams = [_camera([4.0, 0, 2], [0, 0, 1], "a"), _camera([0, 4.0, 1.5], [0, 0, 1], "b")]
    rays, scores, _ = _rays(walk[:6], cams)
    rays, scores = torch.from_numpy(rays), torch.from_numpy(scores)
    floor = torch.tensor([[0.0, 0, 1, 0]]).expand(6, 4)
    with torch.no_grad():
        assert torch.allclose(new(rays, scores, floor=floor), old(rays, scores), atol=1e-5)
        one = rays[:, :1], scores[:, :1]
        assert torch.allclose(new(*one), old(*one), atol=1e-5)
        assert not torch.allclose(new(*one, floor=floor), old(*one), atol=1e-3)


@pytest.fixture(scope="module")
def floor_lifter(tmp_path_factory):
    model = _random_weights(RMPL(RMPLConfig(**TINY, floor=True)), seed=3)
    path = tmp_path_factory.mktemp("floor_model")
    save_checkpoint(model, path, {"model": model.config.to_dict()})
    return path


def test_lifter_given_absent_and_bad_floor(walk, floor_lifter):
    lifter = Lifter.from_pretrained(floor_lifter, backend="torch")
    assert lifter.reads_floor and checkpoint_reads_floor(floor_lifter)
    assert not checkpoint_reads_floor("default")
    cam = _camera([4.0, 0, 2.0], [0, 0, 1])
    rig = Rig((cam,))
    _, _, kp = _rays(walk[:5], [cam])
    sc = np.ones(kp.shape[:-1])
    given = lifter.lift(kp, sc, rig, floor=Floor((0.0, 0.0, 1.0), 0.0)).points
    absent = lifter.lift(kp, sc, rig, up=np.array([0.0, 0, 1])).points
    assert np.isfinite(given).all() and np.isfinite(absent).all()
    assert not np.allclose(given, absent)
    # The floor in another frame: the same plane written with a shifted origin moves the
    # answer with it.
    shifted = lifter.lift(kp, sc, rig, floor=Floor((0.0, 0.0, 1.0), 0.3)).points
    assert not np.allclose(shifted, given)
    with pytest.raises(InputError, match="floor"):
        lifter.lift(kp, sc, rig, floor=Floor((0.0, 0.0, 1.0), 5.0))  # above the camera
    with pytest.raises(InputError, match="floor"):
        lifter.lift(kp, sc, rig, floor=Floor((0.0, 0.0, 2.0), 0.0))  # not a unit normal
    with pytest.raises(InputError, match="floor"):
        lifter.lift(kp, sc, rig, floor=(0.0, 0.0, 1.0, 0.0))  # not a Floor


def test_an_estimated_floor_goes_in_like_a_given_one(walk, floor_lifter):
    """A floor fitted to multi-view poses (the lowest ankles) is a plane the lifter reads."""
    lifter = Lifter.from_pretrained(floor_lifter, backend="torch")
    lower = walk[np.arange(len(walk)), 15 + walk[:, 15:17, 2].argmin(1)]  # the lower ankle
    floor = fit_floor(lower, np.array([0.0, 0, 1]))
    assert abs(floor.height) < 0.1
    cam = _camera([4.0, 0, 2.0], [0, 0, 1])
    _, _, kp = _rays(walk[:3], [cam])
    out = lifter.lift(kp, np.ones(kp.shape[:-1]), Rig((cam,)), floor=floor).points
    assert np.isfinite(out).all()


def test_onnx_reads_the_floor_as_torch_does(walk, floor_lifter):
    pytest.importorskip("onnxruntime")
    torch_lifter = Lifter.from_pretrained(floor_lifter, backend="torch")
    onnx_lifter = Lifter.from_pretrained(floor_lifter, backend="onnx")
    cam = _camera([4.0, 0, 2.0], [0, 0, 1])
    _, _, kp = _rays(walk[:4], [cam])
    sc = np.ones(kp.shape[:-1])
    for floor in (Floor((0.0, 0.0, 1.0), 0.0), None):
        a = torch_lifter.lift(kp, sc, Rig((cam,)), floor=floor, up=np.array([0.0, 0, 1])).points
        b = onnx_lifter.lift(kp, sc, Rig((cam,)), floor=floor, up=np.array([0.0, 0, 1])).points
        assert np.allclose(a, b, atol=1e-4)
