"""The board bundle adjustment: its analytic Jacobian (poses, lenses with distortion, the
lens prior) against central differences, and the same solution as with SciPy's finite
differences."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.calibration import bundle as ba
from rmpl.calibration.bundle import Observations, _Problem, _solve, rodrigues_batch


def _mat(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _scene(rng, V=3, P=4, rotation=1.0):
    """Cameras turned by up to ``rotation`` radians around boards ~4 m in front of each."""
    Rc = rodrigues_batch(rng.normal(size=(V, 3)) * rotation)
    Rc[0] = np.eye(3)
    ahead = np.array([0.0, 0.0, 4.0])
    tc = ahead - Rc @ ahead + rng.normal(size=(V, 3)) * 0.05
    tc[0] = 0.0
    Rb = rodrigues_batch(rng.normal(size=(P, 3)))
    tb = ahead + rng.normal(size=(P, 3)) * 0.3
    grid = np.stack(np.meshgrid(np.arange(4) * 0.15, np.arange(3) * 0.15), -1).reshape(-1, 2)
    grid = np.c_[grid - grid.mean(0), np.zeros(len(grid))]
    K = [
        np.array([[f, 0, 320.0], [0, f * 1.01, 240.0], [0, 0, 1]]) for f in rng.uniform(500, 900, V)
    ]
    dist = [np.array([-0.25, 0.08, 1e-3, -2e-3, 0.02]) + rng.normal(size=5) * 0.01 for _ in K]
    cam, pose = np.meshgrid(np.arange(V), np.arange(P), indexing="ij")
    cam = np.repeat(cam.ravel(), len(grid))
    pose = np.repeat(pose.ravel(), len(grid))
    points = np.tile(grid, (V * P, 1))
    T_cw = [_mat(Rc[v], tc[v]) for v in range(V)]
    T_wb = [_mat(Rb[p], tb[p]) for p in range(P)]
    return Observations(cam, pose, points, np.zeros((len(cam), 2))), K, dist, T_cw, T_wb


def _numeric(fun, x, eps=1e-6):
    cols = []
    for k in range(len(x)):
        d = np.zeros_like(x)
        d[k] = eps
        cols.append((fun(x + d) - fun(x - d)) / (2 * eps))
    return np.stack(cols, 1)


@pytest.mark.parametrize(
    "free_lens,prior,ref,rotation",
    [(True, True, 0, 1.0), (True, False, 1, 2.5), (False, False, 0, 1e-6), (True, True, 2, 0.0)],
)
def test_jacobian_matches_central_differences(free_lens, prior, ref, rotation):
    rng = np.random.default_rng(ref + 3)
    obs, K, dist, T_cw, T_wb = _scene(rng, rotation=rotation)
    if ref != 0:  # the reference camera's pose is the frame: make it the identity
        T_ref = np.linalg.inv(T_cw[ref])
        T_cw = [T @ T_ref for T in T_cw]
        T_wb = [np.linalg.inv(T_ref) @ T for T in T_wb]
    lens = np.array(
        [[k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d] for k, d in zip(K, dist, strict=True)]
    )
    pri = (lens + rng.normal(size=lens.shape), np.abs(lens) * 0.01 + 0.01) if prior else None
    prob = _Problem(obs, len(K), len(T_wb), ref, free_lens, pri)
    x = prob.pack(K, dist, T_cw, T_wb)
    J = prob.jacobian(x, K, dist).toarray()
    N = _numeric(lambda y: prob.residuals(y, K, dist), x)
    assert J.shape == N.shape
    scale = np.abs(N).max(1, keepdims=True) + 1.0
    assert (np.abs(J - N) / scale).max() < 1e-6
    S = prob.sparsity()[0].toarray()
    assert not (J[S == 0] != 0).any()


def test_distort_jacobian_matches_central_differences():
    rng = np.random.default_rng(1)
    xy = rng.normal(size=(20, 2)) * 0.4
    d = rng.normal(size=(20, 5)) * 0.1
    dxy, ddist, xd = ba._distort_jacobian(xy, d)
    from rmpl.geometry.camera import distort

    assert np.allclose(xd, distort(xy, d))
    for k in range(2):
        e = np.zeros(2)
        e[k] = 1e-6
        num = (distort(xy + e, d) - distort(xy - e, d)) / 2e-6
        assert np.allclose(dxy[:, :, k], num, atol=1e-8)
    for k in range(5):
        e = np.zeros(5)
        e[k] = 1e-6
        num = (distort(xy, d + e) - distort(xy, d - e)) / 2e-6
        assert np.allclose(ddist[:, :, k], num, atol=1e-8)


def test_analytic_and_finite_difference_solutions_agree():
    rng = np.random.default_rng(8)
    obs, K, dist, T_cw, T_wb = _scene(rng, P=6, rotation=0.6)
    prob = _Problem(obs, len(K), len(T_wb), 0, True)
    truth = prob.pack(K, dist, T_cw, T_wb)
    obs.pixels = (
        prob.residuals(truth, K, dist).reshape(-1, 2) + rng.normal(size=(len(obs.cam), 2)) * 0.3
    )
    lens = np.array(
        [[k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d] for k, d in zip(K, dist, strict=True)]
    )
    std = np.tile([5.0, 5.0, 3.0, 3.0, 0.01, 0.01, 1e-3, 1e-3, 0.01], (len(K), 1))
    prob = _Problem(obs, len(K), len(T_wb), 0, True, (lens, std))
    x0 = truth + rng.normal(size=truth.shape) * 1e-3
    a = _solve(prob, x0, K, dist, analytic=True)
    f = _solve(prob, x0, K, dist, analytic=False)
    assert a.success and f.success
    assert abs(a.cost - f.cost) <= 1e-6 * f.cost
    assert np.abs(a.x - f.x).max() < 1e-4 * (np.abs(f.x).max())
    assert np.abs(a.fun - f.fun).max() < 1e-3  # pixels
