"""The bundle adjustment of calibration from people: its analytic Jacobian against central
differences at random points (small, large and zero rotations), the same solution as with
SciPy's finite differences on a synthetic rig, and the per-track outlier rule."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.calibration import people_bundle as pb
from rmpl.geometry.camera import look_at, rodrigues, rotation_to_rodrigues


def _numeric(fun, x, eps=1e-6):
    """Central differences of ``fun`` at ``x``, dense (rows, len(x))."""
    cols = []
    for k in range(len(x)):
        d = np.zeros_like(x)
        d[k] = eps
        cols.append((fun(x + d) - fun(x - d)) / (2 * eps))
    return np.stack(cols, 1)


def _random_problem(rng, rvecs, num_points=12, obs_per_point=3):
    """A problem of len(rvecs) cameras at the given rotation vectors, looking at points
    about 4 m in front of each, with two people's bones; x at a random point."""
    V = len(rvecs)
    R = rodrigues(np.asarray(rvecs, float))
    X = rng.normal(size=(num_points, 3)) * 0.5
    # each camera placed so the cloud is ~4 m in front of it: t = -R c, c = -4 R^T e_z
    t = np.array([[0.0, 0.0, 4.0]] * V) + rng.normal(size=(V, 3)) * 0.1
    cam = np.concatenate([rng.choice(V, obs_per_point, replace=False) for _ in X])
    point = np.repeat(np.arange(num_points), obs_per_point)
    xy = rng.normal(size=(len(cam), 2)) * 0.1
    focal = rng.uniform(500, 1500, V)
    bones = np.array([[0, 1], [1, 2], [3, 4], [4, 5], [6, 7]])
    bone_length = np.array([0, 1, 2, 3, 0])
    prob = pb.BundleProblem(cam, point, xy, focal, bones, bone_length)
    lengths = rng.uniform(0.2, 0.5, 4)
    return prob, R, t, X, lengths


@pytest.mark.parametrize(
    "rvecs",
    [
        [[0.0, 0.0, 0.0], [1e-9, -2e-9, 0.0], [2e-4, 1e-4, -3e-4], [0.0, 0.0, 0.0]],
        [[0.3, -0.2, 0.1], [1.2, 0.4, -0.9], [0.0, 3.0, 0.5], [2.0, -2.0, 1.0]],
    ],
    ids=["small", "large"],
)
@pytest.mark.parametrize("fixed", [0, 2])
@pytest.mark.parametrize("bones", ["metres", "relative"])
def test_jacobian_matches_central_differences(rvecs, fixed, bones, monkeypatch):
    monkeypatch.setattr(pb, "BONE_TERM", bones)
    rng = np.random.default_rng(11 + fixed)
    prob, R, t, X, lengths = _random_problem(rng, rvecs)
    V = len(R)
    free = [v for v in range(V) if v != fixed]
    gauge_cam = (fixed + 1) % V
    d0 = 1.7  # the gauge's start distance: any value, the derivative does not see it
    mask = np.ones(len(prob.cam), bool)
    args = (prob, mask, V, free, (R[fixed], t[fixed]), 4, (fixed, gauge_cam, d0))
    rv = np.asarray(rvecs, float)[free]
    x = np.concatenate([np.c_[rv, t[free]].ravel(), lengths, X.ravel()])
    J = pb._jacobian(x, *args).toarray()
    N = _numeric(lambda y: pb._residuals(y, *args), x)
    assert J.shape == N.shape
    scale = np.abs(N).max(1, keepdims=True) + 1.0
    assert np.abs(J - N).max() / scale.max() < 1e-6
    assert (np.abs(J - N) / scale).max() < 1e-6
    S = pb._sparsity(*args[:4], 4, len(X)).toarray()
    assert not (J[S == 0] != 0).any()  # inside the pattern the finite differences used


def test_jacobian_with_a_mask_and_a_free_gauge_pair():
    rng = np.random.default_rng(5)
    prob, R, t, X, lengths = _random_problem(rng, [[0.1, 0.2, 0.3], [2.5, 0.1, -0.4], [-1, 1, 1]])
    V = len(R)
    mask = rng.random(len(prob.cam)) > 0.3
    free = [1, 2]  # camera 0 fixed, the gauge between two free cameras
    args = (prob, mask, V, free, (R[0], t[0]), 4, (1, 2, 0.5))
    x = np.concatenate([np.c_[rotation_to_rodrigues(R[free]), t[free]].ravel(), lengths, X.ravel()])
    J = pb._jacobian(x, *args).toarray()
    N = _numeric(lambda y: pb._residuals(y, *args), x)
    assert np.allclose(J, N, atol=1e-6 * (np.abs(N).max() + 1))


def test_left_jacobian_is_the_derivative_of_rodrigues():
    rng = np.random.default_rng(3)
    for r in [np.zeros(3), rng.normal(size=3) * 1e-5, rng.normal(size=3), [0, 0, np.pi - 1e-3]]:
        r = np.asarray(r, float)
        Jl = pb._left_jacobian(r)
        for k in range(3):
            d = np.zeros(3)
            d[k] = 1e-6
            dR = (rodrigues(r + d) - rodrigues(r - d)) / 2e-6 @ rodrigues(r).T  # [J e_k]_x
            w = np.array([dR[2, 1], dR[0, 2], dR[1, 0]])
            assert np.allclose(w, Jl[:, k], atol=1e-7)


def _synthetic_problem(seed=4, frames=8, views=4):
    """Points of people seen by a ring of cameras, the start cameras perturbed."""
    from rmpl.calibration.people_synth import moving_people

    rng = np.random.default_rng(seed)
    P = moving_people(np.arange(frames) / 10, (1.75, 1.6), rng=seed)  # (T, G, 17, 3)
    T, G, J, _ = P.shape
    ang = 2 * np.pi * np.arange(views) / views
    eye = np.c_[4 * np.cos(ang), 4 * np.sin(ang), np.full(views, 2.0)]
    R, t = look_at(eye, np.zeros((views, 3)) + [0, 0, 1.0])
    X = P.reshape(-1, 3)
    Xc = np.einsum("vij,nj->vni", R, X) + t[:, None]
    xy = Xc[..., :2] / Xc[..., 2:] + rng.normal(size=(views, len(X), 2)) * 1.5 / 800
    cam, point = np.nonzero(rng.random((views, len(X))) > 0.2)
    bones, blen = [], []
    for k, (a, b) in enumerate(pb.BONES):
        idx = np.arange(T * G) * J
        bones.append(np.c_[idx + a, idx + b])
        blen.append(np.tile(np.arange(G) * len(pb.BONES), T) + k)
    prob = pb.BundleProblem(cam, point, xy[cam, point], np.full(views, 800.0),
                            np.concatenate(bones), np.concatenate(blen))  # fmt: skip
    prob.member = cam * 1000 + point // J  # a 2D track per camera and person-frame
    R0 = np.einsum("vij,vjk->vik", rodrigues(rng.normal(size=(views, 3)) * 0.02), R)
    t0 = t + rng.normal(size=t.shape) * 0.05
    X0 = X + rng.normal(size=X.shape) * 0.03
    a, b = np.array(pb.BONES).T
    d = np.linalg.norm(P[:, :, a] - P[:, :, b], axis=-1)
    L0 = d.mean(0).ravel() * 1.05
    return prob, R0, t0, X0, L0


def test_analytic_and_finite_difference_solutions_agree():
    """The same problem solved: the two solutions differ by far less than their own
    uncertainty (the solver stops a little earlier or later on either path)."""
    prob, R0, t0, X0, L0 = _synthetic_problem()
    args = (prob, R0, t0, X0, L0, (0, 1), pb.ROUNDS, 60)
    a = pb._adjust(*args, True)
    f = pb._adjust(*args, False)
    assert (a.kept == f.kept).all()
    cov_a, cov_f = pb.centre_covariance(a, len(L0)), pb.centre_covariance(f, len(L0))
    assert np.allclose(cov_a, cov_f, rtol=1e-3, atol=1e-3 * np.abs(cov_f).max())
    sd = np.sqrt(np.linalg.eigvalsh(cov_f[1:]).min(-1))  # metres, each free centre
    C = lambda r: -np.einsum("vji,vj->vi", r.R, r.t)  # noqa: E731
    assert (np.linalg.norm(C(a) - C(f), axis=-1)[1:] < 0.05 * sd).all()
    cos = (np.einsum("vij,vij->v", a.R, f.R) - 1) / 2
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3
    assert np.abs(a.errors - f.errors).max() < 0.01  # pixels
    assert abs(a.sigma - f.sigma) < 1e-5 * f.sigma


def test_adjust_recovers_the_rig():
    prob, R0, t0, X0, L0 = _synthetic_problem(seed=6)
    res = pb.adjust(prob, R0, t0, X0, L0, fixed=0, gauge_cam=1)
    assert np.median(res.errors[res.kept]) < 3.0
    assert res.kept.mean() > 0.95
    assert res.jac.shape[0] == 2 * int(res.kept.sum()) + len(prob.bones) + 1


def test_bad_members_takes_each_tracks_median():
    prob = pb.BundleProblem(*(np.zeros(7, int),) * 2, np.zeros((7, 2)), np.ones(1),
                            np.zeros((0, 2), int), np.zeros(0, int))  # fmt: skip
    prob.member = np.array([5, 5, 5, 9, 9, 2, 2])
    errors = np.array([1.0, 50.0, 2.0, 4.0, 8.0, 30.0, 1.0])
    # medians: track 5 -> 2, track 9 -> 6, track 2 -> 15.5
    bad = pb._bad_members(prob, errors, 5.0)
    assert bad.tolist() == [False] * 3 + [True] * 4
    assert not pb._bad_members(prob, errors, 20.0).any()


def test_one_blas_thread_limits_blas_inside_only():
    threadpoolctl = pytest.importorskip("threadpoolctl")

    def blas_threads():
        info = threadpoolctl.threadpool_info()
        return [i["num_threads"] for i in info if i["user_api"] == "blas"]

    before = blas_threads()
    with pb.one_blas_thread():
        assert all(n == 1 for n in blas_threads())
    assert blas_threads() == before


def test_the_relative_bone_term_does_not_change_with_the_scale(monkeypatch):
    d, L = np.array([0.30, 0.42, 0.25]), np.array([0.31, 0.40, 0.25])
    monkeypatch.setattr(pb, "BONE_TERM", "relative")
    assert np.allclose(pb._bone_terms(3 * d, 3 * L)[0], pb._bone_terms(d, L)[0])
    monkeypatch.setattr(pb, "BONE_TERM", "metres")
    assert np.allclose(pb._bone_terms(3 * d, 3 * L)[0], 3 * pb._bone_terms(d, L)[0])
