"""Compare 3D methods on identical 2D input: triangulation, robust triangulation, RMPL.

A method maps per-person multi-view keypoints ``(N, V, J, 2)`` + scores ``(N, V, J)`` and a
rig to COCO-17 joints ``(N, 17, 3)``, or HALPE-26 ``(N, 26, 3)`` (a lifter that outputs it:
its first 17 joints are COCO-17, the joints scored, so every table stays comparable; its
head top and neck give a third PCP, "own"). Every method of one run sees the same per-person 2D
input: the 2D people are associated (or taken) once per view subset, perturbed once per
condition (keypoint dropout, calibration noise), and then handed to every method.

Protocols (chosen per dataset, stated in every output header):

- **multi-person, detected 2D** (Shelf, Campus, Panoptic with a user file): per view the
  detections are grouped into people (Shelf's OpenPose candidates with their part
  affinities; other sources are people already); the people of the views in use are
  associated by ray distance (:func:`rmpl.pipeline.association.associate`), re-run for every view
  subset (a single view: every 2D person is a 3D person); each method's estimates are
  matched to the ground-truth people by Hungarian assignment on the mean distance of the
  evaluated joints (0.5 m gate). An unmatched person counts as missing: outside MPJPE,
  against coverage, PCK and PCP.
- **single person** (Human3.6M): in each view the one detected person (the highest total
  score when there are several) is the subject.
- **given association** (2D annotations, or 2D projected from the ground truth): slot ``n``
  of every view is ground-truth person ``n``; no association, no matching.

Ground truth is mapped to COCO-17 by joint name (:func:`rmpl.data.base.coco17_by_name`)
and only the joints it defines are scored (Shelf/Campus: the 12 limb joints; H36M: the
limbs and the nose; Panoptic: all 17). PCP (Shelf, Campus) uses the Shelf-14 joints with
the predicted neck and head top derived by :func:`rmpl.skeleton.convert`, by the
literature's conversion, or (HALPE-26 methods) the method's own
(:data:`rmpl.evaluate.scoring.PCP_CONVERSIONS`).

Metrics (:mod:`rmpl.evaluate.scoring`) are computed per view subset (and calibration-noise
repetition) and averaged in the tables (:mod:`rmpl.evaluate.tables`).

Shape glossary: ``T`` frames, ``V`` views, ``P`` ground-truth people, ``N`` people given to
a method, ``J`` joints. Units: metres inside, millimetres in the tables.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace

import numpy as np

from rmpl.data.base import MultiViewDataset
from rmpl.errors import InputError
from rmpl.evaluate.evalset import MATCH_GATE, EvalSet, gt_coco, reprojection_check
from rmpl.evaluate.methods import Method
from rmpl.geometry import Rig
from rmpl.io.poses import Poses3D
from rmpl.skeleton import COCO17, HALPE26, convert

__all__ = [
    "EvalConfig",
    "Evaluation",
    "evaluate",
    "evaluate_poses",
    "multi_view_floor",
    "view_subsets",
]


def view_subsets(num_views: int, spec: str) -> dict[str, list[tuple[int, ...]]]:
    """View subsets from a spec like ``all,pairs`` or ``1,2,3,4,5`` (k = every k-subset).

    Raises:
        ValueError: an unknown item, or a view count outside 1..``num_views``.
    """
    out = {}
    for item in spec.split(","):
        item = item.strip()
        if item == "all":
            out[f"{num_views} views"] = [tuple(range(num_views))]
            continue
        if item == "pairs":
            item = "2"
        if not item.isdigit():
            raise ValueError(f"--views: expected 'all', 'pairs' or view counts, got {item!r}")
        k = int(item)
        if not 1 <= k <= num_views:
            raise ValueError(
                f"--views: {k} view(s) requested but the dataset's rig has {num_views} cameras"
            )
        subs = list(itertools.combinations(range(num_views), k))
        label = f"{k} view" + ("s" if k > 1 else "")
        out[label + (f" (mean of {len(subs)})" if len(subs) > 1 else "")] = subs
    return out


# --------------------------------------------------------------------------- configuration


def _plain(values) -> list[float]:
    """Numbers as plain Python floats, so a message prints 0.0 and not np.float64(0.0)."""
    return [float(v) for v in values]


@dataclass(frozen=True)
class EvalConfig:
    """Test-time perturbations and metric thresholds, identical for every method.

    Attributes:
        dropout: keypoint removal probabilities to sweep (thesis 6.11.1); each keypoint of
            the per-person input is removed (NaN, score 0) with probability p.
        calib_noise: (degrees, metres) standard deviations of the extrinsic noise (thesis
            6.11.3), or None. When set, every table has a clean and a noisy row.
        calib_reps: repetitions (independent noise draws) averaged for ``calib_noise``.
        seed: seed of every random draw (dropout masks, calibration noise, 2D noise).
        pck_threshold: PCK distance threshold, metres.
        match_gate: largest mean joint distance of a prediction matched to a person, metres.
        fps: frame rate of the sequence methods (:mod:`rmpl.evaluate.sequences`), frames/s.
    """

    dropout: tuple[float, ...] = (0.0,)
    calib_noise: tuple[float, float] | None = None
    calib_reps: int = 5
    seed: int = 0
    pck_threshold: float = 0.150
    match_gate: float = MATCH_GATE
    fps: float = 25.0

    def __post_init__(self) -> None:
        if not self.dropout or any(not 0 <= p < 1 for p in self.dropout):
            raise ValueError(f"--dropout: probabilities in [0, 1), got {_plain(self.dropout)}")
        if self.calib_noise is not None:
            deg, m = self.calib_noise
            if not (deg >= 0 and m >= 0) or deg == m == 0:
                got = tuple(_plain(self.calib_noise))
                raise ValueError(f"--calib-noise: DEG,MM >= 0 and not both 0, got {got}")
        if self.calib_reps < 1:
            raise ValueError(f"--calib-reps must be >= 1, got {self.calib_reps}")
        if not self.pck_threshold > 0:
            raise ValueError(f"--pck must be > 0, got {self.pck_threshold}")
        if not self.fps > 0:
            raise ValueError(f"--fps must be > 0, got {float(self.fps)}")

    def conditions(self) -> list[tuple[float, tuple[float, float] | None]]:
        """Every (dropout p, calibration noise or None) pair evaluated."""
        calibs = [None] if self.calib_noise is None else [None, self.calib_noise]
        return [(p, c) for c in calibs for p in self.dropout]


# --------------------------------------------------------------------------- evaluation


@dataclass
class Evaluation:
    """Everything one run measured.

    Attributes:
        evset: the dataset and its 2D.
        config: the perturbations.
        methods: method names, in order.
        joints: COCO-17 indices scored.
        view_sets: view label -> subsets.
        gt: per view label, per subset entry: ground truth COCO-17 (n, 17, 3) of the
            scored poses (one per frame and present person, all parts).
        native: the same poses in the dataset's joint set (for PCP), (n, J_gt, 3).
        person: (n,) person label per pose; clip: (n,) clip label per pose.
        preds: (view label, condition index, method) -> per subset entry, the COCO-17
            predictions (n, 17, 3) (the first 17 joints of a HALPE-26 method).
        extra: the same keys -> per subset entry, the HALPE-26 joints after COCO-17
            (n, 9, 3): head top, neck, mid-hip, feet; all NaN for a COCO-17 method.
        skeletons: method -> the joint set it output ("coco17", or "halpe26" when it gave
            HALPE-26 anywhere).
    """

    evset: EvalSet
    config: EvalConfig
    methods: list[str]
    joints: list[int]
    view_sets: dict[str, list[tuple[int, ...]]]
    gt: np.ndarray = field(default_factory=lambda: np.zeros((0, 17, 3)))
    native: np.ndarray = field(default_factory=lambda: np.zeros((0, 14, 3)))
    person: np.ndarray = field(default_factory=lambda: np.zeros(0, str))
    clip: np.ndarray = field(default_factory=lambda: np.zeros(0, str))
    preds: dict[tuple[str, int, str], list[np.ndarray]] = field(default_factory=dict)
    extra: dict[tuple[str, int, str], list[np.ndarray]] = field(default_factory=dict)
    skeletons: dict[str, str] = field(default_factory=dict)
    reprojection: tuple[float, float, int] = (float("nan"), float("nan"), 0)
    scored: str = ""  # how finished results were matched (evaluate_poses); "" = the protocol


def _per_person_input(data: MultiViewDataset, views: tuple[int, ...], protocol: str, assoc):
    """The 2D people handed to the methods for one part and view subset.

    Returns:
        keypoints (M, k, J, 2), scores (M, k, J), frame index (M,), ground-truth slot
        (M,) (-1: to be matched); J the 2D's joints (COCO-17, or HALPE-26).
    """
    from rmpl.pipeline.association import associate

    kp_all = data.keypoints[:, list(views)]  # (T, k, N, J, 2)
    sc_all = data.scores[:, list(views)]
    T, k, N, J = kp_all.shape[:4]
    if protocol == "given":
        # (T, k, P, J, 2) -> (T * P, k, J, 2): one input per frame and person
        P = data.num_people
        kp = np.moveaxis(kp_all[:, :, :P], 2, 1).reshape(T * P, k, J, 2)
        sc = np.moveaxis(sc_all[:, :, :P], 2, 1).reshape(T * P, k, J)
        frame, slot = np.repeat(np.arange(T), P), np.tile(np.arange(P), T)
        seen = (sc > 0).any((-1, -2))
        return kp[seen], sc[seen], frame[seen], slot[seen]
    if protocol == "single":
        best = np.argmax(sc_all.sum(-1), axis=-1)  # (T, k) the most confident person
        kp = np.take_along_axis(kp_all, best[..., None, None, None], 2)[:, :, 0]
        sc = np.take_along_axis(sc_all, best[..., None, None], 2)[:, :, 0]
        seen = (sc > 0).any((-1, -2))
        return kp[seen], sc[seen], np.arange(T)[seen], np.zeros(int(seen.sum()), int)
    rig = data.rig[list(views)]
    kps, scs, frames = [], [], []
    for t in range(T):
        people = [(kp_all[t, v], sc_all[t, v]) for v in range(k)]
        people = [(a[(b > 0).any(-1)], b[(b > 0).any(-1)]) for a, b in people]
        found = associate([p[0] for p in people], [p[1] for p in people], rig, assoc)
        if len(found):
            kps.append(found.keypoints)
            scs.append(found.scores)
            frames.append(np.full(len(found), t))
    if not kps:
        empty = np.zeros((0, k, J))
        return np.zeros((0, k, J, 2)), empty, np.zeros(0, int), np.zeros(0, int)
    frame = np.concatenate(frames)
    return np.concatenate(kps), np.concatenate(scs), frame, np.full(len(frame), -1)


def _perturbed_rig(rig: Rig, deg: float, metres: float, rng: np.random.Generator) -> Rig:
    from rmpl.data.synthetic import perturb_extrinsics

    R, t = perturb_extrinsics(rig.R, rig.t, deg, metres, rng)
    return Rig(tuple(c.with_pose(R[v], t[v]) for v, c in enumerate(rig)))


def _dropout(kp, sc, p: float, rng: np.random.Generator):
    if p <= 0:
        return kp, sc
    drop = rng.random(sc.shape) < p
    return np.where(drop[..., None], np.nan, kp), np.where(drop, 0.0, sc)


def _assign(pred, frame, slot, gt_frames, joints, gate) -> np.ndarray:
    """Place predictions (M, J, 3) onto ground-truth slots: (T, P, J, 3), NaN if unmatched.

    Matching uses the COCO-17 ``joints`` (the first 17 of HALPE-26 predictions)."""
    from rmpl.pipeline.association import match_poses

    T, P = gt_frames.shape[:2]
    out = np.full((T, P, pred.shape[-2], 3), np.nan)
    given = slot >= 0
    out[frame[given], slot[given]] = pred[given]
    todo = np.flatnonzero(~given)
    if todo.size:
        for t in np.unique(frame[todo]):
            rows = todo[frame[todo] == t]
            match = match_poses(pred[rows, :17], gt_frames[t], gate, joints)
            ok = match >= 0
            out[t, ok] = pred[rows[match[ok]]]
    return out


def _scored(evset: EvalSet, names: list[str], view_sets, cfg: EvalConfig):
    """An empty :class:`Evaluation` with its scored ground-truth poses filled in.

    Returns:
        The evaluation, the per-part COCO-17 ground truth (T, P, 17, 3) and the per-part
        (T, P) masks of the scored poses.
    """
    V = evset.num_views
    for label, subsets in view_sets.items():
        for s in subsets:
            if not s or max(s) >= V:
                raise ValueError(f"view subset {s} of {label!r} does not fit {V} cameras")
    gts = [gt_coco(p) for p in evset.parts]
    defined = np.zeros(17, bool)
    for g in gts:
        defined |= np.isfinite(g).all(-1).any((0, 1))
    joints = [int(j) for j in np.flatnonzero(defined)]
    if not joints:
        raise InputError(None, "gt", "ground truth with COCO-17 joints", "none defined")
    ev = Evaluation(evset, cfg, list(names), joints, view_sets)
    ev.reprojection = reprojection_check(evset)
    # The scored poses: every (part, frame, person) with any ground-truth joint.
    present = [np.isfinite(g[..., joints, :]).all(-1).any(-1) for g in gts]  # (T, P)
    ev.gt = np.concatenate([g[m] for g, m in zip(gts, present, strict=True)])
    ev.native = np.concatenate([p.gt[m] for p, m in zip(evset.parts, present, strict=True)])
    persons, clips = [], []
    for p, m in zip(evset.parts, present, strict=True):
        ids = p.person_ids if p.person_ids is not None else np.arange(p.num_people)
        tag = p.name.split("/", 1)[1] + " " if "/" in p.name else ""
        lab = np.array([f"{tag}person {i}" for i in ids])
        if evset.name in ("shelf", "campus"):
            lab = np.array([f"actor {i}" for i in ids])
        persons.append(np.broadcast_to(lab, m.shape)[m])
        clip = p.clips if p.clips is not None else np.full(len(p), p.name)
        clips.append(np.broadcast_to(clip[:, None], m.shape)[m])
    ev.person, ev.clip = np.concatenate(persons), np.concatenate(clips)
    return ev, gts, present


def _noisy_rigs(evset: EvalSet, cfg: EvalConfig) -> dict[tuple[int, int], Rig]:
    """(repetition, part) -> the part's rig with calibration noise; {} without noise."""
    rigs = {}
    if cfg.calib_noise is not None:  # one draw of the whole rig per repetition and part
        for r in range(cfg.calib_reps):
            for i, part in enumerate(evset.parts):
                rng = np.random.default_rng([cfg.seed, 1, r, i])
                rigs[r, i] = _perturbed_rig(part.rig, *cfg.calib_noise, rng)
    return rigs


@dataclass
class _Run:
    """What one :func:`evaluate` call shares between its view subsets."""

    ev: Evaluation
    methods: dict[str, Method]
    gts: list[np.ndarray]  # per part: COCO-17 ground truth (T, P, 17, 3)
    present: list[np.ndarray]  # per part: (T, P) mask of the scored poses
    rigs: dict[tuple[int, int], Rig]
    bar: object  # tqdm progress bar


def _output_joints(name: str, pred: np.ndarray) -> np.ndarray:
    """A method's predictions (M, J, 3) as HALPE-26 (M, 26, 3): COCO-17 padded with NaN.

    Raises:
        ValueError: predictions that are neither COCO-17 nor HALPE-26.
    """
    J = pred.shape[-2]
    if J == HALPE26.num_joints:
        return pred
    if J != COCO17.num_joints:
        raise ValueError(f"method {name} returned {J} joints: expected COCO-17 or HALPE-26")
    pad = np.full((*pred.shape[:-2], HALPE26.num_joints - J, 3), np.nan)
    return np.concatenate([pred, pad], axis=-2)


def _run_condition(run: _Run, views, si: int, inputs, ci: int, p: float, calib, r: int):
    """Every method on one view subset, condition and repetition: name -> (n, 26, 3)
    HALPE-26, NaN after the first 17 joints for a COCO-17 method."""
    evset, cfg = run.ev.evset, run.ev.config
    per_method: dict[str, list] = {m: [] for m in run.methods}
    for i, (part, inp) in enumerate(zip(evset.parts, inputs, strict=True)):
        kp, sc, frame, slot = inp
        rng = np.random.default_rng([cfg.seed, 2, ci, si, i, r])
        kp, sc = _dropout(kp, sc, p, rng)
        rig = (run.rigs[r, i] if calib is not None else part.rig)[list(views)]
        for name, method in run.methods.items():
            if getattr(method, "sequence", False):  # tracks, then per-frame predictions
                pred, at = method(kp, sc, frame, len(part), rig, cfg.fps, part.frames, part.clips)
                unmatched = np.full(len(at), -1)
                placed = _assign(pred, at, unmatched, run.gts[i], run.ev.joints, cfg.match_gate)
            else:
                pred = method(kp, sc, rig) if len(kp) else np.zeros((0, 17, 3))
                placed = _assign(pred, frame, slot, run.gts[i], run.ev.joints, cfg.match_gate)
            if pred.shape[-2] == HALPE26.num_joints:
                run.ev.skeletons[name] = HALPE26.name
            per_method[name].append(_output_joints(name, placed[run.present[i]]))
        run.bar.update()
    return {name: np.concatenate(per_method[name]) for name in run.methods}


def _run_subset(run: _Run, label: str, si: int, views: tuple[int, ...]) -> None:
    """Associate (or take) the 2D people of one view subset, then run every condition."""
    from rmpl.pipeline.association import AssociationConfig

    evset, cfg = run.ev.evset, run.ev.config
    assoc = AssociationConfig(min_views=min(2, len(views)))
    inputs = []
    for part in evset.parts:
        inputs.append(_per_person_input(part, views, evset.protocol, assoc))
        run.bar.update()
    for ci, (p, calib) in enumerate(cfg.conditions()):
        for r in range(cfg.calib_reps if calib is not None else 1):
            preds = _run_condition(run, views, si, inputs, ci, p, calib, r)
            for name, pred in preds.items():
                run.ev.preds[label, ci, name].append(pred[:, :17])
                run.ev.extra[label, ci, name].append(pred[:, 17:])


def evaluate(
    evset: EvalSet,
    methods: dict[str, Method],
    view_sets: dict[str, list[tuple[int, ...]]],
    config: EvalConfig | None = None,
    progress: bool = True,
) -> Evaluation:
    """Run every method on every view subset and condition of an :class:`EvalSet`.

    Args:
        evset: the dataset with its 2D input.
        methods: name -> method.
        view_sets: view label -> view subsets (see :func:`view_subsets`).
        config: perturbations and thresholds.
        progress: show a tqdm progress bar.

    Returns:
        :class:`Evaluation` (see :mod:`rmpl.evaluate.tables` for the numbers).
    """
    from tqdm import tqdm

    cfg = config or EvalConfig()
    conditions = cfg.conditions()
    ev, gts, present = _scored(evset, list(methods), view_sets, cfg)
    runs = sum(cfg.calib_reps if c is not None else 1 for _, c in conditions)
    total = sum(len(s) for s in view_sets.values()) * len(evset.parts) * (1 + runs)
    bar = tqdm(total=total, desc="evaluate", unit="step", disable=not progress)
    run = _Run(ev, methods, gts, present, _noisy_rigs(evset, cfg), bar)
    ev.skeletons = dict.fromkeys(methods, COCO17.name)
    for label, subsets in view_sets.items():
        for (ci, _), name in itertools.product(enumerate(conditions), methods):
            ev.preds[label, ci, name] = []
            ev.extra[label, ci, name] = []
        for si, views in enumerate(subsets):
            _run_subset(run, label, si, views)
    bar.close()
    return ev


def _result_people(poses: Poses3D, part: MultiViewDataset, name: str):
    """The people of a finished result in the dataset's frames.

    Returns:
        Poses (M, J, 3), COCO-17 or HALPE-26 (kept: its head top and neck give the "own"
        PCP), and the dataset frame index of each (M,).

    Raises:
        InputError: no result frame is a frame of the dataset.
    """
    row = {int(f): t for t, f in enumerate(part.frames)}
    pts = poses.points
    if poses.skeleton not in (COCO17.name, HALPE26.name):
        pts = convert(pts, poses.skeleton, COCO17.name)
    frames = poses.frames if poses.frames is not None else np.arange(len(pts))
    pred, frame = [], []
    for i, f in enumerate(np.asarray(frames).tolist()):
        if int(f) not in row:
            continue
        people = pts[i][np.isfinite(pts[i]).all(-1).any(-1)]
        pred.append(people)
        frame.append(np.full(len(people), row[int(f)]))
    if not pred:
        span = f"{part.frames[0]}..{part.frames[-1]}"
        got = f"{frames[0]}..{frames[-1]}" if len(frames) else "no frame"
        raise InputError(name, "frames", f"frame numbers among the dataset's {span}", got)
    return np.concatenate(pred), np.concatenate(frame)


def evaluate_poses(
    evset: EvalSet, results: dict[str, Poses3D], config: EvalConfig | None = None
) -> Evaluation:
    """Score finished 3D results (``rmpl run`` output, any tool's TRC) against the ground truth.

    Every person of a result frame is matched to the ground truth of the dataset frame with
    the same number, by the same Hungarian assignment as :func:`evaluate`; unmatched ground
    truth counts as missing. The view label is "all" and there are no perturbations.

    Args:
        evset: a single-clip dataset (its frame numbers are matched to the results').
        results: name -> poses (COCO-17 or a joint set that converts to it).
        config: thresholds (dropout and calibration noise must be off).

    Returns:
        :class:`Evaluation` with one method per result.

    Raises:
        InputError: a result with no frame in common with the dataset.
    """
    cfg = config or EvalConfig()
    if cfg.dropout != (0.0,) or cfg.calib_noise is not None:
        raise ValueError("finished results cannot be perturbed: no dropout or calibration noise")
    if len(evset.parts) != 1:
        raise ValueError(f"results are matched by frame number: one clip, got {len(evset.parts)}")
    part = evset.parts[0]
    view_sets = {"all": [tuple(range(evset.num_views))]}
    ev, gts, present = _scored(evset, list(results), view_sets, cfg)
    ev.scored = (
        "finished 3D results (--poses); in every frame their people are matched to the ground "
        f"truth by Hungarian assignment on the mean joint distance ({cfg.match_gate:g} m "
        "gate); unmatched ground truth counts as missing"
    )
    for name, poses in results.items():
        pred, frame = _result_people(poses, part, name)
        placed = _assign(pred, frame, np.full(len(frame), -1), gts[0], ev.joints, cfg.match_gate)
        placed = _output_joints(name, placed[present[0]])
        ev.skeletons[name] = HALPE26.name if pred.shape[-2] == 26 else COCO17.name
        ev.preds["all", 0, name] = [placed[:, :17]]
        ev.extra["all", 0, name] = [placed[:, 17:]]
    return ev


def multi_view_floor(evset: EvalSet):
    """The floor estimated from the dataset's own 2D with every camera: the people of each
    frame associated and triangulated (DLT, joints seen by 2+ views), then
    :func:`rmpl.pipeline.monocular.floor_from_poses` (no ground truth is used).

    Returns:
        The :class:`rmpl.geometry.floor.Floor` (one for all parts: they share a rig).

    Raises:
        InputError: parts with different rigs, or too few triangulated poses.
    """
    from rmpl.geometry import triangulate
    from rmpl.inference import estimate_up
    from rmpl.pipeline.association import AssociationConfig
    from rmpl.pipeline.monocular import floor_from_poses

    rig = evset.parts[0].rig
    if any(not np.allclose(p.rig.centers, rig.centers) for p in evset.parts):
        raise InputError(None, "--floor estimate", "parts that share one rig", evset.name)
    views = tuple(range(evset.num_views))
    points = []
    for part in evset.parts:
        kp, sc, _, _ = _per_person_input(part, views, evset.protocol, AssociationConfig())
        if len(kp):
            points.append(triangulate(kp, sc, part.rig).points)
    if not points:
        raise InputError(None, "--floor estimate", "people seen by 2+ cameras", "none")
    floor = floor_from_poses(np.concatenate(points), estimate_up(rig))
    return replace(floor, source=f"{floor.source}, triangulated from all {len(views)} cameras")
