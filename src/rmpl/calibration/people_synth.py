"""Synthetic people and rigs where the answer is known: for tests and benchmarks of the
calibration from people and of the synchronisation.

:func:`moving_people` makes COCO-17 stick figures of given statures (proportions of
:mod:`rmpl.anthropometry`) that wander over a floor at z = 0 and swing their legs and arms
by smooth random (not periodic) motions; :func:`ring_rig` puts cameras around them;
:func:`observe` projects them with pixel noise, shuffles the people's order in every
frame and view (as a detector does) and drops what falls outside the images.

Shape glossary: ``T`` frames, ``V`` views, ``P`` people, ``J`` joints (17). Metres, z up.
"""

from __future__ import annotations

import numpy as np

from rmpl.geometry.camera import Camera, Rig, look_at

__all__ = ["moving_people", "observe", "ring_rig"]


def _smooth(rng: np.random.Generator, times: np.ndarray, amp: float, n: int = 4) -> np.ndarray:
    """A smooth random signal: a few sinusoids of random frequency (0.2-1.5 Hz) and phase."""
    f = rng.uniform(0.2, 1.5, n)
    ph = rng.uniform(0, 2 * np.pi, n)
    a = rng.uniform(0.3, 1.0, n) * amp / np.sqrt(n)
    return (a[None] * np.sin(2 * np.pi * f[None] * times[:, None] + ph[None])).sum(-1)


def _figure(H: float, heading, lean, hipL, hipR, kneeL, kneeR, armL, armR, elbL, elbR):
    """COCO-17 joints (T, 17, 3) of a figure standing at the origin, facing ``heading``."""
    T = len(heading)
    fwd = np.stack([np.cos(heading), np.sin(heading), np.zeros(T)], -1)
    side = np.stack([-np.sin(heading), np.cos(heading), np.zeros(T)], -1)  # to the left
    up = np.array([0.0, 0.0, 1.0])
    pelvis = 0.53 * H * up + 0 * fwd
    trunk = (0.818 - 0.53) * H * (np.cos(lean)[:, None] * up + np.sin(lean)[:, None] * fwd)
    neck = pelvis + trunk
    out = np.zeros((T, 17, 3))

    def limb(root, a1, a2, l1, l2):
        d1 = -np.cos(a1)[:, None] * up + np.sin(a1)[:, None] * fwd
        a = a1 + a2
        d2 = -np.cos(a)[:, None] * up + np.sin(a)[:, None] * fwd
        mid = root + l1 * d1
        return mid, mid + l2 * d2

    for s, sign, hip, knee, arm, elb in ((0, 1, hipL, kneeL, armL, elbL),
                                         (1, -1, hipR, kneeR, armR, elbR)):  # fmt: skip
        hj = pelvis + sign * 0.095 * H * side
        k, a = limb(hj, hip, -np.abs(knee), 0.245 * H, 0.246 * H)
        sh = neck + sign * 0.13 * H * side
        e, w = limb(sh, arm, np.abs(elb), 0.186 * H, 0.146 * H)
        out[:, 11 + s], out[:, 13 + s], out[:, 15 + s] = hj, k, a
        out[:, 5 + s], out[:, 7 + s], out[:, 9 + s] = sh, e, w
        out[:, 1 + s] = neck + 0.125 * H * up + 0.04 * H * fwd + sign * 0.03 * H * side
        out[:, 3 + s] = neck + 0.11 * H * up + sign * 0.07 * H * side
    out[:, 0] = neck + 0.10 * H * up + 0.07 * H * fwd
    return out


def moving_people(
    times: np.ndarray,
    heights: tuple[float, ...] = (1.75,),
    rng: np.random.Generator | int | None = 0,
    area: float = 1.5,
) -> np.ndarray:
    """People moving about, shape (T, P, 17, 3), metres, z up, floor z = 0.

    The motion is a function of time drawn from ``rng``: the same seed gives the same
    people at any times (each camera of a rig can sample it at its own instants).

    Args:
        times: the instants, seconds, shape (T,).
        heights: each person's stature, metres.
        rng: a Generator or a seed.
        area: half-width of the square they move in, metres.
    """
    rng = np.random.default_rng(rng)
    t = np.asarray(times, float)
    people = []
    for H in heights:
        x = _smooth(rng, t, area) + rng.uniform(-0.3, 0.3)
        y = _smooth(rng, t, area) + rng.uniform(-0.3, 0.3)
        heading = rng.uniform(0, 2 * np.pi) + _smooth(rng, t, 2.0)
        ang = [_smooth(rng, t, 0.6) for _ in range(4)]
        bend = [np.abs(_smooth(rng, t, 0.9)) for _ in range(4)]
        lean = 0.1 + _smooth(rng, t, 0.1)
        fig = _figure(H, heading, lean, ang[0], ang[1], bend[0], bend[1],
                      ang[2], ang[3], bend[2], bend[3])  # fmt: skip
        fig[..., 2] -= np.minimum(fig[:, 15, 2], fig[:, 16, 2])[:, None] - 0.039 * H
        people.append(fig + np.stack([x, y, np.zeros_like(x)], -1)[:, None])
    return np.stack(people, 1)


def ring_rig(
    num_views: int,
    rng: np.random.Generator | int | None = 0,
    radius: tuple[float, float] = (4.0, 6.0),
    size: tuple[int, int] = (1280, 720),
    focal: tuple[float, float] = (900.0, 1300.0),
    distortion: bool = False,
) -> Rig:
    """Cameras on a ring around the origin at 1.5-3 m height, looking at the people's
    middle (z = 1 m), names ``cam0``, ``cam1``, ...."""
    rng = np.random.default_rng(rng)
    az = np.linspace(0, 2 * np.pi, num_views, endpoint=False) + rng.uniform(-0.3, 0.3, num_views)
    cams = []
    for v in range(num_views):
        r = rng.uniform(*radius)
        eye = np.array([r * np.cos(az[v]), r * np.sin(az[v]), rng.uniform(1.5, 3.0)])
        target = np.array([0.0, 0.0, 1.0]) + rng.uniform(-0.3, 0.3, 3)
        R, t = look_at(eye, target)
        f = rng.uniform(*focal)
        K = np.array([[f, 0, size[0] / 2 + rng.uniform(-10, 10)],
                      [0, f, size[1] / 2 + rng.uniform(-10, 10)], [0, 0, 1]])  # fmt: skip
        dist = np.array([rng.uniform(-0.2, 0.05), rng.uniform(-0.05, 0.1), 0, 0, 0])
        cams.append(Camera(K, R, t, dist if distortion else np.zeros(5), size, f"cam{v}"))
    return Rig(tuple(cams))


def observe(
    points: np.ndarray,
    rig: Rig,
    noise: float = 1.0,
    rng: np.random.Generator | int | None = 0,
    shuffle: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Project people into every view as a detector reports them.

    Args:
        points: shape (T, P, J, 3), metres.
        noise: pixel noise (standard deviation).
        shuffle: put the people in a random order in every frame and view.

    Returns:
        keypoints (T, V, P, J, 2), pixels, NaN outside the image; scores (T, V, P, J).
    """
    rng = np.random.default_rng(rng)
    T, P, J, _ = points.shape
    kp = rig.project(points.reshape(T, P * J, 3)).reshape(T, len(rig), P, J, 2)
    kp = kp + rng.normal(0, noise, kp.shape)
    size = rig.sizes[None, :, None, None]
    inside = np.isfinite(kp).all(-1) & (kp >= 0).all(-1) & (kp < size).all(-1)
    kp[~inside] = np.nan
    sc = np.where(inside, 0.9, 0.0)
    if shuffle:
        order = np.argsort(rng.random((T, len(rig), P)), axis=-1)
        kp = np.take_along_axis(kp, order[..., None, None], axis=2)
        sc = np.take_along_axis(sc, order[..., None], axis=2)
    return kp, sc
