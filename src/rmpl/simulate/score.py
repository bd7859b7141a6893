"""Scores of every stage of a simulated capture against its truth.

A simulated recording knows everything: the cameras, each camera's time offset, where every
person's joints are and where they project. Each function here scores one stage of the
user's chain against that truth: the calibration (:func:`calibration_errors`), the
synchronisation (:func:`sync_errors`), the 2D detector (:func:`detection_scores`), the
identities (:func:`identity_scores`), the 3D poses (:func:`pose_scores`) and the joint
angles (:func:`joint_angles`, :func:`angle_errors`).

Every score is a plain dict that can be dumped to JSON: Python floats, ints, bools, lists,
strings and None. An undefined figure is None, never NaN, and a stage that could not be
scored says why in ``"note"`` (None when all went well).

Shape glossary: ``T`` frames, ``V`` views, ``N`` detection slots of one image, ``P`` true
people, ``Q`` predicted tracks, ``J`` joints. Units: pixels, metres (reported in mm),
seconds, degrees.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.transform import Rotation

from rmpl.calibration.people import similarity
from rmpl.calibration.sync import Sync
from rmpl.geometry.camera import Camera, Rig
from rmpl.metrics import mpjpe, pck
from rmpl.skeleton import COCO17, HALPE26
from rmpl.synth.generate.scenes import match_detections

__all__ = [
    "MIN_VISIBLE_JOINTS",
    "ORIENTATION_WEIGHT",
    "angle_errors",
    "calibration_errors",
    "detection_scores",
    "frames_on_common_clock",
    "identity_scores",
    "joint_angles",
    "pose_scores",
    "sync_errors",
]

#: The camera orientations' weight in the alignment of a found world to the true one: each
#: camera adds three points along its axes at this fraction of the centres' spread (RMS
#: distance from their mean). Small, so the centres decide where they can (three or more
#: cameras off one line) and a camera turned alone keeps its whole error; the orientations
#: settle what the centres leave open (the turn about the line of two cameras).
ORIENTATION_WEIGHT = 0.1
#: A true person is in a view, for the detector's recall, with this many visible joints.
MIN_VISIBLE_JOINTS = 4
_CALIBRATION_KEYS = ("rotation_deg", "centre_mm", "focal_pct", "principal_px")


def _num(x) -> float | None:
    """A finite value as a Python float, else None."""
    if x is None:
        return None
    x = float(x)
    return x if np.isfinite(x) else None


def _stats(values, keys=("max", "mean")) -> dict[str, float | None]:
    """Max / mean / median / p90 of the absolute values (an array, or floats and Nones
    where None is left out), None for none."""
    if not isinstance(values, np.ndarray):
        values = np.array([x for x in values if x is not None], float)
    v = np.abs(values)
    funcs = {"max": np.max, "mean": np.mean, "median": np.median,
             "p90": lambda a: np.percentile(a, 90)}  # fmt: skip
    return {k: _num(funcs[k](v)) if v.size else None for k in keys}


# --------------------------------------------------------------------------- calibration


def _world_similarity(found: list[Camera], truth: list[Camera]):
    """(s, R, t) with true X ~ s R found X + t, from the centres and the orientations.

    The found and true centres go to Umeyama (:func:`rmpl.calibration.people.similarity`)
    with, for each camera, three more points along its axes (the rows of R) at
    :data:`ORIENTATION_WEIGHT` times each world's own centre spread: a found world that is
    the true one moved by a similarity maps onto it exactly.
    """
    cf = np.array([c.center for c in found])  # (V, 3)
    cg = np.array([c.center for c in truth])
    spread_f = np.sqrt(((cf - cf.mean(0)) ** 2).sum(-1).mean())
    spread_g = np.sqrt(((cg - cg.mean(0)) ** 2).sum(-1).mean())
    if not (spread_f > 0 and spread_g > 0):
        return None
    Rf, Rg = np.array([c.R for c in found]), np.array([c.R for c in truth])  # (V, 3, 3)
    axes_f = cf[:, None] + ORIENTATION_WEIGHT * spread_f * Rf  # (V, 3 axes, 3)
    axes_g = cg[:, None] + ORIENTATION_WEIGHT * spread_g * Rg
    src = np.concatenate([cf, axes_f.reshape(-1, 3)])
    dst = np.concatenate([cg, axes_g.reshape(-1, 3)])
    return similarity(src, dst)


def _camera_errors(f: Camera, g: Camera, transform) -> dict[str, float | None]:
    """One camera's errors; rotation and centre None without a transform."""
    out = {
        "rotation_deg": None,
        "centre_mm": None,
        "focal_pct": _num(100 * (f.K[0, 0] - g.K[0, 0]) / g.K[0, 0]),
        "principal_px": _num(np.linalg.norm(f.K[:2, 2] - g.K[:2, 2])),
    }
    if transform is not None:
        s, R, t = transform
        turn = Rotation.from_matrix((f.R @ R.T) @ g.R.T)  # found orientation in the true world
        out["rotation_deg"] = _num(np.degrees(turn.magnitude()))
        out["centre_mm"] = _num(1000 * np.linalg.norm(s * R @ f.center + t - g.center))
    return out


def calibration_errors(found: Rig, truth: Rig, align: bool = True) -> dict:
    """Each camera's errors of a found calibration against the true one.

    Cameras are matched by name. With ``align``, the found world (a calibration from people
    or a board has its own origin, scale and orientation) is first moved onto the true one
    by the similarity that best maps the found centres and orientations onto the true ones
    (:func:`_world_similarity`; two cameras at least); without, both are taken to be in the
    same world.

    Args:
        found, truth: the rigs; cameras matched by ``name``.
        align: align the found world to the true one first.

    Returns:
        ``cameras``: name -> ``rotation_deg`` (geodesic angle between the found and true
        orientations), ``centre_mm``, ``focal_pct`` (found fx minus true fx, % of the true
        fx, signed), ``principal_px`` (distance of the principal points); ``max`` and
        ``mean`` of each (absolute values) over the cameras; ``scale``: found metres per
        true metre (None without alignment); ``aligned``; ``missing`` (true cameras not
        found), ``extra`` (found cameras not in the truth); ``note``.
    """
    names = [n for n in truth.names if n in found.names]
    f = [found[found.names.index(n)] for n in names]
    g = [truth[truth.names.index(n)] for n in names]
    out = {"aligned": bool(align), "scale": None, "cameras": {},
           "missing": [n for n in truth.names if n not in found.names],
           "extra": [n for n in found.names if n not in truth.names], "note": None}  # fmt: skip
    transform = (1.0, np.eye(3), np.zeros(3))  # the same world
    if align:
        transform = _world_similarity(f, g) if len(names) >= 2 else None
        if transform is None:
            out["note"] = "no alignment: it needs two cameras found at distinct places"
        else:
            out["scale"] = _num(1.0 / transform[0])
    if not names:
        out["note"] = "no camera of the truth was found"
    cams = {n: _camera_errors(a, b, transform) for n, a, b in zip(names, f, g, strict=True)}
    out["cameras"] = cams
    for key in _CALIBRATION_KEYS:
        out[key] = _stats(c[key] for c in cams.values())
    if out["missing"] and out["note"] is None:
        out["note"] = f"cameras not found: {', '.join(out['missing'])}"
    return out


# --------------------------------------------------------------------------- synchronisation


def _whole(x: float) -> int:
    """Nearest whole frame, halves up (not to even)."""
    return int(np.floor(x + 0.5))


def sync_errors(found: Sync | None, truth: Sync) -> dict:
    """Each camera's found time offset against the true one, in that camera's frames.

    Both offsets are taken relative to the truth's reference camera (``truth.views[0]``):
    each file's offset of that camera is subtracted from its others, so two files that name
    a different reference first compare alike.

    Args:
        found: what ``rmpl sync`` found, None when it refused.
        truth: the true offsets; its ``fps`` turn seconds into each camera's frames.

    Returns:
        ``reference``; ``refused``; ``cameras``: name -> ``true_frames``, ``found_frames``,
        ``error_frames`` (found minus true, fractional), ``exact`` (the same whole frame:
        both rounded to the nearest frame agree), None for a camera the found file lacks;
        ``max_abs_error_frames``, ``all_exact``; ``note``.
    """
    ref = truth.views[0]
    out = {"reference": ref, "refused": found is None, "cameras": dict.fromkeys(truth.views),
           "max_abs_error_frames": None, "all_exact": None, "note": None}  # fmt: skip
    if found is None:
        out["note"] = "refused: no offsets were found"
        return out
    if ref not in found.views:
        out["note"] = f"the found offsets lack the reference camera {ref!r}"
        return out
    found_ref = found.offsets[found.views.index(ref)]
    missing = []
    for v, name in enumerate(truth.views):
        if name not in found.views:
            missing.append(name)
            continue
        fps = float(truth.fps[v])
        true_frames = float(truth.offsets[v] - truth.offsets[0]) * fps
        found_frames = float(found.offsets[found.views.index(name)] - found_ref) * fps
        out["cameras"][name] = {
            "true_frames": true_frames,
            "found_frames": found_frames,
            "error_frames": found_frames - true_frames,
            "exact": _whole(found_frames) == _whole(true_frames),
        }
    scored = [c for c in out["cameras"].values() if c is not None]
    out["max_abs_error_frames"] = _stats((c["error_frames"] for c in scored), ("max",))["max"]
    out["all_exact"] = all(c["exact"] for c in scored) and not missing
    if missing:
        out["note"] = f"cameras without a found offset: {', '.join(missing)}"
    return out


# --------------------------------------------------------------------------- the 2D detector


def _common_joints(keypoints, scores, truth_2d, visible):
    """The detector's and the truth's joints on one set: the first 17 (COCO-17) if J differ."""
    if keypoints.shape[-2] == truth_2d.shape[-2]:
        return keypoints, scores, truth_2d, visible
    J = COCO17.num_joints
    if min(keypoints.shape[-2], truth_2d.shape[-2]) < J:
        raise ValueError(
            f"joint sets differ and one has fewer than {J} joints: "
            f"{keypoints.shape[-2]}, {truth_2d.shape[-2]}"
        )
    return keypoints[..., :J, :], scores[..., :J], truth_2d[..., :J, :], visible[..., :J]


def _check_detections(keypoints, scores, truth_2d, visible):
    """The arrays checked and on one joint set; a truth without people gets one seen nowhere
    (so the gathers of :func:`_pixel_errors` work)."""
    keypoints, scores = np.asarray(keypoints, float), np.asarray(scores, float)
    truth_2d, visible = np.asarray(truth_2d, float), np.asarray(visible, bool)
    if keypoints.ndim != 5 or scores.shape != keypoints.shape[:-1]:
        raise ValueError(f"keypoints (T, V, N, J, 2), scores (T, V, N, J): got "
                         f"{keypoints.shape}, {scores.shape}")  # fmt: skip
    if truth_2d.ndim != 5 or visible.shape != truth_2d.shape[:-1]:
        raise ValueError(f"truth_2d (T, V, P, J, 2), visible (T, V, P, J): got "
                         f"{truth_2d.shape}, {visible.shape}")  # fmt: skip
    if keypoints.shape[:2] != truth_2d.shape[:2]:
        raise ValueError(f"frames and views differ: {keypoints.shape[:2]}, {truth_2d.shape[:2]}")
    keypoints, scores, truth_2d, visible = _common_joints(keypoints, scores, truth_2d, visible)
    if truth_2d.shape[2] == 0:
        truth_2d = np.full((*truth_2d.shape[:2], 1, *truth_2d.shape[3:]), np.nan)
        visible = np.zeros(truth_2d.shape[:-1], bool)
    return keypoints, scores, truth_2d, visible


def _pixel_errors(keypoints, detected, truth_2d, visible, match) -> np.ndarray:
    """(T, V, N, J) pixel error of each matched slot's detected joints that its true person
    shows; NaN elsewhere."""
    mine = np.take_along_axis(truth_2d, match.clip(0)[..., None, None], axis=2)  # (T,V,N,J,2)
    shown = np.take_along_axis(visible, match.clip(0)[..., None], axis=2)  # (T, V, N, J)
    scored = (match >= 0)[..., None] & detected & shown
    return np.where(scored, np.linalg.norm(keypoints - mine, axis=-1), np.nan)


def _match_all(keypoints, detected, truth_2d, visible) -> np.ndarray:
    """(T, V, N) true person of each detection slot, -1 for none (:func:`match_detections`).

    Every person with a visible joint may be matched; joints whose projection is NaN are
    placed at the person's mean projection (``match_detections`` measures each body's size).
    """
    T, V, N = keypoints.shape[:3]
    seen = visible.any(-1)  # (T, V, P)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a person projected nowhere
        centre = np.nanmean(truth_2d, axis=-2)  # (T, V, P, 2)
    filled = np.where(np.isfinite(truth_2d), truth_2d, centre[..., None, :])  # (T, V, P, J, 2)
    weights = np.where(detected, 1.0, 0.0)
    match = np.full((T, V, N), -1, int)
    for t, v in zip(*np.nonzero(detected.any((-1, -2)) & seen.any(-1)), strict=True):
        match[t, v] = match_detections(keypoints[t, v], weights[t, v], filled[t, v], seen[t, v])
    return match


def _detection_summary(match, in_view, has_det, errors, joint_names) -> dict:
    """Recall, precision and pixel errors of one block (all views or one)."""
    P = in_view.shape[-1]
    found_people = (match[..., :, None] == np.arange(P)).any(-2)  # (T, V, P)
    num_true, num_det = int(in_view.sum()), int(has_det.sum())
    matched = int(((match >= 0) & has_det).sum())
    e = errors[np.isfinite(errors)]
    per_joint = {}
    for j, name in enumerate(joint_names):
        ej = errors[..., j][np.isfinite(errors[..., j])]
        per_joint[name] = _stats(ej, ("median", "mean"))
    return {
        "people_in_view": num_true,
        "detections": num_det,
        "recall": _num(int((found_people & in_view).sum()) / num_true) if num_true else None,
        "precision": _num(matched / num_det) if num_det else None,
        "joints_scored": int(e.size),
        "error_px": _stats(e, ("median", "mean", "p90")),
        "per_joint_px": per_joint,
    }


def detection_scores(
    keypoints: np.ndarray,
    scores: np.ndarray,
    truth_2d: np.ndarray,
    visible: np.ndarray,
    threshold: float = 0.5,
    views: Sequence[str] | None = None,
) -> dict:
    """The 2D detector's people and joints against the true projections.

    In each frame and view the detection slots are matched to the true people by
    :func:`rmpl.synth.generate.scenes.match_detections` (Hungarian, on the median pixel
    distance over the detected joints relative to the body's projected size); a detection is
    a slot with a joint of score >= ``threshold``, and only such joints are used. When the
    detector's joint set differs from the truth's, both are scored on their first 17 joints
    (COCO-17, the first 17 of every set in :mod:`rmpl.skeleton`).

    Args:
        keypoints: (T, V, N, J, 2) pixels, NaN = missing. scores: (T, V, N, J), 0 = missing.
        truth_2d: (T, V, P, J', 2) the true projections of the P people's joints, pixels.
        visible: (T, V, P, J') bool, in the image and not hidden.
        threshold: a joint is detected at this score or above.
        views: the V views' names (default "0", "1", ...).

    Returns:
        Over all views, and per view in ``views`` (name -> the same keys): ``recall`` (true
        people in view, with at least :data:`MIN_VISIBLE_JOINTS` visible joints, matched
        by a detection), ``precision`` (detections matched to a true person with a visible
        joint / detections), ``people_in_view``, ``detections``, ``joints_scored``,
        ``error_px`` (``median``, ``mean``, ``p90`` of the pixel error of the matched
        people's detected and visible joints), ``per_joint_px`` (joint name -> median,
        mean); ``joints`` (the joint set scored); ``note``.
    """
    keypoints, scores, truth_2d, visible = _check_detections(keypoints, scores, truth_2d, visible)
    J, V = keypoints.shape[-2], keypoints.shape[1]
    detected = (scores >= threshold) & np.isfinite(keypoints).all(-1)  # (T, V, N, J)
    match = _match_all(keypoints, detected, truth_2d, visible)
    errors = _pixel_errors(keypoints, detected, truth_2d, visible, match)
    skeleton = {17: COCO17, 26: HALPE26}.get(J)
    names = list(skeleton.joints) if skeleton else [str(j) for j in range(J)]
    in_view = visible.sum(-1) >= MIN_VISIBLE_JOINTS
    has_det = detected.any(-1)
    blocks = (match, in_view, has_det, errors)
    out = _detection_summary(*blocks, names)
    views = [str(v) for v in range(V)] if views is None else list(views)
    out["views"] = {n: _detection_summary(*(b[:, v] for b in blocks), names)
                    for v, n in enumerate(views)}  # fmt: skip
    out["joints"] = skeleton.name if skeleton else f"{J} joints"
    out["note"] = None if in_view.any() else "no true person is in view"
    return out


# --------------------------------------------------------------------------- identities


def _present(points: np.ndarray) -> np.ndarray:
    """(T, P) a track has a joint in the frame."""
    return np.isfinite(points).all(-1).any(-1)


def _track_distances(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(T, Q, P) mean distance over the joints both have, metres; inf where none."""
    T, Q, P = pred.shape[0], pred.shape[1], truth.shape[1]
    out = np.full((T, Q, P), np.inf)
    for p in range(P):  # one true person at a time: (T, Q, J) in memory
        d = np.linalg.norm(pred - truth[:, p, None], axis=-1)  # (T, Q, J)
        ok = np.isfinite(d)
        n = ok.sum(-1)
        out[:, :, p] = np.where(n > 0, np.where(ok, d, 0).sum(-1) / np.maximum(n, 1), np.inf)
    return out


def _tracks_per_person(dist: np.ndarray, threshold_m: float) -> list[int]:
    """How many distinct tracks the per-frame Hungarian matching gives each true person."""
    cover = [set() for _ in range(dist.shape[2])]
    for t in np.nonzero((dist <= threshold_m).any((1, 2)))[0]:
        cost = np.where(dist[t] <= threshold_m, dist[t], 1e6)  # (Q, P)
        for q, p in zip(*linear_sum_assignment(cost), strict=True):
            if cost[q, p] <= threshold_m:
                cover[p].add(int(q))
    return [len(c) for c in cover]


def _check_tracks(pred: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pred, truth = np.asarray(pred, float), np.asarray(truth, float)
    if pred.ndim != 4 or truth.ndim != 4 or pred.shape[-1] != 3:
        raise ValueError(f"pred and truth must be (T, Q, J, 3), (T, P, J, 3): got "
                         f"{pred.shape}, {truth.shape}")  # fmt: skip
    if pred.shape[0] != truth.shape[0] or pred.shape[2:] != truth.shape[2:]:
        raise ValueError(f"frames and joints must agree: {pred.shape}, {truth.shape}")
    return pred, truth


def identity_scores(pred: np.ndarray, truth: np.ndarray, threshold_m: float = 0.5) -> dict:
    """How well the predicted tracks keep the true people's identities.

    A track matches a true person in a frame when the mean distance over the joints both
    have is at most ``threshold_m``. IDF1 (Ristani et al. 2016, "Performance measures and a
    data set for multi-target, multi-camera tracking"): one global one-to-one assignment of
    tracks to true people maximising the frames they match (IDTP); every other frame a track
    is present is an IDFP, every other frame a person is present an IDFN; IDF1 = 2 IDTP /
    (2 IDTP + IDFP + IDFN).

    Args:
        pred: (T, Q, J, 3) predicted tracks, metres; NaN = absent / missing.
        truth: (T, P, J, 3) true people on the same frames and joints; NaN = absent.
        threshold_m: metres.

    Returns:
        ``num_tracks`` (tracks present in a frame at least), ``num_people``,
        ``tracks_per_person`` (per true person, the distinct tracks the per-frame Hungarian
        matching gives it), ``max_tracks_per_person``, ``idf1``, ``idp`` (IDTP / track
        presences), ``idr`` (IDTP / true presences), ``idtp``, ``idfp``, ``idfn``,
        ``assignment`` (per true person the track of the global assignment, None for none),
        ``threshold_m``, ``note``.
    """
    pred, truth = _check_tracks(pred, truth)
    dist = _track_distances(pred, truth)  # (T, Q, P)
    tp = (dist <= threshold_m).sum(0)  # (Q, P) frames each pair matches
    rows, cols = linear_sum_assignment(tp, maximize=True)
    assignment: list[int | None] = [None] * truth.shape[1]
    for q, p in zip(rows, cols, strict=True):
        if tp[q, p] > 0:
            assignment[p] = int(q)
    idtp = int(tp[rows, cols].sum())
    num_pred, num_true = int(_present(pred).sum()), int(_present(truth).sum())
    per_person = _tracks_per_person(dist, threshold_m)
    total = num_pred + num_true
    return {
        "num_tracks": int(_present(pred).any(0).sum()),
        "num_people": int(_present(truth).any(0).sum()),
        "tracks_per_person": per_person,
        "max_tracks_per_person": max(per_person, default=None),
        "idf1": 2 * idtp / total if total else None,
        "idp": idtp / num_pred if num_pred else None,
        "idr": idtp / num_true if num_true else None,
        "idtp": idtp,
        "idfp": num_pred - idtp,
        "idfn": num_true - idtp,
        "assignment": assignment,
        "threshold_m": float(threshold_m),
        "note": None if total else "neither tracks nor people in any frame",
    }


# --------------------------------------------------------------------------- 3D poses


def _pose_block(pred: np.ndarray, truth: np.ndarray, pck_mm: Sequence[float]) -> dict:
    """MPJPE (mm), PCK (%) and coverage of (*, J, 3) predictions against the truth."""
    present = np.isfinite(truth).all(-1)
    covered = present & np.isfinite(pred).all(-1)
    n = int(present.sum())
    return {
        "mpjpe_mm": _num(1000 * mpjpe(pred, truth)) if covered.any() else None,
        "pck": {f"{mm:g}": _num(pck(pred, truth, mm / 1000)) if n else None for mm in pck_mm},
        "coverage": int(covered.sum()) / n if n else None,
        "joints_true": n,
    }


def pose_scores(
    pred: np.ndarray,
    truth: np.ndarray,
    joints: Sequence[int] | None = None,
    pck_mm: Sequence[float] = (50, 100, 150),
    threshold_m: float = 0.5,
) -> dict:
    """3D poses against the truth, each true person through its track of the identity
    assignment (:func:`identity_scores`, on all joints), so a swap costs.

    Args:
        pred: (T, Q, J, 3) predicted tracks, metres; NaN = missing.
        truth: (T, P, J, 3) true people on the same frames and joint set; NaN = absent.
        joints: joint indices scored (all if None); the identities use every joint.
        pck_mm: PCK thresholds, millimetres.
        threshold_m: the identity matching's threshold, metres.

    Returns:
        ``overall`` and ``people`` (one per true person): ``mpjpe_mm`` (over the joints both
        have), ``pck`` (threshold in mm -> % of the true joints within it; a missing
        prediction counts as wrong, :func:`rmpl.metrics.pck`), ``coverage`` (fraction of the
        true joints with a prediction), ``joints_true``, and per person ``track``;
        ``identity`` (:func:`identity_scores`); ``note``.
    """
    pred, truth = _check_tracks(pred, truth)
    identity = identity_scores(pred, truth, threshold_m)
    paired = np.full_like(truth, np.nan)  # (T, P, J, 3) each true person's track
    for p, q in enumerate(identity["assignment"]):
        if q is not None:
            paired[:, p] = pred[:, q]
    if joints is not None:
        paired, truth = paired[..., list(joints), :], truth[..., list(joints), :]
    people = []
    for p, q in enumerate(identity["assignment"]):
        people.append({"track": q} | _pose_block(paired[:, p], truth[:, p], pck_mm))
    overall = _pose_block(paired, truth, pck_mm)
    lost = [p for p, q in enumerate(identity["assignment"]) if q is None]
    note = f"true people without a track: {lost}" if lost else None
    if overall["joints_true"] == 0:
        note = "no true joint to score"
    return {"overall": overall, "people": people, "identity": identity, "note": note}


def frames_on_common_clock(
    pred_frames: np.ndarray, truth_frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs of the frames a run and the truth share.

    Both count the reference camera's frames (a run's ``Poses3D.frames``, the truth's).

    Returns:
        (pred_index, truth_index), each (n,) int, in increasing frame order.

    >>> frames_on_common_clock(np.array([3, 4, 5, 7]), np.arange(6))
    (array([0, 1, 2]), array([3, 4, 5]))
    """
    a, b = np.asarray(pred_frames), np.asarray(truth_frames)
    if len(np.unique(a)) != len(a) or len(np.unique(b)) != len(b):
        raise ValueError("frame numbers must be distinct")
    _, ia, ib = np.intersect1d(a, b, assume_unique=True, return_indices=True)
    return ia, ib


# --------------------------------------------------------------------------- joint angles


def _unit(x: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _pelvis_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(forward, up) unit vectors (..., 3) of the pelvis frame of HALPE-26 points.

    Right: left hip to right hip. Up: from the hips' midpoint to the neck (the shoulders'
    midpoint where the neck is missing), made perpendicular to right. Forward: up x right.
    """
    H = HALPE26.index
    left, right = points[..., H("left_hip"), :], points[..., H("right_hip"), :]
    shoulders = points[..., [H("left_shoulder"), H("right_shoulder")], :].mean(-2)
    neck = points[..., H("neck"), :]
    top = np.where(np.isfinite(neck).all(-1, keepdims=True), neck, shoulders)
    r = _unit(right - left)
    u = top - (left + right) / 2
    u = _unit(u - (u * r).sum(-1, keepdims=True) * r)
    return np.cross(u, r), u


def joint_angles(points: np.ndarray) -> dict[str, np.ndarray]:
    """Knee and hip flexion of HALPE-26 poses, degrees.

    Knee flexion: 180 minus the angle hip-knee-ankle (0 = straight leg). Hip flexion: the
    thigh (hip to knee) in the pelvis frame (:func:`_pelvis_frame`), projected onto the
    sagittal plane (forward, up): its angle from the trunk's downward axis, positive
    forward (the first angle of the ISB flexion-adduction-rotation sequence; 0 = thigh
    along the trunk, 90 = thigh horizontal in front).

    Args:
        points: (..., 26, 3) HALPE-26 joints, metres; NaN = missing.

    Returns:
        ``knee_flexion_left``, ``knee_flexion_right``, ``hip_flexion_left``,
        ``hip_flexion_right``: each shape (...), NaN where a joint needed is missing.

    >>> leg = np.full((26, 3), np.nan)
    >>> leg[[13, 15]] = [[0, 0, 0.5], [0, 0, 0.0]]  # left knee, ankle
    >>> leg[11] = [0, 0.4, 0.5]  # left hip, thigh horizontal
    >>> round(float(joint_angles(leg)["knee_flexion_left"]), 6)
    90.0
    """
    points = np.asarray(points, float)
    if points.shape[-2:] != (HALPE26.num_joints, 3):
        raise ValueError(f"points must be HALPE-26, shape (..., 26, 3), got {points.shape}")
    H = HALPE26.index
    forward, up = _pelvis_frame(points)
    out = {}
    for side in ("left", "right"):
        hip, knee = points[..., H(f"{side}_hip"), :], points[..., H(f"{side}_knee"), :]
        ankle = points[..., H(f"{side}_ankle"), :]
        cos = (_unit(hip - knee) * _unit(ankle - knee)).sum(-1)
        out[f"knee_flexion_{side}"] = 180 - np.degrees(np.arccos(np.clip(cos, -1, 1)))
        thigh = knee - hip
        along = -(thigh * up).sum(-1)  # down the trunk
        out[f"hip_flexion_{side}"] = np.degrees(np.arctan2((thigh * forward).sum(-1), along))
    return out


def angle_errors(pred: np.ndarray, truth: np.ndarray) -> dict:
    """Per angle of :func:`joint_angles`: errors of predicted against true HALPE-26 poses.

    Args:
        pred, truth: (..., 26, 3), the same leading shape, metres; NaN = missing.

    Returns:
        angle name -> ``mae_deg`` (mean absolute error), ``rmse_deg``, ``poses`` (where
        both angles exist; the errors None when there are none).
    """
    a, b = joint_angles(pred), joint_angles(truth)
    out = {}
    for name in a:
        e = a[name] - b[name]
        e = e[np.isfinite(e)]
        out[name] = {
            "mae_deg": _num(np.abs(e).mean()) if e.size else None,
            "rmse_deg": _num(np.sqrt((e**2).mean())) if e.size else None,
            "poses": int(e.size),
        }
    return out
