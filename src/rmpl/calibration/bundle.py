"""One bundle adjustment of every camera and every board pose.

``scipy.optimize.least_squares`` (trust-region reflective) minimises the reprojection
error of every board corner seen, with an analytic sparse Jacobian (``_Problem.jacobian``:
a corner's two residuals depend only on its camera and its board pose; rotations through
the left Jacobian of SO(3), the lens through the derivatives of the distortion polynomial)
and a robust loss (``soft_l1``, scale 1 px). Unknowns: each camera's pose (the reference
camera's is fixed: it sets the frame), optionally its lens (fx, fy, cx, cy, k1, k2, p1, p2,
k3), and each board pose.
A lens that is adjusted keeps its own calibration as a Gaussian prior (OpenCV's standard
deviations of each parameter), so views that disagree across cameras (a board moving
between unsynchronised frames) cannot drag it where its own images say it is not. The
scale comes from the board's squares.

Rules fixed in advance: after a first solve, every view (one camera at one instant) whose
RMS exceeds both 2 px and four times the median view's is dropped and the problem solved
again. The adjustment is refused ("diverged") when a result is not finite, a focal length
moved by over 25%, or a camera's RMS ends above 3 px: the error names that camera and its
worst views.

The covariance of the camera parameters is the inverse of the Schur complement of the
Gauss-Newton normal matrix (board poses eliminated) times the residual variance; each
camera centre's 3x3 covariance follows by the centre's Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares

from rmpl.errors import InputError
from rmpl.geometry.camera import distort

__all__ = ["Adjusted", "Observations", "adjust", "rodrigues_batch"]

_DROP_PX, _DROP_RATIO, _DIVERGED_PX, _FOCAL_JUMP = 2.0, 4.0, 3.0, 0.25


def rodrigues_batch(r: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) from rotation vectors (N, 3)."""
    theta = np.linalg.norm(r, axis=1)
    small = theta < 1e-12
    k = r / np.where(small, 1.0, theta)[:, None]
    Kx = np.zeros((len(r), 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2], Kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    Kx = Kx - Kx.transpose(0, 2, 1)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * Kx + (1 - c) * Kx @ Kx


def _rvec(R: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.Rodrigues(R)[0].ravel()


@dataclass
class Observations:
    """Every corner seen: camera index, board-pose index, board point (metres), pixel;
    and per view (camera, board pose) its label for messages."""

    cam: np.ndarray
    pose: np.ndarray
    points: np.ndarray
    pixels: np.ndarray
    labels: dict[tuple[int, int], str] = field(default_factory=dict)


@dataclass
class Adjusted:
    """The adjustment's result: per camera K (3, 3), dist (5,), T_cw (4, 4); per board pose
    T_wb (4, 4); per camera RMS px and centre covariance (3, 3) m^2; views dropped."""

    K: list[np.ndarray]
    dist: list[np.ndarray]
    T_cw: list[np.ndarray]
    T_wb: list[np.ndarray]
    rms: np.ndarray
    centre_cov: np.ndarray
    dropped: list[tuple[int, str]]
    view_rms: dict[tuple[int, int], float]


class _Problem:
    def __init__(self, obs: Observations, V: int, P: int, ref: int, free_lens: bool, prior=None):
        self.obs, self.V, self.P, self.ref, self.free = obs, V, P, ref, free_lens
        self.prior = prior  # (lens values (V, 9), their standard deviations (V, 9)) or None
        self.nlens = 9 if free_lens else 0
        self.ncam = 6 + self.nlens
        self.cam_cols = [None if v == ref else v for v in range(V)]

    def pack(self, K, dist, T_cw, T_wb) -> np.ndarray:
        cams = []
        for v in range(self.V):
            pose = [] if v == self.ref else [*_rvec(T_cw[v][:3, :3]), *T_cw[v][:3, 3]]
            lens = [K[v][0, 0], K[v][1, 1], K[v][0, 2], K[v][1, 2], *dist[v]] if self.free else []
            cams.append(np.array(pose + lens, float))
        boards = [np.r_[_rvec(T[:3, :3]), T[:3, 3]] for T in T_wb]
        return np.concatenate(cams + boards)

    def unpack(self, x, K0, dist0):
        i, K, dist, Rc, tc = 0, [], [], [], []
        for v in range(self.V):
            if v == self.ref:
                Rc.append(np.zeros(3)), tc.append(np.zeros(3))
            else:
                Rc.append(x[i : i + 3]), tc.append(x[i + 3 : i + 6])
                i += 6
            if self.free:
                fx, fy, cx, cy = x[i : i + 4]
                K.append(np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]))
                dist.append(x[i + 4 : i + 9])
                i += 9
            else:
                K.append(K0[v]), dist.append(dist0[v])
        boards = x[i:].reshape(self.P, 6)
        return K, dist, np.array(Rc), np.array(tc), boards

    def residuals(self, x, K0, dist0, obs=None) -> np.ndarray:
        o = obs or self.obs
        K, dist, rc, tc, boards = self.unpack(x, K0, dist0)
        Rb, Rcm = rodrigues_batch(boards[:, :3]), rodrigues_batch(rc)
        Xw = np.einsum("nij,nj->ni", Rb[o.pose], o.points) + boards[o.pose, 3:]
        Xc = np.einsum("nij,nj->ni", Rcm[o.cam], Xw) + tc[o.cam]
        xy = distort(Xc[:, :2] / Xc[:, 2:3], np.stack(dist)[o.cam])
        Ks = np.stack(K)[o.cam]
        uv = np.stack(
            [Ks[:, 0, 0] * xy[:, 0] + Ks[:, 0, 2], Ks[:, 1, 1] * xy[:, 1] + Ks[:, 1, 2]], 1
        )
        res = (uv - o.pixels).ravel()
        if self.prior is None or not self.free:
            return res
        lens = np.array(
            [[k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d] for k, d in zip(K, dist, strict=True)]
        )
        return np.concatenate([res, ((lens - self.prior[0]) / self.prior[1]).ravel()])

    def starts(self) -> np.ndarray:
        """Each camera's first column (V,) and the first board column."""
        widths = [self.ncam - (6 if v == self.ref else 0) for v in range(self.V)]
        return np.r_[0, np.cumsum(widths)]

    def jacobian(self, x, K0, dist0) -> sp.csr_matrix:
        """The analytic Jacobian of :meth:`residuals` (CSR, inside :meth:`sparsity`'s
        pattern); a rotation's derivative through the left Jacobian of SO(3)."""
        from rmpl.calibration.people_bundle import _assemble, _left_jacobian, _skew

        o, n = self.obs, len(self.obs.cam)
        K, dist, rc, tc, boards = self.unpack(x, K0, dist0)
        Rb, Rcm = rodrigues_batch(boards[:, :3]), rodrigues_batch(rc)
        Pw = np.einsum("nij,nj->ni", Rb[o.pose], o.points)  # board point turned, (n, 3)
        Y = np.einsum("nij,nj->ni", Rcm[o.cam], Pw + boards[o.pose, 3:])
        Xc = Y + tc[o.cam]
        xn = Xc[:, :2] / Xc[:, 2:3]
        dxy, ddist, xd = _distort_jacobian(xn, np.stack(dist)[o.cam])
        Ks = np.stack(K)[o.cam]
        f = np.c_[Ks[:, 0, 0], Ks[:, 1, 1]]
        eye = np.broadcast_to(np.eye(2), (n, 2, 2))
        dproj = np.concatenate([eye, -xn[:, :, None]], -1) / Xc[:, 2, None, None]  # dxn/dXc
        G = (f[:, :, None] * dxy) @ dproj  # (n, 2, 3) d pixel / d Xc
        rows = 2 * np.arange(n)[:, None] + np.arange(2)  # (n, 2)
        starts = self.starts()
        board0 = starts[-1]
        GR = G @ Rcm[o.cam]
        dboard = np.concatenate([GR @ (-_skew(Pw) @ _left_jacobian(boards[:, :3])[o.pose]), GR], -1)
        blocks = [(rows, board0 + 6 * o.pose[:, None] + np.arange(6), dboard)]
        has = o.cam != self.ref
        dpose = np.concatenate([G @ (-_skew(Y) @ _left_jacobian(rc)[o.cam]), G], -1)
        blocks.append((rows[has], starts[o.cam[has]][:, None] + np.arange(6), dpose[has]))
        nrows = 2 * n
        if self.free:
            dlens = np.zeros((n, 2, 9))
            dlens[:, 0, 0], dlens[:, 1, 1] = xd[:, 0], xd[:, 1]
            dlens[:, 0, 2] = dlens[:, 1, 3] = 1.0
            dlens[:, :, 4:] = f[:, :, None] * ddist
            first = starts[:-1] + np.where(np.arange(self.V) == self.ref, 0, 6)
            blocks.append((rows, first[o.cam][:, None] + np.arange(9), dlens))
            if self.prior is not None:
                prior_rows = (nrows + np.arange(9 * self.V))[:, None]  # one entry each
                prior_cols = (first[:, None] + np.arange(9)).reshape(-1, 1)
                blocks.append((prior_rows, prior_cols, (1 / self.prior[1]).reshape(-1, 1, 1)))
                nrows += 9 * self.V
        return _assemble(blocks, (nrows, board0 + 6 * self.P))

    def sparsity(self) -> sp.csr_matrix:
        o, n = self.obs, len(self.obs.cam)
        starts, col = [], 0
        for v in range(self.V):
            starts.append(col)
            col += self.ncam - (6 if v == self.ref else 0)
        widths = np.array([self.ncam - (6 if v == self.ref else 0) for v in range(self.V)])
        board0 = col
        rows, cols = [], []
        for r2 in (0, 1):
            r = 2 * np.arange(n) + r2
            for j in range(widths.max()):
                keep = j < widths[o.cam]
                rows.append(r[keep]), cols.append(np.array(starts)[o.cam][keep] + j)
            for j in range(6):
                rows.append(r), cols.append(board0 + 6 * o.pose + j)
        nrows = 2 * n
        if self.prior is not None and self.free:
            for v in range(self.V):
                first = starts[v] + (0 if v == self.ref else 6)
                rows.append(nrows + 9 * v + np.arange(9)), cols.append(first + np.arange(9))
            nrows += 9 * self.V
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        shape = (nrows, board0 + 6 * self.P)
        return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=shape), board0


def _distort_jacobian(xy: np.ndarray, dist: np.ndarray):
    """Of :func:`rmpl.geometry.camera.distort` at ``xy`` (n, 2) with ``dist`` (n, 5): the
    derivatives by (x, y), (n, 2, 2), and by (k1, k2, p1, p2, k3), (n, 2, 5); and the
    distorted coordinates (n, 2)."""
    k1, k2, p1, p2, k3 = dist.T
    x, y = xy.T
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    cross = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    dxy = np.stack(
        [
            np.stack([radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x, cross], -1),
            np.stack([cross, radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x], -1),
        ],
        -2,
    )
    ddist = np.stack(
        [
            np.stack([x * r2, x * r2**2, 2 * x * y, r2 + 2 * x * x, x * r2**3], -1),
            np.stack([y * r2, y * r2**2, r2 + 2 * y * y, 2 * x * y, y * r2**3], -1),
        ],
        -2,
    )
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return dxy, ddist, np.c_[xd, yd]


def _view_rms(res: np.ndarray, obs: Observations) -> dict[tuple[int, int], float]:
    sq = res[: 2 * len(obs.cam)].reshape(-1, 2) ** 2
    out: dict[tuple[int, int], float] = {}
    key = obs.cam * 1_000_000 + obs.pose
    for k in np.unique(key):
        m = key == k
        out[int(k // 1_000_000), int(k % 1_000_000)] = float(np.sqrt(sq[m].sum(1).mean()))
    return out


def _subset(obs: Observations, keep: np.ndarray) -> Observations:
    return Observations(
        obs.cam[keep], obs.pose[keep], obs.points[keep], obs.pixels[keep], obs.labels
    )


def _solve(prob: _Problem, x0, K0, dist0, analytic: bool = True):
    """The least-squares solution from ``x0``: with the analytic Jacobian, or
    (``analytic=False``) SciPy's finite differences over the sparsity pattern."""
    from rmpl.calibration.people_bundle import one_blas_thread

    jac = {"jac": prob.jacobian} if analytic else {"jac_sparsity": prob.sparsity()[0]}
    with one_blas_thread():
        return least_squares(
            prob.residuals, x0, **jac, loss="soft_l1", f_scale=1.0, x_scale="jac",
            method="trf", args=(K0, dist0), max_nfev=100, xtol=1e-6, ftol=1e-6,
        )  # fmt: skip


def adjust(
    obs: Observations,
    K0: list[np.ndarray],
    dist0: list[np.ndarray],
    T_cw0: list[np.ndarray],
    T_wb0: list[np.ndarray],
    ref: int,
    names: list[str],
    *,
    free_lens: bool = True,
    lens_std: list[np.ndarray | None] | None = None,
) -> Adjusted:
    """Adjust cameras (and lenses when ``free_lens``) and board poses together.

    Raises:
        InputError: the adjustment diverged (camera and its worst views named).
    """
    V, P = len(K0), len(T_wb0)
    dist0 = [np.pad(np.ravel(d)[:5], (0, 5 - min(5, np.ravel(d).size))) for d in dist0]
    prior = _prior(K0, dist0, lens_std)
    prob = _Problem(obs, V, P, ref, free_lens, prior)
    x0 = prob.pack(K0, dist0, T_cw0, T_wb0)
    sol = _solve(prob, x0, K0, dist0)
    views = _view_rms(sol.fun, obs)
    med = np.median(list(views.values()))
    bad = {k for k, e in views.items() if e > _DROP_PX and e > _DROP_RATIO * med}
    dropped = [(k[0], obs.labels.get(k, f"view {k}")) for k in sorted(bad)]
    if bad:
        keep = np.array([(c, p) not in bad for c, p in zip(obs.cam, obs.pose, strict=True)])
        obs = _subset(obs, keep)
        prob = _Problem(obs, V, P, ref, free_lens, prior)
        sol = _solve(prob, sol.x, K0, dist0)
        views = _view_rms(sol.fun, obs)
    K, dist, rc, tc, boards = prob.unpack(sol.x, K0, dist0)
    rms = np.array([_rms(sol.fun, obs.cam == v) for v in range(V)])
    _guard(sol.x, K, K0, rms, views, obs, names)
    Rc, Rb = rodrigues_batch(rc), rodrigues_batch(boards[:, :3])
    T_cw = [_mat(Rc[v], tc[v]) for v in range(V)]
    T_wb = [_mat(Rb[p], boards[p, 3:]) for p in range(P)]
    cov = _centre_cov(prob, sol, rc, tc)
    return Adjusted(K, [np.asarray(d) for d in dist], T_cw, T_wb, rms, cov, dropped, views)


def _prior(K0, dist0, lens_std):
    """Each lens's calibration as a prior: its values and OpenCV's standard deviations
    (floored at 1e-6 of the value's scale), or None when a lens has none."""
    if lens_std is None or any(s is None or not np.all(np.isfinite(s)) for s in lens_std):
        return None
    values = np.array(
        [[k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d] for k, d in zip(K0, dist0, strict=True)]
    )
    floor = np.r_[np.full(4, 1e-3), np.full(5, 1e-6)]
    return values, np.maximum(np.stack(lens_std), floor)


def _mat(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _rms(res: np.ndarray, mask: np.ndarray) -> float:
    r = res[: 2 * len(mask)].reshape(-1, 2)[mask]
    return float(np.sqrt((r**2).sum(1).mean())) if len(r) else float("nan")


def _guard(x, K, K0, rms, views, obs, names) -> None:
    for v in range(len(K)):
        jump = abs(K[v][0, 0] / K0[v][0, 0] - 1)
        if np.all(np.isfinite(x)) and jump <= _FOCAL_JUMP and rms[v] <= _DIVERGED_PX:
            continue
        worst = sorted((e, p) for (c, p), e in views.items() if c == v)[::-1][:3]
        labels = ", ".join(f"{obs.labels.get((v, p), p)} ({e:.1f} px)" for e, p in worst)
        raise InputError(
            None, f"camera {names[v]}",
            "a bundle adjustment that converges (check this camera's images, its board "
            "detections and that the cameras did not move during the recording)",
            f"diverged: RMS {rms[v]:.2f} px, focal moved {100 * jump:.0f}%; worst views {labels}",
        )  # fmt: skip


def _centre_cov(prob: _Problem, sol, rc, tc) -> np.ndarray:
    """(V, 3, 3) covariance of each camera centre, m^2 (zero for the reference camera)."""
    J = sp.csr_matrix(sol.jac)
    m, n = J.shape
    _, board0 = prob.sparsity()
    H = (J.T @ J).tocsr()
    A = H[:board0, :board0].toarray()
    B = H[:board0, board0:].toarray()
    C = H[board0:, board0:]
    Cinv = sp.block_diag(
        [np.linalg.pinv(C[i : i + 6, i : i + 6].toarray()) for i in range(0, C.shape[0], 6)]
    ).tocsr()
    S = A - B @ (Cinv @ B.T)
    sigma2 = float(sol.fun @ sol.fun) / max(m - n, 1)
    cov = np.linalg.pinv(S) * sigma2
    out = np.zeros((prob.V, 3, 3))
    col = 0
    for v in range(prob.V):
        if v == prob.ref:
            col += prob.nlens
            continue
        G = _centre_jacobian(rc[v], tc[v])
        out[v] = G @ cov[col : col + 6, col : col + 6] @ G.T
        col += prob.ncam
    return out


def _centre_jacobian(r: np.ndarray, t: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    """d(-R(r)^T t) / d(r, t), (3, 6), by central differences."""

    def centre(p):
        return -rodrigues_batch(p[None, :3])[0].T @ p[3:]

    p = np.r_[r, t]
    cols = [(centre(p + e) - centre(p - e)) / (2 * eps) for e in np.eye(6) * eps]
    return np.stack(cols, axis=1)
