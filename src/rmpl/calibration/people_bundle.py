"""The bundle adjustment of calibration from people: every camera and the 3D joints of many
frames, with constant bone lengths per person and a robust loss.

Parameters, one vector: each free camera's rotation vector and translation (6), each
person's bone lengths (one per bone of :data:`BONES`), each 3D joint (3). Residuals:

- reprojection, pixels: ``f * (x_normalised(projected) - x_normalised(observed))`` for every
  observation (a joint of a person in a view and frame);
- bones, ``(|X_a - X_b| - L) / (BONE_RELATIVE_SIGMA * L) * PIXEL_SIGMA``: a bone
  differing by :data:`BONE_RELATIVE_SIGMA` of its person's length weighs as a
  :data:`PIXEL_SIGMA` pixel error. The term does not change when the whole scene is scaled
  (:data:`BONE_TERM` "metres", by :data:`BONE_SIGMA` metres, falls as the people shrink
  against the rig, and a converged adjustment drifts that way);
- the gauge: one camera fixed (its pose is not a parameter) and the distance between it and
  a second camera held at its start value (the scale comes afterwards).

SciPy's ``least_squares`` (trust region, LSMR) gets the analytic sparse Jacobian
(:func:`_jacobian`; a rotation's derivative through the left Jacobian of SO(3)); the
loss is ``soft_l1`` with a scale of :data:`PIXEL_SIGMA`; observations further than a
threshold that tightens over the rounds (:data:`ROUNDS`) are dropped between rounds. Each
round runs to convergence (up to 300 evaluations): stopping early left the cameras where
rounding happened to stop them.

Shape glossary: ``M`` observations, ``N`` 3D points, ``V`` cameras, ``G`` people.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass

import numpy as np

from rmpl.geometry.camera import rodrigues

__all__ = [
    "BONES",
    "BundleProblem",
    "BundleResult",
    "adjust",
    "centre_covariance",
    "one_blas_thread",
]

log = logging.getLogger(__name__)

#: COCO-17 bones held constant per person: (joint a, joint b).
BONES = (
    (15, 13),
    (13, 11),
    (16, 14),
    (14, 12),
    (11, 12),
    (5, 11),
    (6, 12),
    (5, 6),
    (5, 7),
    (7, 9),
    (6, 8),
    (8, 10),
)
BONE_SIGMA = 0.02
#: The bone term: "metres", ``(|X_a - X_b| - L) / BONE_SIGMA * PIXEL_SIGMA``, or
#: "relative", ``(|X_a - X_b| - L) / (BONE_RELATIVE_SIGMA * L) * PIXEL_SIGMA``, which does
#: not change when the whole scene is scaled (the "metres" term falls as the people shrink).
BONE_TERM = "relative"
BONE_RELATIVE_SIGMA = 0.05  # 2 cm on a bone of 0.4 m
PIXEL_SIGMA = 3.0
#: Outlier thresholds of the successive rounds, pixels (the last round keeps the rest).
ROUNDS = (40.0, 20.0, 10.0)
GAUGE_WEIGHT = 1e3


@dataclass
class BundleProblem:
    """Observations: ``cam`` (M,) camera index, ``point`` (M,) 3D point index, ``xy`` (M, 2)
    normalised undistorted coordinates, ``focal`` (V,) pixels; ``bones`` (B, 2) point index
    pairs with ``bone_person`` (B,) the index of their length (person * 12 + bone)."""

    cam: np.ndarray
    point: np.ndarray
    xy: np.ndarray
    focal: np.ndarray
    bones: np.ndarray
    bone_length: np.ndarray  # (B,) index into the lengths
    member: np.ndarray | None = None  # (M,) the 2D track of each observation


@dataclass
class BundleResult:
    """Cameras (R (V, 3, 3), t (V, 3)), points (N, 3), lengths (L,), the observations kept
    (M,) bool, per-observation errors (M,) pixels, and SciPy's Jacobian at the solution."""

    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    lengths: np.ndarray
    kept: np.ndarray
    errors: np.ndarray
    jac: object
    free: list[int]
    sigma: float


def _unpack(x, V, free, fixed_R, fixed_t, num_lengths):
    cams = x[: 6 * len(free)].reshape(-1, 6)
    R = np.repeat(fixed_R[None], V, 0).copy()
    t = np.repeat(fixed_t[None], V, 0).copy()
    R[free] = rodrigues(cams[:, :3])
    t[free] = cams[:, 3:]
    lengths = x[6 * len(free) : 6 * len(free) + num_lengths]
    points = x[6 * len(free) + num_lengths :].reshape(-1, 3)
    return R, t, lengths, points


def _residuals(x, prob: BundleProblem, mask, V, free, fixed, num_lengths, gauge):
    R, t, lengths, X = _unpack(x, V, free, fixed[0], fixed[1], num_lengths)
    c, p = prob.cam[mask], prob.point[mask]
    Xc = np.einsum("mij,mj->mi", R[c], X[p]) + t[c]
    z = np.where(np.abs(Xc[:, 2]) > 1e-9, Xc[:, 2], 1e-9)
    proj = Xc[:, :2] / z[:, None]
    reproj = ((proj - prob.xy[mask]) * prob.focal[c][:, None]).ravel()
    a, b = prob.bones[:, 0], prob.bones[:, 1]
    bone = _bone_terms(np.linalg.norm(X[a] - X[b], axis=-1), lengths[prob.bone_length])[0]
    i, j, d0 = gauge
    Ci, Cj = -R[i].T @ t[i], -R[j].T @ t[j]
    g = GAUGE_WEIGHT * (np.linalg.norm(Ci - Cj) - d0)
    return np.concatenate([reproj, bone, [g]])


def _bone_terms(d: np.ndarray, L: np.ndarray):
    """Each bone's residual (B,) from its length ``d`` and its person's ``L``, and the
    residual's derivatives by ``d`` and by ``L`` (:data:`BONE_TERM`)."""
    if BONE_TERM == "relative":
        Lp = np.where(L > 1e-6, L, 1e-6)
        w = PIXEL_SIGMA / (BONE_RELATIVE_SIGMA * Lp)
        return (d - L) * w, w, -d * w / Lp
    w = PIXEL_SIGMA / BONE_SIGMA
    return (d - L) * w, np.full_like(d, w), np.full_like(d, -w)


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]_x, shape (*, 3, 3), of vectors (*, 3): ``_skew(a) @ b == cross(a, b)``."""
    z = np.zeros_like(v[..., 0])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


def _left_jacobian(rvec: np.ndarray) -> np.ndarray:
    """The left Jacobian of SO(3), shape (*, 3, 3), at rotation vectors (*, 3):
    ``rodrigues(r + d) ~ rodrigues(J d) @ rodrigues(r)`` for a small ``d``, so
    ``d(R X)/dr = -[R X]_x J`` and ``d(R^T t)/dr = R^T [t]_x J``.

    >>> import numpy as np
    >>> np.allclose(_left_jacobian(np.zeros(3)), np.eye(3))
    True
    """
    r = np.asarray(rvec, dtype=float)
    theta = np.linalg.norm(r, axis=-1)
    small = theta < 1e-3  # the series to theta^2: its error (theta^4 / 720) stays < 1e-15
    th = np.where(small, 1.0, theta)
    a = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(th)) / th**2)
    b = np.where(small, 1 / 6 - theta**2 / 120, (th - np.sin(th)) / th**3)
    K = _skew(r)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def _jacobian(x, prob: BundleProblem, mask, V, free, fixed, num_lengths, gauge):
    """The analytic Jacobian of :func:`_residuals`, a CSR matrix of the same shape as
    :func:`_sparsity`'s pattern (and nonzero only inside it)."""
    R, t, lengths, X = _unpack(x, V, free, fixed[0], fixed[1], num_lengths)
    F = len(free)
    nc, off = 6 * F, 6 * F + num_lengths
    col = np.full(V, -1)
    col[free] = np.arange(F)
    Jl = np.zeros((V, 3, 3))
    Jl[free] = _left_jacobian(x[:nc].reshape(-1, 6)[:, :3])
    c, p = prob.cam[mask], prob.point[mask]
    M, B = len(c), len(prob.bones)
    rows2 = np.arange(2 * M).reshape(M, 2)  # the two rows of each observation
    # reprojection: d(f * Xc[:2] / z)/dXc, (M, 2, 3), then through Xc = R X + t
    Y = np.einsum("mij,mj->mi", R[c], X[p])
    Xc = Y + t[c]
    ok = np.abs(Xc[:, 2]) > 1e-9  # where _residuals clamps z, z is a constant
    z = np.where(ok, Xc[:, 2], 1e-9)
    fz = prob.focal[c] / z
    D = np.zeros((M, 2, 3))
    D[:, 0, 0] = D[:, 1, 1] = fz
    D[:, :, 2] = np.where(ok[:, None], -fz[:, None] * Xc[:, :2] / z[:, None], 0.0)
    blocks = [(rows2, off + 3 * p[:, None] + np.arange(3), D @ R[c])]
    has = col[c] >= 0
    dY = -_skew(Y[has]) @ Jl[c[has]]  # (Mf, 3, 3) d(R X)/d(rotation vector)
    cam_vals = np.concatenate([D[has] @ dY, D[has]], -1)  # (Mf, 2, 6)
    blocks.append((rows2[has], 6 * col[c[has]][:, None] + np.arange(6), cam_vals))
    # bones: through their lengths |X_a - X_b|
    d = X[prob.bones[:, 0]] - X[prob.bones[:, 1]]
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    _, by_d, by_L = _bone_terms(n[:, 0], lengths[prob.bone_length])
    u = np.where(n > 0, d / np.where(n > 0, n, 1.0), 0.0) * by_d[:, None]
    br = (2 * M + np.arange(B))[:, None]
    blocks += [
        (br, off + 3 * prob.bones[:, :1] + np.arange(3), u[:, None]),
        (br, off + 3 * prob.bones[:, 1:] + np.arange(3), -u[:, None]),
        (br, nc + prob.bone_length[:, None], by_L[:, None, None]),
    ]
    blocks += _gauge_blocks(R, t, col, Jl, gauge, 2 * M + B)
    return _assemble(blocks, (2 * M + B + 1, off + 3 * len(X)))


def _assemble(blocks, shape):
    """A CSR matrix from blocks, each (rows (K, r), cols (K, c), values (K, r, c)): block
    k puts values[k] at rows[k] x cols[k]."""
    from scipy.sparse import csr_matrix

    r = np.concatenate([np.broadcast_to(rw[:, :, None], v.shape).ravel() for rw, _, v in blocks])
    c = np.concatenate([np.broadcast_to(cl[:, None, :], v.shape).ravel() for _, cl, v in blocks])
    vals = np.concatenate([v.ravel() for _, _, v in blocks])
    return csr_matrix((vals, (r, c)), shape=shape)


def _gauge_blocks(R, t, col, Jl, gauge, row):
    """The gauge row's derivative by each free camera of the pair: (rows, cols, values)."""
    i, j, _ = gauge
    C = -np.einsum("vji,vj->vi", R, t)  # (V, 3) centres -R^T t
    diff = C[i] - C[j]
    dist = float(np.linalg.norm(diff))
    if i == j or dist == 0.0:
        return []
    g = GAUGE_WEIGHT * diff / dist  # d gauge / d C_i; its negative for C_j
    out = []
    for v, sign in ((i, 1.0), (j, -1.0)):
        if col[v] < 0:
            continue
        dC = np.c_[-R[v].T @ _skew(t[v]) @ Jl[v], -R[v].T]  # (3, 6) d C / d(r, t)
        cols = 6 * col[v] + np.arange(6)[None]
        out.append((np.array([[row]]), cols, sign * (g @ dC)[None, None]))
    return out


def _sparsity(prob: BundleProblem, mask, V, free, num_lengths, num_points):
    from scipy.sparse import coo_matrix

    col = np.full(V, -1)
    col[free] = np.arange(len(free))
    nc, off = 6 * len(free), 6 * len(free) + num_lengths
    c, p = prob.cam[mask], prob.point[mask]
    M, B = len(c), len(prob.bones)
    rows, cols = [], []
    r2 = np.repeat(np.arange(2 * M).reshape(M, 2), 1, 0)  # (M, 2) rows of each observation
    has = col[c] >= 0
    cam_cols = 6 * col[c][has][:, None] + np.arange(6)  # (Mf, 6)
    for k in range(2):
        rows.append(np.repeat(r2[has, k], 6))
        cols.append(cam_cols.ravel())
        rows.append(np.repeat(r2[:, k], 3))
        cols.append((off + 3 * p[:, None] + np.arange(3)).ravel())
    br = 2 * M + np.arange(B)
    rows += [br, np.repeat(br, 3), np.repeat(br, 3)]
    cols += [
        nc + prob.bone_length,
        (off + 3 * prob.bones[:, :1] + np.arange(3)).ravel(),
        (off + 3 * prob.bones[:, 1:] + np.arange(3)).ravel(),
    ]
    rows.append(np.full(nc, 2 * M + B))
    cols.append(np.arange(nc))
    r, cc = np.concatenate(rows), np.concatenate(cols)
    shape = (2 * M + B + 1, off + 3 * num_points)
    return coo_matrix((np.ones(len(r), np.int8), (r, cc)), shape=shape).tocsr()


def adjust(
    prob: BundleProblem,
    R: np.ndarray,
    t: np.ndarray,
    points: np.ndarray,
    lengths: np.ndarray,
    fixed: int,
    gauge_cam: int,
    rounds: tuple[float, ...] = ROUNDS,
    max_nfev: int = 300,
) -> BundleResult:
    """Adjust cameras, bone lengths and points; ``fixed`` camera's pose stays, the distance
    from it to ``gauge_cam`` too. Returns the solution after the last round."""
    return _adjust(prob, R, t, points, lengths, (fixed, gauge_cam), rounds, max_nfev, True)


def _adjust(prob, R, t, points, lengths, pair, rounds, max_nfev, analytic) -> BundleResult:
    """:func:`adjust` with the analytic Jacobian or (``analytic=False``) SciPy's finite
    differences over the sparsity pattern."""
    from rmpl.geometry.camera import rotation_to_rodrigues

    fixed, gauge_cam = pair
    V = len(R)
    free = [v for v in range(V) if v != fixed]
    fixed_pose = (R[fixed], t[fixed])
    d0 = float(np.linalg.norm(-R[fixed].T @ t[fixed] + R[gauge_cam].T @ t[gauge_cam]))
    gauge = (fixed, gauge_cam, d0)
    x = np.concatenate(
        [np.c_[rotation_to_rodrigues(R[free]), t[free]].ravel(), lengths, points.ravel()]
    )
    L = len(lengths)
    with one_blas_thread():
        res, x, mask, errors = _rounds(prob, x, V, free, fixed_pose, L, gauge, rounds, max_nfev,
                                       analytic)  # fmt: skip
    R1, t1, lengths1, X1 = _unpack(x, V, free, *fixed_pose, L)
    r = res.fun[: 2 * int(mask.sum())]
    sigma = float(np.sqrt(np.mean(r**2))) if len(r) else 1.0
    return BundleResult(R1, t1, X1, lengths1, mask, errors, res.jac, free, sigma)


def one_blas_thread():
    """A context in which BLAS runs on one thread (when threadpoolctl is installed).

    The solver's linear algebra is sparse products and dot products of vectors of some
    10^4-10^5 numbers, too small to gain from threads; on a busy machine (or beside
    torch's threads) OpenBLAS's threads waiting for a core made the adjustment some ten
    times slower."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(1, user_api="blas")


def _rounds(prob, x, V, free, fixed_pose, L, gauge, rounds, max_nfev, analytic):
    """The solves of :func:`adjust`, the outliers dropped between them."""
    from scipy.optimize import least_squares

    mask = np.ones(len(prob.cam), bool)
    for threshold in (*rounds, None):
        if analytic:
            jac = {"jac": _jacobian}
        else:
            N = (len(x) - 6 * len(free) - L) // 3
            jac = {"jac_sparsity": _sparsity(prob, mask, V, free, L, N)}
        res = least_squares(
            _residuals,
            x,
            **jac,
            loss="soft_l1",
            f_scale=PIXEL_SIGMA,
            x_scale="jac",
            method="trf",
            tr_solver="lsmr",
            max_nfev=max_nfev,
            args=(prob, mask, V, free, fixed_pose, L, gauge),
        )
        x = res.x
        log.debug(
            "round %s: %d observations, %d evaluations, status %d, cost %.6g",
            threshold, int(mask.sum()), res.nfev, res.status, res.cost,
        )  # fmt: skip
        errors = _errors(x, prob, V, free, fixed_pose, L)
        if threshold is None:
            break
        keep = errors <= max(threshold, 3.0 * float(np.median(errors[mask])))
        keep &= ~_bad_members(prob, errors, max(threshold / 2, 2.0 * float(np.median(errors))))
        if (keep == mask).all():
            continue
        mask = keep
    return res, x, mask, errors


def _bad_members(prob: BundleProblem, errors: np.ndarray, limit: float) -> np.ndarray:
    """Observations of the 2D tracks whose median error exceeds ``limit`` pixels: a track
    given to the wrong person goes whole, not only its worst joints."""
    if prob.member is None:
        return np.zeros(len(errors), bool)
    _, inv = np.unique(prob.member, return_inverse=True)
    counts = np.bincount(inv)
    first = np.r_[0, np.cumsum(counts)[:-1]]
    e = errors[np.lexsort((errors, inv))]  # each track's errors together, ascending
    med = (e[first + (counts - 1) // 2] + e[first + counts // 2]) / 2
    return med[inv] > limit


def _errors(x, prob, V, free, fixed_pose, L) -> np.ndarray:
    mask = np.ones(len(prob.cam), bool)
    r = _residuals(x, prob, mask, V, free, fixed_pose, L, (0, 0, 0.0))
    return np.linalg.norm(r[: 2 * len(prob.cam)].reshape(-1, 2), axis=-1)


def centre_covariance(result: BundleResult, num_lengths: int) -> np.ndarray:
    """Each camera centre's covariance (V, 3, 3), in the adjustment's units, from the
    Gauss-Newton covariance of the camera parameters (points and lengths marginalised by
    the Schur complement), scaled by the residuals' variance. The fixed camera gets 0."""
    from scipy.sparse.linalg import splu

    J = result.jac.tocsc()
    nc = 6 * len(result.free)
    Jc, Jp = J[:, :nc].toarray(), J[:, nc:]
    Hcc = Jc.T @ Jc
    Hpc = Jp.T @ Jc
    Hpp = (Jp.T @ Jp).tocsc()
    Hpp = Hpp + 1e-9 * _eye(Hpp.shape[0])
    S = Hcc - Hpc.T @ splu(Hpp, permc_spec="MMD_AT_PLUS_A").solve(Hpc)  # Hpp symmetric
    cov = np.linalg.pinv(S) * result.sigma**2
    V = len(result.R)
    out = np.zeros((V, 3, 3))
    for k, v in enumerate(result.free):
        Jcen = _centre_jacobian(result.R[v], result.t[v])
        out[v] = Jcen @ cov[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] @ Jcen.T
    return out


def _eye(n: int):
    from scipy.sparse import identity

    return identity(n, format="csc")


def _centre_jacobian(R: np.ndarray, t: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """d(-R^T t)/d(rotation vector, t), (3, 6), by central differences."""
    from rmpl.geometry.camera import rotation_to_rodrigues

    p0 = np.r_[rotation_to_rodrigues(R), t]

    def centre(p):
        return -rodrigues(p[:3]).T @ p[3:]

    J = np.zeros((3, 6))
    for i in range(6):
        d = np.zeros(6)
        d[i] = eps
        J[:, i] = (centre(p0 + d) - centre(p0 - d)) / (2 * eps)
    return J
