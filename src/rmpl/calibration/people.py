"""Camera extrinsics from the people in view: no board.

The intrinsics come from a calibration file whose extrinsics are never read
(:func:`intrinsics_only`). The cameras' poses come from the 2D keypoints (COCO-17 joints):

1. **People in time and across views.** Each view's people are linked frame to frame
   (:func:`rmpl.calibration.sync.link_people`). For every pair of views and every pair of
   tracks seen together, an essential matrix is fitted by RANSAC (OpenCV, undistorted
   normalised points); track pairs whose joints fit a pair's best matrix are the same
   person, and people are the groups of tracks so linked (one track per view at a time).
2. **Start.** The pair of views with the most inliers gives two cameras
   (``recoverPose``); the people's joints are triangulated and every other camera is
   placed from them by PnP with RANSAC, the camera with most points first.
3. **Bundle adjustment** (:mod:`.people_bundle`) over every camera, each person's bone
   lengths and the joints of up to ``max_frames`` frames, robust, outliers dropped by
   tightening thresholds.
4. **Scale**: ``height`` (the person seen most, metres), ``camera_distance`` (two cameras'
   centres), or by default the adult body prior: each person's stature from its bone
   lengths (:mod:`rmpl.anthropometry`) is taken as :data:`ADULT_STATURE` +-
   :data:`ADULT_STATURE_SD`; with G people the scale's uncertainty is the prior's over
   sqrt(G) with the proportions' :data:`PROPORTION_SD`.
5. **Floor and up**: up is the robust mean direction from the ankles' midpoint to the
   shoulders' midpoint; the floor is fitted under the lowest ankles
   (:func:`rmpl.geometry.floor.fit_floor`); the world is z up, z = 0 on the floor, the
   origin under the people's median ankle position, x along the first camera's image x.

Shape glossary: ``T`` frames, ``V`` views, ``P`` people per view, ``G`` people, ``J``
joints (17), ``Q`` tracks. Metres, pixels.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np

from rmpl.calibration.people_assoc import triangulate_normalised
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig

__all__ = [
    "ADULT_STATURE",
    "ADULT_STATURE_SD",
    "PROPORTION_SD",
    "PeopleCalibration",
    "calibrate_from_people",
    "intrinsics_only",
    "moved",
    "similarity",
    "triangulate_normalised",
]

log = logging.getLogger(__name__)

#: The adult body prior: stature of adults of both sexes, mean and spread, metres.
ADULT_STATURE = 1.70
ADULT_STATURE_SD = 0.10
#: The spread of a stature estimated from bone lengths (Drillis & Contini proportions).
PROPORTION_SD = 0.04
MIN_SCORE = 0.3
RANSAC_PX = 4.0
PNP_PX = 12.0  # the start's two cameras are a few degrees off: PnP inliers are looser
MIN_COMMON = 60  # joint correspondences a pair of tracks needs
HYPOTHESIS_POINTS = 1000  # joints of a track pair a hypothesis is fitted on
SUPPORT_PX = 10.0  # median Sampson distance of a track pair of one person
#: The least motion of the people (see :func:`_motion`) to calibrate from.
MIN_MOTION = 0.02
#: A camera whose centre's 1-sigma exceeds this fraction of its distance to the people
#: is called unreliable (the report warns, ``rmpl calibrate`` exits with status 3).
UNRELIABLE_SD = 0.05
SUPPORT_RATIO = 2.0  # ... or this many times that of the pair that proposed the matrix
J17 = 17


@dataclass
class PeopleCalibration:
    """The result: the rig (metric, z up, floor z = 0) and what the report says."""

    rig: Rig
    rms: np.ndarray  # (V,) pixels, observations kept
    centre_sd: np.ndarray  # (V,) metres, the largest axis of each centre's 1-sigma ellipsoid
    scale_source: str
    scale_sd: float  # relative
    people: list[dict]
    frames_used: np.ndarray
    observations: tuple[int, int]  # kept, total
    floor: str
    moved: list[dict] = field(default_factory=list)
    centre_sd_relative: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (V,)
    warnings: list[str] = field(default_factory=list)


def intrinsics_only(rig: Rig) -> Rig:
    """The cameras' K, distortion and size with identity poses: nothing of the given
    extrinsics goes further than this function."""
    return Rig(tuple(Camera(c.K, np.eye(3), np.zeros(3), c.dist, c.size, c.name) for c in rig))


def _normalised(points: np.ndarray, cam: Camera) -> np.ndarray:
    from rmpl.calibration.sync import _normalised as norm

    return norm(points, cam)


# --------------------------------------------------------------------------- people


def _tracks(keypoints, scores, rig):
    """Per view: normalised tracks (T, Q, J, 2) with NaN below :data:`MIN_SCORE`."""
    from rmpl.calibration.sync import link_people

    out = []
    for v, cam in enumerate(rig):
        kp = np.where(
            (scores[:, v, :, :J17] >= MIN_SCORE)[..., None], keypoints[:, v, :, :J17], np.nan
        )
        tr = link_people(kp)
        out.append(_normalised(tr, cam))
    return out


def _motion(tracks) -> float:
    """How much the people move: over views and tracks, the largest median (over joints
    seen in 10 frames or more) of a joint's spread over the frames (the root of its
    positions' variance), as a fraction of the track's height in the image."""
    best = 0.0
    for tr in tracks:  # (T, Q, J, 2) per view
        for q in range(tr.shape[1]):
            x = tr[:, q]
            joints = np.isfinite(x).all(-1).sum(0) >= 10
            if not joints.any():
                continue
            x = x[:, joints]
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore", RuntimeWarning)  # frames without the joints
                h = np.nanmedian(np.nanmax(x[..., 1], -1) - np.nanmin(x[..., 1], -1))
                spread = np.median(np.sqrt(np.nanvar(x[..., 0], 0) + np.nanvar(x[..., 1], 0)))
            if h > 0:
                best = max(best, float(spread / h))
    return best


def _check_motion(tracks, source) -> None:
    moving = _motion(tracks)
    if moving < MIN_MOTION:
        raise InputError(
            source,
            "keypoints",
            f"people who move (a joint's spread over the frames at least {100 * MIN_MOTION:.0f}% "
            "of the person's height in the image): a still scene gives a few points however "
            "many frames",
            f"{100 * moving:.1f}%",
        )


def _common(a: np.ndarray, b: np.ndarray):
    """Joint correspondences of two tracks (T, J, 2): (n, 2) and (n, 2), and the frames."""
    ok = np.isfinite(a).all(-1) & np.isfinite(b).all(-1)
    t, _ = np.nonzero(ok)
    return a[ok], b[ok], t


def _sampson(E: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    ha, hb = np.c_[xa, np.ones(len(xa))], np.c_[xb, np.ones(len(xb))]
    Ea, Eb = ha @ E.T, hb @ E
    num = np.einsum("ni,ni->n", hb, Ea) ** 2
    return np.sqrt(num / (Ea[:, 0] ** 2 + Ea[:, 1] ** 2 + Eb[:, 0] ** 2 + Eb[:, 1] ** 2))


def _pair_matrix(tracks_a, tracks_b, focal: float):
    """The essential matrix of a pair of views and the track pairs it matches:
    (inliers, E, [(i, j, fraction)], {(i, j) of the track pairs seen together}).

    Every pair of tracks seen together gives a hypothesis (RANSAC on its joints); a
    hypothesis is supported by the track pairs whose median Sampson distance is under
    :data:`SUPPORT_PX` (the same person, whoever it is), weighed by their joints. The
    best supported is fitted again on all its supporters' joints at once: one person's
    joints alone span too little to fix the matrix, several people together do.
    """
    import cv2

    thr = RANSAC_PX / focal
    cands = []
    for i in range(tracks_a.shape[1]):
        for j in range(tracks_b.shape[1]):
            xa, xb, _ = _common(tracks_a[:, i], tracks_b[:, j])
            if len(xa) >= MIN_COMMON // 2:
                cands.append((i, j, xa, xb))
    best = (0, None, [])
    for _i, _j, xa, xb in cands:
        if len(xa) < MIN_COMMON:
            continue
        if len(xa) > HYPOTHESIS_POINTS:  # spread over the track, the same every run
            k = np.linspace(0, len(xa) - 1, HYPOTHESIS_POINTS).round().astype(int)
            xa, xb = xa[k], xb[k]
        E, _ = cv2.findEssentialMat(xa, xb, np.eye(3), cv2.RANSAC, 0.999, thr)
        if E is None or E.shape != (3, 3):
            continue
        E = E[:3]
        sup = _support(E, cands, focal, float(np.median(_sampson(E, xa, xb))) * focal)
        score = sum(len(c[2]) for c in sup)
        if score > best[0]:
            best = (score, E, sup)
    together = {(i, j) for i, j, *_ in cands}
    if best[1] is None:
        return 0, None, [], together
    E, sup = best[1], best[2]
    n = 0
    for _ in range(2):  # refit on every supporter, then take the supporters again
        xa = np.concatenate([c[2] for c in sup])
        xb = np.concatenate([c[3] for c in sup])
        E2, mask = cv2.findEssentialMat(xa, xb, np.eye(3), cv2.RANSAC, 0.999, thr)
        if E2 is None or E2.shape != (3, 3):
            break
        E, n = E2, int(mask.sum())
        noise = min(float(np.median(_sampson(E, c[2], c[3]))) for c in sup) * focal
        sup = _support(E, cands, focal, noise) or sup
    matches = [(i, j, float((_sampson(E, xa, xb) < thr).mean())) for i, j, xa, xb in sup]
    return n, E, matches, together


def _support(E: np.ndarray, cands: list, focal: float, noise: float = 0.0) -> list:
    """The track pairs whose median Sampson distance (pixels) is under :data:`SUPPORT_PX`,
    or under :data:`SUPPORT_RATIO` times ``noise`` (the hypothesis' own pair's median: a
    detector whose joints scatter more gets a wider gate, in proportion)."""
    limit = max(SUPPORT_PX, SUPPORT_RATIO * noise)
    return [c for c in cands if np.median(_sampson(E, c[2], c[3])) * focal < limit]


def _people_matches(tracks, focal: np.ndarray, with_pairs: bool = False):
    """Matching track pairs per pair of views ({(a, b): [(i, j, fraction)]}), from each
    pair's best essential matrix; with ``with_pairs`` also {(a, b): (inliers, E)}."""
    V = len(tracks)
    pairs, matches, together = {}, {}, {}
    for a in range(V):
        for b in range(a + 1, V):
            n, E, ms, tog = _pair_matrix(tracks[a], tracks[b], float(np.mean(focal[[a, b]])))
            together[(a, b)] = tog
            if E is not None:
                pairs[(a, b)], matches[(a, b)] = (n, E), ms
            log.debug("views %d-%d: %d inliers, %d matched track pairs", a, b, n, len(ms))
    return (pairs, matches, together) if with_pairs else (matches, together)


def _group(tracks, matches: dict, together: dict) -> list[dict[int, list[int]]]:
    """People: groups of (view, track) joined by matching track pairs, strongest first,
    never two tracks of one view seen at the same time, and never two tracks of two views
    that were seen together without matching (a merge must hold for every pair of views,
    not only for the link that proposes it)."""
    matched = {(a, i, b, j) for (a, b), ms in matches.items() for i, j, _ in ms}
    seen = [np.isfinite(tr).all(-1).any(-1) for tr in tracks]  # (T, Q) per view
    owner: dict[tuple[int, int], int] = {}
    groups: list[dict[int, list[int]]] = []
    links = sorted(
        ((f, a, i, b, j) for (a, b), ms in matches.items() for i, j, f in ms),
        reverse=True,
    )
    for _, a, i, b, j in links:
        ga, gb = owner.get((a, i)), owner.get((b, j))
        if ga is not None and ga == gb:
            continue
        parts = [
            groups[g] if g is not None else {k[0]: [k[1]]} for g, k in ((ga, (a, i)), (gb, (b, j)))
        ]
        if not _consistent(parts[0], parts[1], together, matched):
            continue
        merged: dict[int, list[int]] = {}
        for part in parts:
            for v, qs in part.items():
                merged.setdefault(v, []).extend(qs)
        if any(_overlap(seen[v], qs) for v, qs in merged.items()):
            continue
        for g in sorted({g for g in (ga, gb) if g is not None}, reverse=True):
            groups[g] = {}
        groups.append(merged)
        for v, qs in merged.items():
            for q in qs:
                owner[(v, q)] = len(groups) - 1
    return [g for g in groups if len(g) >= 2]


def _consistent(g1: dict, g2: dict, together: dict, matched: set) -> bool:
    for v, qs in g1.items():
        for w, rs in g2.items():
            if v == w:
                continue
            a, b = min(v, w), max(v, w)
            for q in qs:
                for r in rs:
                    i, j = (q, r) if v < w else (r, q)
                    if (i, j) in together.get((a, b), ()) and (a, i, b, j) not in matched:
                        return False
    return True


def _overlap(seen: np.ndarray, qs: list[int]) -> bool:
    return len(qs) > 1 and bool((seen[:, qs].sum(-1) > 1).any())


def _observations(tracks, groups, V: int) -> tuple[np.ndarray, np.ndarray]:
    """The people's 2D, shape (T, G, V, J, 2), normalised, NaN where unseen; and the
    track (an id unique over views) each comes from, (T, G, V), -1 where none."""
    T = len(tracks[0])
    obs = np.full((T, len(groups), V, J17, 2), np.nan)
    ids = np.full((T, len(groups), V), -1)
    for g, members in enumerate(groups):
        for v, qs in members.items():
            for q in qs:
                x = tracks[v][:, q]
                ok = np.isfinite(x).all(-1)
                obs[:, g, v][ok] = x[ok]
                ids[ok.any(-1), g, v] = v * 100000 + q
    return obs, ids


# --------------------------------------------------------------------------- geometry


def _pnp(X: np.ndarray, x: np.ndarray, focal: float):
    import cv2

    ok = np.isfinite(X).all(-1) & np.isfinite(x).all(-1)
    if ok.sum() < 12:
        return None
    X, x = X[ok].astype(np.float64), x[ok].astype(np.float64)
    found, rvec, tvec, inl = cv2.solvePnPRansac(
        X, x, np.eye(3), None, reprojectionError=PNP_PX / focal, iterationsCount=500
    )
    if not found or inl is None or len(inl) < 12:
        return None
    i = inl[:, 0]
    _, rvec, tvec = cv2.solvePnP(X[i], x[i], np.eye(3), None, rvec, tvec, True)
    return cv2.Rodrigues(rvec)[0], tvec[:, 0], len(i)


def similarity(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R, t) with ``dst ~ s R src + t`` (Umeyama), src and dst (N, 3), N >= 3.

    >>> a = np.random.default_rng(0).normal(size=(5, 3))
    >>> s, R, t = similarity(a, 2 * a + 1)
    >>> round(s, 6), bool(np.allclose(R, np.eye(3)))
    (2.0, True)
    """
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    U, S, Vt = np.linalg.svd(b.T @ a / len(a))
    D = np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / (a**2).sum(1).mean())
    return s, R, md - s * R @ ms


# --------------------------------------------------------------------------- the start


def _start(tracks, rig, source):
    """(R (V, 3, 3), t (V, 3), people, obs) from essential matrices and PnP."""
    import cv2

    V = len(rig)
    focal = np.array([float(np.mean(np.diag(c.K)[:2])) for c in rig])
    pairs, matches, together = _people_matches(tracks, focal, with_pairs=True)
    if not pairs:
        raise InputError(
            source,
            "keypoints",
            "one person seen by two cameras at once, in "
            f"at least {MIN_COMMON} joints over the frames",
            "none",
        )
    groups = _group(tracks, matches, together)
    obs, ids = _observations(tracks, groups, V)
    (a, b), (n, E) = max(pairs.items(), key=lambda kv: kv[1][0])
    xa, xb = obs[:, :, a].reshape(-1, 2), obs[:, :, b].reshape(-1, 2)
    ok = np.isfinite(xa).all(-1) & np.isfinite(xb).all(-1)
    _, Rb, tb, _ = cv2.recoverPose(E, xa[ok], xb[ok], np.eye(3))
    R, t = np.repeat(np.eye(3)[None], V, 0), np.zeros((V, 3))
    R[b], t[b] = Rb, tb[:, 0]
    placed = {a, b}
    while len(placed) < V:
        use = np.isin(np.arange(V), sorted(placed))
        X = triangulate_normalised(np.moveaxis(obs, 2, 3), R, t, use)  # (T, G, J, 3)
        best = None
        for c in set(range(V)) - placed:
            got = _pnp(X.reshape(-1, 3), obs[:, :, c].reshape(-1, 2), focal[c])
            if got is not None and (best is None or got[2] > best[1][2]):
                best = (c, got)
        if best is None:
            best = _place_by_pair(obs, R, t, placed, pairs, X)
        if best is None:
            missing = [rig[c].name for c in sorted(set(range(V)) - placed)]
            raise InputError(
                source,
                "keypoints",
                "every camera seeing a person that two placed cameras see",
                f"no pose for cameras {missing}",
            )
        c, (Rc, tc, _) = best
        R[c], t[c] = Rc, tc
        placed.add(c)
    return R, t, groups, (obs, ids), a, b


def _bone_median(X: np.ndarray) -> float:
    from rmpl.calibration.people_bundle import BONES

    d = np.concatenate([np.linalg.norm(X[..., p, :] - X[..., q, :], axis=-1).ravel()
                        for p, q in BONES])  # fmt: skip
    d = d[np.isfinite(d)]
    return float(np.median(d)) if len(d) >= 20 else np.nan


def _place_by_pair(obs, R, t, placed: set, pairs: dict, X: np.ndarray):
    """A camera no point of two placed cameras reaches: from its essential matrix with a
    placed camera, the baseline set so that bones are as long as in the placed cameras'
    reconstruction. Returns (camera, (R, t, inliers)) or None."""
    import cv2

    ref = _bone_median(X)
    if not np.isfinite(ref):
        return None
    best = None
    for (i, j), (n, E) in pairs.items():
        if (i in placed) == (j in placed):
            continue
        p, c = (i, j) if i in placed else (j, i)
        xp, xc = obs[:, :, p].reshape(-1, 2), obs[:, :, c].reshape(-1, 2)
        ok = np.isfinite(xp).all(-1) & np.isfinite(xc).all(-1)
        if ok.sum() < MIN_COMMON:
            continue
        if p < c:  # x_c = Rr x_p + tr
            _, Rr, tr, _ = cv2.recoverPose(E, xp[ok], xc[ok], np.eye(3))
            tr = tr[:, 0]
        else:
            _, Rr, tr, _ = cv2.recoverPose(E, xc[ok], xp[ok], np.eye(3))
            Rr, tr = Rr.T, -Rr.T @ tr[:, 0]
        Rc = Rr @ R[p]
        R2, t2 = R.copy(), t.copy()
        R2[c], t2[c] = Rc, Rr @ t[p] + tr
        use = np.isin(np.arange(len(R)), [p, c])
        X1 = triangulate_normalised(np.moveaxis(obs, 2, 3), R2, t2, use)
        scale = ref / _bone_median(X1)
        if np.isfinite(scale) and (best is None or n > best[1][2]):
            best = (c, (Rc, Rr @ t[p] + scale * tr, n))
    return best


# --------------------------------------------------------------------------- adjustment


def _frames(obs: np.ndarray, max_frames: int) -> np.ndarray:
    seen = (np.isfinite(obs).all(-1).sum(-1) >= 3).sum(-1) >= 2  # (T, G) two views
    frames = np.flatnonzero(seen.any(-1))
    if len(frames) > max_frames:
        frames = frames[np.linspace(0, len(frames) - 1, max_frames).round().astype(int)]
    return frames


def _problem(obs: np.ndarray, X: np.ndarray, focal: np.ndarray, ids: np.ndarray):
    """The bundle problem of the frames' observations (T', G, V, J, 2) and start X."""
    from rmpl.calibration.people_bundle import BONES, BundleProblem

    T, G, V, J, _ = obs.shape
    has = np.isfinite(X).all(-1)  # (T, G, J)
    index = np.full(has.shape, -1)
    index[has] = np.arange(has.sum())
    seen = np.isfinite(obs).all(-1) & has[:, :, None]  # (T, G, V, J)
    t, g, v, j = np.nonzero(seen)
    bones, lengths = [], []
    for k, (p, q) in enumerate(BONES):
        both = has[..., p] & has[..., q]
        tt, gg = np.nonzero(both)
        bones.append(np.c_[index[tt, gg, p], index[tt, gg, q]])
        lengths.append(gg * len(BONES) + k)
    prob = BundleProblem(
        v, index[t, g, j], obs[t, g, v, j], focal, np.concatenate(bones), np.concatenate(lengths)
    )
    prob.member = ids[t, g, v]
    return prob, X[has], index


def _start_lengths(X: np.ndarray) -> np.ndarray:
    from rmpl.calibration.people_bundle import BONES

    G = X.shape[1]
    out = np.zeros(G * len(BONES))
    for k, (p, q) in enumerate(BONES):
        d = np.linalg.norm(X[:, :, p] - X[:, :, q], axis=-1)  # (T, G), NaN where unseen
        med = np.full(G, 0.3)  # a bone never seen starts at 30 cm
        has = np.isfinite(d).any(0)
        med[has] = np.nanmedian(d[:, has], 0)
        out[np.arange(G) * len(BONES) + k] = med
    return out


def _check(keypoints, scores, rig: Rig, source) -> None:
    T, V = keypoints.shape[:2]
    if V < 2:
        raise InputError(source, "views", "two or more cameras to calibrate from people", V)
    if V != len(rig):
        raise InputError(source, "views", f"one view per camera of the intrinsics ({len(rig)})", V)
    for v, cam in enumerate(rig):
        ok = scores[:, v, :, :J17] >= MIN_SCORE
        if ok.sum() < MIN_COMMON:
            raise InputError(
                source,
                f"view {cam.name}",
                f"a person in view (keypoints with score >= {MIN_SCORE})",
                f"{int(ok.sum())} keypoints",
            )
        if cam.size is not None:
            xy = keypoints[:, v, :, :J17][ok]
            out = ((xy < -0.05 * np.array(cam.size)) | (xy > 1.05 * np.array(cam.size))).any(-1)
            if out.mean() > 0.05:
                raise InputError(
                    source,
                    f"camera {cam.name}.size",
                    f"intrinsics that fit the "
                    f"images: keypoints inside {cam.size[0]} x {cam.size[1]} px",
                    f"{100 * out.mean():.0f}% outside",
                )


def _heights(X: np.ndarray) -> np.ndarray:
    """Each person's stature from its joints (T, G, J, 3), NaN with too few frames."""
    from rmpl.anthropometry import estimate_height

    out = np.full(X.shape[1], np.nan)
    for g in range(X.shape[1]):
        if (
            np.isfinite(X[:, g, :J17]).all(-1).all(-1).sum() >= 10
            or np.isfinite(X[:, g, 11:17]).all(-1).all(-1).sum() >= 10
        ):
            try:
                out[g] = estimate_height(X[:, g, :J17], "coco17")
            except (InputError, ValueError):
                pass
    return out


def _scale(X, heights, seen, centres, cov, rig, height, camera_distance, source):
    """(factor, relative sd, description) to metres."""
    if camera_distance is not None:
        a, b, metres = camera_distance
        names = rig.names
        for n in (a, b):
            if n not in names:
                raise InputError(source, "--camera-distance", f"a camera of {names}", n)
        i, j = names.index(a), names.index(b)
        d = float(np.linalg.norm(centres[i] - centres[j]))
        sd = float(np.sqrt(np.trace(cov[i]) / 3 + np.trace(cov[j]) / 3)) / d
        return float(metres) / d, sd, f"the distance {a}-{b} = {float(metres):.3f} m"
    ok = np.isfinite(heights)
    if not ok.any():
        raise InputError(
            source,
            "keypoints",
            "a person whose legs and trunk are seen by two cameras in 10 frames (for the scale)",
            "none",
        )
    if height is not None:
        g = int(np.argmax(np.where(ok, seen, -1)))
        return (
            float(height) / heights[g],
            PROPORTION_SD,
            f"--height {float(height):.3f} m (person {g}, seen most)",
        )
    # Each person weighs by its observations: a short fragment (often of someone also
    # seen longer) says little; the people count as their effective number (Kish).
    w = np.asarray(seen, float)[ok]
    w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1 / len(w))
    n_eff = 1.0 / float((w**2).sum())
    rel = np.hypot(ADULT_STATURE_SD / ADULT_STATURE, PROPORTION_SD) / np.sqrt(n_eff)
    factor = float(np.exp((w * np.log(ADULT_STATURE / heights[ok])).sum()))
    return (
        factor,
        float(rel),
        (
            f"the adult body prior ({ADULT_STATURE:.2f} +- "
            f"{ADULT_STATURE_SD:.2f} m) over {_count(int(ok.sum()), 'person', 'people')}, "
            f"weighed by their observations (as {n_eff:.1f} independent)"
        ),
    )


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def _up_and_floor(X: np.ndarray):
    """(rotation world -> z up, origin, Floor) from the people's joints (T, G, J, 3) m."""
    from rmpl.geometry.floor import fit_floor

    P = X[..., :J17, :].reshape(-1, J17, 3)
    v = 0.5 * (P[:, 5] + P[:, 6]) - 0.5 * (P[:, 15] + P[:, 16])
    v = v[np.isfinite(v).all(-1)]
    if len(v) < 10:
        raise InputError(None, "keypoints", "people standing in 10 frames (for up)", len(v))
    u = v / np.linalg.norm(v, axis=-1, keepdims=True)
    up = np.median(u, 0)
    for _ in range(5):
        up = up / np.linalg.norm(up)
        near = u[u @ up > np.cos(np.radians(30))]
        up = near.mean(0) if len(near) >= 10 else up
    up = up / np.linalg.norm(up)
    ank = P[:, [15, 16]]
    h = ank @ up
    low = np.take_along_axis(
        ank, np.nanargmin(np.where(np.isfinite(h), h, np.inf), 1)[:, None, None].repeat(3, -1), 1
    )[:, 0]
    floor = fit_floor(low, up)
    n = np.asarray(floor.normal)
    return n, floor, low


def _world(n: np.ndarray, offset: float, low: np.ndarray, R0: np.ndarray) -> tuple:
    """(Rw, o): x' = Rw (x - o), z' along n, z' = 0 on the floor, x' along camera 0's x."""
    x = R0[0] - (R0[0] @ n) * n
    x = x / np.linalg.norm(x)
    Rw = np.stack([x, np.cross(n, x), n])
    centre = np.nanmedian(low, 0)
    o = centre - (centre @ n - offset) * n
    return Rw, o


def calibrate_from_people(
    keypoints: np.ndarray,
    scores: np.ndarray,
    intrinsics: Rig,
    *,
    start: Rig | None = None,
    height: float | None = None,
    camera_distance: tuple[str, str, float] | None = None,
    max_frames: int = 200,
    source=None,
) -> PeopleCalibration:
    """The cameras' poses from the people they film.

    Args:
        keypoints: shape (T, V, P, J, 2), pixels, NaN = missing; COCO-17 first (J >= 17).
            People need not keep their index across frames or views.
        scores: shape (T, V, P, J).
        intrinsics: the V cameras' K, distortion and size (their poses are never read).
        start: with ``--refine``, the calibration to correct (its poses are the start and
            its frame and scale are kept); None starts from the people alone.
        height: one person's standing height, metres (the person seen most).
        camera_distance: (camera, camera, metres) between two centres.
        max_frames: frames in the bundle adjustment, spread over the recording.

    Raises:
        InputError: one camera, a view without people, intrinsics that do not fit the
            images, or people too few to place every camera.
    """
    from rmpl.calibration.people_assoc import MAX_COST, reassociate
    from rmpl.calibration.people_bundle import adjust

    keypoints, scores = np.asarray(keypoints, float), np.asarray(scores, float)
    rig0 = intrinsics_only(intrinsics)
    _check(keypoints, scores, rig0, source)
    focal = np.array([float(np.mean(np.diag(c.K)[:2])) for c in rig0])
    tracks = _tracks(keypoints, scores, rig0)
    _check_motion(tracks, source)
    R, t, groups, (obs, ids), a, b = _initial(tracks, rig0, focal, start, source)
    rescale = start is None  # to about metres from the prior, so that bones mean metres
    for max_cost in (None, *MAX_COST):  # then who is who again, through the cameras found
        if max_cost is not None:
            rig_now = Rig(tuple(Camera(c.K, R[v], t[v], c.dist, c.size, c.name)
                                for v, c in enumerate(rig0)))  # fmt: skip
            obs, ids, groups = reassociate(keypoints, scores, rig_now, max_cost, MIN_SCORE,
                                           _normalised)  # fmt: skip
        frames = _frames(obs, max_frames)
        if not len(frames) or not groups:
            raise InputError(source, "keypoints", "frames where two cameras see one person")
        obs, ids = obs[frames], ids[frames]
        X = triangulate_normalised(np.moveaxis(obs, 2, 3), R, t, np.ones(len(rig0), bool))
        if rescale:
            s0, rescale = _prescale(X), False
            t, X = t * s0, X * s0
        prob, X0, index = _problem(obs, X, focal, ids)
        L0 = _start_lengths(X)
        res = adjust(prob, R, t, X0, L0, fixed=a, gauge_cam=b)
        R, t = res.R, res.t
    _check_kept(res, prob, rig0, source)
    return _finish(res, prob, (X, X0, index, L0), groups, frames, rig0, start,
                   (height, camera_distance), source)  # fmt: skip


def _finish(res, prob, points, groups, frames, rig0: Rig, start, scale_by, source):
    """The adjusted cameras in metres, z up on the floor (or in ``start``'s frame), with
    the report's figures."""
    from rmpl.calibration.people_bundle import centre_covariance

    X, X0, index, L0 = points
    Xb = np.full(X.shape, np.nan)
    Xb[index >= 0] = res.points
    cov = centre_covariance(res, len(L0))
    centres = -np.einsum("vji,vj->vi", res.R, res.t)
    seen = np.bincount(prob.point[res.kept], minlength=len(X0))
    per_person = np.array([seen[index[:, g][index[:, g] >= 0]].sum() for g in range(len(groups))])
    heights = _heights(Xb)
    scene = (Xb, heights, per_person, centres, cov)
    s, Rw, o, what, sd, floor = _frame(res, scene, rig0, start, *scale_by, source)
    Rn = np.einsum("vij,kj->vik", res.R, Rw)  # R Rw^T
    tn = s * (res.t + np.einsum("vij,j->vi", res.R, o / s))
    rig = Rig(tuple(Camera(c.K, Rn[v], tn[v], c.dist, c.size, c.name) for v, c in enumerate(rig0)))
    people = _people_table(groups, rig0, per_person, heights, s)
    out = _result(rig, res, prob, cov, s, (what, sd), people, frames, floor, start)
    _reliability(out, cov, centres, Xb)
    return out


def _reliability(out: PeopleCalibration, cov: np.ndarray, centres: np.ndarray, X) -> None:
    """Each centre's 1-sigma over its distance to the people (unitless), and a warning
    for every camera above :data:`UNRELIABLE_SD`: too little motion, too few views of
    the people, or people grouped wrongly leave a camera's place undecided."""
    middle = np.nanmedian(X.reshape(-1, 3), 0)
    dist = np.linalg.norm(centres - middle, axis=-1)
    out.centre_sd_relative = np.sqrt(np.linalg.eigvalsh(cov).max(-1).clip(0)) / dist
    for cam, r in zip(out.rig, out.centre_sd_relative, strict=True):
        if not r <= UNRELIABLE_SD:
            out.warnings.append(
                f"camera {cam.name}'s centre is uncertain by {100 * r:.0f}% of its distance "
                f"to the people (more than {100 * UNRELIABLE_SD:.0f}%): this calibration is "
                "not reliable; record more motion, over more of the floor, seen by more cameras"
            )


def _check_kept(res, prob, rig0: Rig, source) -> None:
    """Every camera keeps :data:`MIN_COMMON` observations that agree with the others: a
    camera the adjustment could not fit is refused, never written."""
    for v, cam in enumerate(rig0):
        mine = prob.cam == v
        kept = int((res.kept & mine).sum())
        if kept < MIN_COMMON:
            raise InputError(
                source,
                f"view {cam.name}",
                f"at least {MIN_COMMON} joints that agree with the other cameras (cameras "
                "started together or given --sync, intrinsics of these images)",
                f"{kept} of {int(mine.sum())}",
            )


def _result(rig, res, prob, cov, s, scale, people, frames, floor, start) -> PeopleCalibration:
    """The calibration with its per-camera RMS, centre uncertainty and what was used."""
    V = len(rig)
    errors = res.errors
    rms = np.array([np.sqrt(np.mean(errors[res.kept & (prob.cam == v)] ** 2)) for v in range(V)])
    sd_centre = s * np.sqrt(np.linalg.eigvalsh(cov).max(-1).clip(0))
    floor_text = "kept from the calibration refined"
    if floor is not None:
        floor_text = f"z = 0, {floor.source}"
    kept = (int(res.kept.sum()), len(res.kept))
    out = PeopleCalibration(rig, rms, sd_centre, *scale, people, frames, kept, floor_text)
    if start is not None:
        out.moved = moved(start, rig)
    return out


def _frame(res, scene, rig0: Rig, start: Rig | None, height, camera_distance, source):
    """Scale, world rotation and origin, with the scale's source, its uncertainty and the
    floor: from the people, or (``--refine``) kept from the calibration refined."""
    Xb, heights, per_person, centres, cov = scene
    if start is not None:
        return (*_keep_frame(res.R, res.t, start), None)
    s, sd, what = _scale(Xb, heights, per_person, centres, cov, rig0, height, camera_distance,
                         source)  # fmt: skip
    n, floor, low = _up_and_floor(Xb * s)
    Rw, o = _world(n, floor.height, low, res.R[0])
    return s, Rw, o, what, sd, floor


def _initial(tracks, rig0: Rig, focal: np.ndarray, start: Rig | None, source):
    """The start: cameras, people groups, observations and the two gauge cameras, from the
    people alone or (``--refine``) from the calibration to correct."""
    if start is None:
        return _start(tracks, rig0, source)
    R, t = start.R.copy(), start.t.copy()
    groups = _group(tracks, *_people_matches(tracks, focal))  # not through start: it moved
    obs = _observations(tracks, groups, len(rig0))
    b = int(np.argmax(np.linalg.norm(start.centers - start.centers[0], axis=-1)))
    return R, t, groups, obs, 0, b


def _people_table(groups, rig0: Rig, per_person: np.ndarray, heights: np.ndarray, s: float):
    """The report's people (:func:`rmpl.calibration.people_assoc.reassociate`'s persons):
    the frames each camera sees them in, their observations kept and stature."""
    return [
        {
            "person": g,
            "frames_per_camera": m["views"],
            "frames": m["frames"],
            "observations": int(per_person[g]),
            "stature_m": None if not np.isfinite(heights[g]) else round(float(heights[g] * s), 3),
        }
        for g, m in enumerate(groups)
    ]


def _prescale(X: np.ndarray) -> float:
    """A first scale to about metres from the prior, so that bone tolerances mean metres."""
    h = _heights(X)
    h = h[np.isfinite(h) & (h > 0)]
    return float(ADULT_STATURE / np.median(h)) if len(h) else 1.0


def _keep_frame(R, t, start: Rig):
    """The similarity that puts the adjusted cameras into ``start``'s frame and scale,
    fitted on the cameras that moved least: (s, Rw, o, description, sd)."""
    C = -np.einsum("vji,vj->vi", R, t)
    use = np.ones(len(C), bool)
    for _ in range(2):
        s, Rs, ts = similarity(C[use], start.centers[use])
        d = np.linalg.norm(s * C @ Rs.T + ts - start.centers, axis=-1)
        use = d <= max(2 * np.median(d), 0.02)
        if use.sum() < 3:
            use = np.ones(len(C), bool)
            break
    # x' = s Rs x + ts = Rw (x - o) * s  with Rw = Rs, o = -Rs^T ts / s
    o = -Rs.T @ ts / s
    return s, Rs, o * s, f"kept from the calibration refined ({int(use.sum())} cameras)", 0.0


def moved(before: Rig, after: Rig) -> list[dict]:
    """Per camera: rotation change (degrees) and centre change (metres)."""
    out = []
    for a, b in zip(before, after, strict=True):
        cosang = (np.trace(a.R @ b.R.T) - 1) / 2
        out.append(
            {
                "camera": a.name,
                "rotation_deg": round(float(np.degrees(np.arccos(np.clip(cosang, -1, 1)))), 3),
                "centre_m": round(float(np.linalg.norm(a.center - b.center)), 4),
            }
        )
    return out
