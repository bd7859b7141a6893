"""Tests of rmpl.benchmarks.scene_eval (matching, "seen" and found rates) on fake scene arrays."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.benchmarks import scene_eval as se
from rmpl.errors import InputError
from rmpl.geometry.camera import look_at

# A standing figure in COCO-17 order (x left, z up), metres.
_FIGURE = np.array(
    [[0, 0.1, 1.6], [0.03, 0.08, 1.63], [-0.03, 0.08, 1.63], [0.08, 0, 1.6], [-0.08, 0, 1.6],
     [0.18, 0, 1.42], [-0.18, 0, 1.42], [0.22, 0, 1.12], [-0.22, 0, 1.12], [0.24, 0.05, 0.85],
     [-0.24, 0.05, 0.85], [0.1, 0, 0.92], [-0.1, 0, 0.92], [0.11, 0.02, 0.5],
     [-0.11, 0.02, 0.5], [0.12, -0.02, 0.08], [-0.12, -0.02, 0.08]]
)  # fmt: skip
_W, _H = 1000, 800


def _project(points: np.ndarray, K, R, t) -> np.ndarray:
    cam = points @ R.T + t
    uv = cam @ K.T
    return uv[..., :2] / uv[..., 2:]


def _scene(extra_slot: bool = True) -> dict[str, np.ndarray]:
    """One scene: 3 body slots (2 bodies), 4 views around them, 3 detector slots per view.

    Body 0 is detected exactly in every view (slot 0); body 1 only in view 0 (slot 1; so
    fewer than 2 views detect it, although every view shows it); with ``extra_slot`` views 0
    and 1 also detect (slot 2) a person where no body stands (a phantom seen twice).
    """
    gt = np.stack([_FIGURE + [-0.8, 0, 0], _FIGURE + [0.8, 0, 0], np.full((17, 3), np.nan)])
    phantom = _FIGURE + [0, 2.0, 0]
    V, N, P = 4, 3, 3
    ang = np.arange(V) * 2 * np.pi / V + 0.3
    eye = np.stack([5 * np.cos(ang), 5 * np.sin(ang), np.full(V, 1.5)], -1)
    R, t = look_at(eye, np.array([0.0, 0.0, 1.0]))
    K = np.broadcast_to(np.array([[900.0, 0, _W / 2], [0, 900, _H / 2], [0, 0, 1]]), (V, 3, 3))
    proj = np.stack([_project(gt, K[v], R[v], t[v]) for v in range(V)])  # (V, P, 17, 2)
    kp = np.full((V, N, 17, 2), np.nan)
    sc = np.zeros((V, N, 17))
    match = np.full((V, N), -1, np.int8)
    kp[:, 0], sc[:, 0], match[:, 0] = proj[:, 0], 0.9, 0
    kp[0, 1], sc[0, 1], match[0, 1] = proj[0, 1], 0.9, 1
    if extra_slot:
        for v in (0, 1):
            kp[v, 2], sc[v, 2] = _project(phantom, K[v], R[v], t[v]), 0.9
    d = {
        "joints3d": gt,
        "present": np.array([True, True, False]),
        "keypoints": kp,
        "scores": sc,
        "match": match,
        "projected": proj,
        "hidden": np.zeros((V, P, 17), bool),
        "K": np.array(K),
        "R": R,
        "t": t,
        "size": np.tile([_W, _H], (V, 1)),
    }
    return {k: np.asarray(v)[None] for k, v in d.items()}  # one scene


def test_person_errors_hungarian_and_gate():
    gt = np.stack([_FIGURE, _FIGURE + [2.0, 0, 0]])
    pred = np.stack([gt[1] + [0, 0, 0.03], gt[0] + [0.04, 0, 0], _FIGURE + [9.0, 0, 0]])
    idx, err = se.person_errors(pred, gt)
    assert idx.tolist() == [1, 0]
    np.testing.assert_allclose(err, [40.0, 30.0], atol=1e-6)
    far = np.stack([gt[0] + [0, 0, se.MISS_GATE + 0.05]])  # beyond the gate: a miss
    idx, err = se.person_errors(far, gt)
    assert idx.tolist() == [-1, -1] and np.isnan(err).all()


def test_seen_by_detector_and_projection():
    d = _scene()
    det = se.seen_by_detector(d["match"][0], 3)  # (V, P)
    assert det.sum(0).tolist() == [4, 1, 0]
    proj = se.seen_by_projection(d["projected"][0], d["hidden"][0], d["size"][0])
    assert proj.sum(0).tolist() == [4, 4, 0]
    hidden = d["hidden"][0].copy()
    hidden[2, 0, list(se.KP_STAR)[:7]] = True  # 5 KP* joints left shown: not seen
    proj = se.seen_by_projection(d["projected"][0], hidden, d["size"][0])
    assert proj.sum(0).tolist() == [3, 4, 0]


def test_score_subset_found_and_spurious():
    d = _scene()
    methods = se.make_methods(["triangulate", "triangulate:given"], "default")
    people, spurious = se.score_subset(d, 0, (0, 1, 2, 3), methods)
    by = {(p.method, p.body): p for p in people}
    assert len(people) == 4  # 2 bodies x 2 methods; the empty slot is no body
    p0, p1 = by["triangulate", 0], by["triangulate", 1]
    assert (p0.seen_det, p0.seen_proj, p0.found) == (4, 4, True)
    assert p0.mpjpe < 1.0  # exact 2D: triangulation is exact
    assert (p1.seen_det, p1.seen_proj, p1.found) == (1, 4, False)  # one view: no association
    assert spurious == {"triangulate": 1}  # the phantom seen in 2 views
    assert by["triangulate:given", 0].found and not by["triangulate:given", 1].found
    s = se.summarize(people, "triangulate")
    assert (s["n_seen_det"], s["found_seen_det"]) == (1, 100.0)  # body 1 is not counted
    assert (s["n_seen_proj"], s["found_seen_proj"]) == (2, 50.0)  # but it is shown


def test_evaluate_set_counts_subsets():
    d = _scene(extra_slot=False)
    people, spurious, pairs = se.evaluate_set(d, 3, se.make_methods(["triangulate"], "default"))
    assert pairs == 4 and len(people) == 8 and spurious == {"triangulate": 0}
    # body 0 is found by every 3-view subset; body 1 by none (one view detects it)
    assert [p.found for p in people if p.body == 0] == [True] * 4
    assert not any(p.found for p in people if p.body == 1)
    with pytest.raises(InputError):
        se.evaluate_set(d, 5, {})


def test_load_one_body_set_as_scenes(tmp_path):
    d = _scene(extra_slot=False)
    J26 = np.concatenate  # the set may carry 26 joints: only the first 17 are read
    shard = {
        "joints3d": J26([d["joints3d"][:, 0], np.zeros((1, 9, 3))], 1),  # (M, 26, 3)
        "keypoints": J26([d["keypoints"][:, :, 0], np.zeros((1, 4, 9, 2))], 2),
        "scores": J26([d["scores"][:, :, 0], np.ones((1, 4, 9))], 2),
        "projected": J26([d["projected"][:, :, 0], np.zeros((1, 4, 9, 2))], 2),
        **{k: d[k] for k in se.CAMERA_KEYS},
    }
    shard["scores"][0, 3, :17] = 0  # view 3 missed the body
    shard["keypoints"][0, 3, :17] = np.nan
    np.savez(tmp_path / "shard_00000.npz", **shard)
    out = se.load_scenes(tmp_path)
    assert out["joints3d"].shape == (1, 1, 17, 3) and out["keypoints"].shape == (1, 4, 1, 17, 2)
    assert out["match"][0, :, 0].tolist() == [0, 0, 0, -1]
    assert out["present"].all() and not out["hidden"].any()


def test_load_refuses_an_empty_folder(tmp_path):
    with pytest.raises(InputError, match="shard"):
        se.load_scenes(tmp_path)
