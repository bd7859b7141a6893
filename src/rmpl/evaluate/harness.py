"""Compare 3D methods on identical 2D input: triangulation, robust triangulation, RMPL.

A method maps per-person multi-view keypoints ``(N, V, J, 2)`` + scores ``(N, V, J)`` and a
rig to COCO-17 joints ``(N, J, 3)``. Every method of one run sees the same per-person 2D
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
the predicted neck and head top derived by :func:`rmpl.skeleton.convert`.

Metrics are computed per view subset (and calibration-noise repetition) and averaged.

Shape glossary: ``T`` frames, ``V`` views, ``P`` ground-truth people, ``N`` people given to
a method, ``J`` joints. Units: metres inside, millimetres in the tables.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.data.base import MultiViewDataset, coco17_by_name
from rmpl.errors import InputError
from rmpl.geometry import Rig, triangulate, triangulate_robust
from rmpl.io.poses import Poses3D
from rmpl.metrics import pcp_parts, procrustes_align
from rmpl.skeleton import COCO17, KP_STAR, SHELF14, convert

__all__ = [
    "METHODS",
    "DATASETS",
    "TWO_D_SOURCES",
    "EvalConfig",
    "EvalSet",
    "Evaluation",
    "make_method",
    "view_subsets",
    "load_eval_set",
    "evaluate",
    "pose_metrics",
    "shelf15",
]

log = logging.getLogger(__name__)

Method = Callable[[np.ndarray, np.ndarray, Rig], np.ndarray]

DATASETS = ("synthetic", "shelf", "campus", "panoptic", "h36m")
#: Where the 2D input comes from (``auto``: a user file, else the dataset's detections when
#: they hold any keypoint, else the projection of the ground truth + the noise model).
TWO_D_SOURCES = ("auto", "detections", "annotations", "projection")
MATCH_GATE = 0.5  # metres, mean distance of the evaluated joints
MID_HIP = SHELF14.num_joints  # index of the mid-hip appended after the Shelf-14 joints
#: The customary ten Shelf/Campus PCP parts: head, arms, legs (Shelf-14 bones) and torso.
PCP_PARTS = SHELF14.bones[:9] + ((SHELF14.index("neck"), MID_HIP),)
#: PCP is reported for the customary actors 1-3 (Shelf's actor 4 is left out).
PCP_ACTORS = 3


def _nan_if_too_few_views(fn: Method) -> Method:
    """Triangulation needs two views: with one, every joint is NaN (counted as missing)."""

    def run(kp: np.ndarray, sc: np.ndarray, rig: Rig) -> np.ndarray:
        if len(rig) < 2:
            return np.full((*kp.shape[:-3], kp.shape[-2], 3), np.nan)
        return fn(kp, sc, rig)

    return run


def _rmpl(spec: str) -> Method:
    from rmpl.inference import Lifter

    lifter = Lifter.from_pretrained(spec or "default")

    def run(kp: np.ndarray, sc: np.ndarray, rig: Rig) -> np.ndarray:
        ok = (sc > 0) & np.isfinite(kp).all(-1)
        if not ok.any():  # nothing to lift; the lifter would refuse
            return np.full((*kp.shape[:-3], kp.shape[-2], 3), np.nan)
        return lifter.lift(kp, sc, rig).points

    return run


METHODS: dict[str, Callable[[str], Method]] = {
    "triangulate": lambda _: _nan_if_too_few_views(
        lambda kp, sc, rig: triangulate(kp, sc, rig).points
    ),
    "robust": lambda _: _nan_if_too_few_views(
        lambda kp, sc, rig: triangulate_robust(kp, sc, rig, swap_pairs=COCO17.flip_pairs).points
    ),
    "rmpl": _rmpl,
}


def make_method(spec: str) -> Method:
    """A method from ``name`` or ``name:argument`` (e.g. ``rmpl:runs/x``)."""
    name, _, arg = spec.partition(":")
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)}")
    return METHODS[name](arg)


def shelf15(coco: np.ndarray) -> np.ndarray:
    """COCO-17 joints (*, 17, 3) to Shelf-14 plus the mid-hip: shape (*, 15, 3)."""
    shelf = convert(coco, "coco17", "shelf14")
    return _with_mid_hip(shelf)


def _with_mid_hip(shelf: np.ndarray) -> np.ndarray:
    """Shelf-14 joints (*, 14, 3) plus the mid-hip (mean of the hips): (*, 15, 3)."""
    hips = shelf[..., [SHELF14.index("right_hip"), SHELF14.index("left_hip")], :]
    return np.concatenate([shelf, hips.mean(-2, keepdims=True)], axis=-2)


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
    """

    dropout: tuple[float, ...] = (0.0,)
    calib_noise: tuple[float, float] | None = None
    calib_reps: int = 5
    seed: int = 0
    pck_threshold: float = 0.150
    match_gate: float = MATCH_GATE

    def __post_init__(self) -> None:
        if not self.dropout or any(not 0 <= p < 1 for p in self.dropout):
            raise ValueError(f"--dropout: probabilities in [0, 1), got {list(self.dropout)}")
        if self.calib_noise is not None:
            deg, m = self.calib_noise
            if not (deg >= 0 and m >= 0) or deg == m == 0:
                raise ValueError(
                    f"--calib-noise: DEG,MM >= 0 and not both 0, got {self.calib_noise}"
                )
        if self.calib_reps < 1:
            raise ValueError(f"--calib-reps must be >= 1, got {self.calib_reps}")
        if not self.pck_threshold > 0:
            raise ValueError(f"--pck must be > 0, got {self.pck_threshold}")

    def conditions(self) -> list[tuple[float, tuple[float, float] | None]]:
        """Every (dropout p, calibration noise or None) pair evaluated."""
        calibs = [None] if self.calib_noise is None else [None, self.calib_noise]
        return [(p, c) for c in calibs for p in self.dropout]


@dataclass(frozen=True)
class EvalSet:
    """A dataset ready to evaluate: one or more parts with 2D, and how the 2D was made.

    Attributes:
        parts: datasets sharing a camera count (H36M subjects, Panoptic sequences), each
            with keypoints (T, V, N, 17, 2) and scores.
        name: dataset name for the tables.
        source: one line saying where the 2D comes from.
        protocol: "associate", "single" or "given" (see the module docstring).
        pcp: whether the dataset reports PCP (Shelf, Campus).
        notes: further header lines (frames used, fallbacks).
    """

    parts: tuple[MultiViewDataset, ...]
    name: str
    source: str
    protocol: str
    pcp: bool = False
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.parts:
            raise ValueError("an evaluation needs at least one dataset part")
        views = {p.num_views for p in self.parts}
        if len(views) != 1:
            raise ValueError(f"every part must have the same number of cameras, got {views}")
        if self.protocol not in ("associate", "single", "given"):
            raise ValueError(f"unknown protocol {self.protocol!r}")
        if any(p.keypoints is None for p in self.parts):
            raise ValueError("every part needs 2D keypoints")

    @property
    def num_views(self) -> int:
        return self.parts[0].num_views

    @property
    def protocol_text(self) -> str:
        return {
            "associate": "2D people of the views in use associated by ray distance per view "
            "subset (rmpl.pipeline.association.associate; 1 view: every 2D person is a 3D person), "
            f"then matched to ground truth by Hungarian assignment on the mean distance of "
            f"the evaluated joints ({MATCH_GATE} m gate); unmatched people count as missing",
            "single": "single person: in each view the detected person with the highest total "
            "score is the subject",
            "given": "association given by the 2D source (slot n of every view is ground-truth "
            "person n); no association step, no matching",
        }[self.protocol]


# --------------------------------------------------------------------------- loading


def _gt_coco(data: MultiViewDataset) -> np.ndarray:
    """Ground truth as COCO-17 by joint name, shape (T, P, 17, 3); undefined joints NaN."""
    idx = coco17_by_name(data.gt_skeleton)
    out = data.gt[..., np.maximum(idx, 0), :].copy()
    out[..., idx < 0, :] = np.nan
    return out


def _has_2d(data: MultiViewDataset) -> bool:
    return data.keypoints is not None and bool((data.scores > 0).any())


def keypoints_from_noise_model(
    data: MultiViewDataset, rng: np.random.Generator, noise=None
) -> MultiViewDataset:
    """2D from the ground truth through the parametric detector model (rmpl.synth.noise).

    The COCO-17 joints the ground truth defines are projected into every view with
    :func:`rmpl.synth.noise.detect_like` (per-joint error, self-occlusion, swaps, misses),
    then shifted by the lens distortion of each camera. Slot ``n`` of every view is
    ground-truth person ``n``.

    Returns:
        A copy of ``data`` with keypoints (T, V, P, 17, 2) pixels and scores (T, V, P, 17).
    """
    from rmpl.geometry.camera import project
    from rmpl.synth.noise import detect_like

    rig = data.rig
    X = _gt_coco(data)  # (T, P, 17, 3)
    T, P = X.shape[:2]
    V = len(rig)
    flat = X.reshape(T * P, 17, 3)
    B = len(flat)
    sizes = rig.sizes
    sizes = np.where(np.isfinite(sizes), sizes, 1e5)  # unknown size: nothing is cut off
    K, R, t = (np.broadcast_to(a, (B, *a.shape)) for a in (rig.K, rig.R, rig.t))
    size = np.broadcast_to(sizes, (B, V, 2))
    with warnings.catch_warnings(), np.errstate(invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # absent people: all-NaN slices
        kp, sc = detect_like(flat, K, R, t, size, rng, noise)
        pin = project(flat[:, None], K[:, :, None], R[:, :, None], t[:, :, None])
        real = rig.project(flat)  # (B, V, 17, 2) with distortion
    kp = kp + np.nan_to_num(real - pin)
    sc = np.where(np.isfinite(kp).all(-1), sc, 0.0)
    kp[sc <= 0] = np.nan
    keypoints = kp.reshape(T, P, V, 17, 2).transpose(0, 2, 1, 3, 4)
    scores = sc.reshape(T, P, V, 17).transpose(0, 2, 1, 3)
    return dataclasses.replace(data, keypoints=keypoints, scores=scores)


def _attach_file(parts: list[MultiViewDataset], paths: Sequence[str]) -> list[MultiViewDataset]:
    from rmpl.data.base import attach_keypoints
    from rmpl.io.keypoints import load_keypoints

    if len(parts) != 1:
        names = [p.name for p in parts]
        raise InputError(
            None, "--keypoints", "one subject/sequence (use --subject or --sequence)", names
        )
    kp = load_keypoints(list(paths) if len(paths) > 1 else paths[0], to="coco17")
    data = parts[0]
    common = np.intersect1d(np.asarray(kp.frames, int), data.frames)
    if common.size == 0:
        raise InputError(
            ", ".join(paths),
            "frames",
            f"frames overlapping the ground truth's {data.frames.min()}..{data.frames.max()}",
            f"frames {int(np.min(kp.frames))}..{int(np.max(kp.frames))}"
            if len(kp.frames)
            else "no frames",
        )
    out = attach_keypoints(data, kp)
    keep = np.isin(out.frames, common)
    return [_take_frames(out, keep)]


def _take_frames(data: MultiViewDataset, keep: np.ndarray) -> MultiViewDataset:
    return dataclasses.replace(
        data,
        frames=data.frames[keep],
        gt=data.gt[keep],
        keypoints=None if data.keypoints is None else data.keypoints[keep],
        scores=None if data.scores is None else data.scores[keep],
        clips=None if data.clips is None else data.clips[keep],
    )


def _shelf4d(root: Path) -> MultiViewDataset:
    """Shelf in the 4D-association layout, with each view's candidates grouped into people."""
    from tqdm import tqdm

    from rmpl.data.shelf import load_shelf
    from rmpl.pipeline.association import group_people

    data = load_shelf(root)
    groups = [
        [group_people(c) for c in frame]
        for frame in tqdm(data.detections, desc="grouping", unit="frame", leave=False)
    ]
    T, V = len(groups), len(data.rig)
    N = max(1, max(len(k) for frame in groups for k, _ in frame))
    kp, sc = np.full((T, V, N, 17, 2), np.nan), np.zeros((T, V, N, 17))
    for t, frame in enumerate(groups):
        for v, (k, s) in enumerate(frame):
            kp[t, v, : len(k)], sc[t, v, : len(k)] = k, s
    sc = np.where(np.isfinite(kp).all(-1), sc, 0.0)
    return MultiViewDataset(
        data.rig,
        np.asarray(data.frames),
        data.gt[:, :, : SHELF14.num_joints],
        SHELF14.name,
        kp,
        sc,
        "shelf",
        person_ids=np.arange(1, data.gt.shape[1] + 1),
    )


def _voxelpose(root: Path, name: str, frames: str) -> tuple[MultiViewDataset, np.ndarray, str]:
    """Shelf/Campus in the VoxelPose layout: dataset, 2D annotations (T, V, P, 17, 2), note."""
    from rmpl.data.campus import EVAL_FRAMES, load_actors_gt, load_campus_layout

    _, gt2d = load_actors_gt(root / "actorsGT.mat")
    data = load_campus_layout(root, name)
    note = f"frames: all {len(data)} of actorsGT.mat"
    if frames == "eval":
        wanted = np.asarray(EVAL_FRAMES[name])
        if wanted.max() < len(data):
            data = _take_frames(data, np.isin(data.frames, wanted))
            note = f"frames: the customary {name} evaluation frames"
        else:
            note += " (fewer than the customary evaluation range)"
    data = dataclasses.replace(data, person_ids=np.arange(1, data.num_people + 1))
    ann = None
    if gt2d is not None:
        rows = data.frames
        idx = coco17_by_name(SHELF14)
        a = gt2d[rows][..., np.maximum(idx, 0), :].copy()  # (T, P, V', 17, 2)
        a[..., idx < 0, :] = np.nan
        V = data.num_views
        ann = np.full((len(rows), V, a.shape[1], 17, 2), np.nan)
        ann[:, : min(V, a.shape[2])] = a.transpose(0, 2, 1, 3, 4)[:, :V]
    return data, ann, note


def load_eval_set(
    dataset: str,
    root: str | Path,
    *,
    two_d: str = "auto",
    keypoints: Sequence[str] | None = None,
    subject: str | None = None,
    sequence: str | None = None,
    cameras: Sequence[str] | None = None,
    frames: str = "eval",
    seed: int = 0,
) -> EvalSet:
    """Load a real dataset and its 2D input for :func:`evaluate`.

    Args:
        dataset: "shelf", "campus", "panoptic" or "h36m".
        root: the dataset folder. Shelf: the 4D-association layout (calibration.json,
            gt.txt, detection/) or the VoxelPose layout (actorsGT.mat); Campus: VoxelPose
            layout; Panoptic: sequences or one sequence folder; H36M: MMPose's layout.
        two_d: one of :data:`TWO_D_SOURCES`; ``keypoints`` overrides it.
        keypoints: user 2D files (anything :func:`rmpl.io.keypoints.load_keypoints`
            reads), matched to the ground truth by frame number and to cameras by name.
        subject: H36M subject (default: every subject of the file).
        sequence: Panoptic sequence (default: every sequence under ``root``).
        cameras: Panoptic HD camera names (default: the customary five).
        frames: Shelf/Campus VoxelPose layout: "eval" (the customary frames when the file
            has them) or "all".
        seed: seed of the 2D noise model when the 2D is projected.

    Returns:
        :class:`EvalSet`.

    Raises:
        InputError: a missing or malformed file, an unknown dataset, a 2D source the
            dataset lacks, or 2D files without frames in common with the ground truth.
    """
    root = Path(root)
    if dataset not in DATASETS or dataset == "synthetic":
        raise InputError(None, "--dataset", f"one of {DATASETS[1:]}", dataset)
    if two_d not in TWO_D_SOURCES:
        raise InputError(None, "--2d", f"one of {TWO_D_SOURCES}", two_d)
    if not root.exists():
        raise InputError(root, None, f"the {dataset} dataset folder", "no such path")
    notes: list[str] = []
    annotations = None
    pcp = dataset in ("shelf", "campus")
    if dataset == "shelf" and (root / "gt.txt").is_file():
        parts = [_shelf4d(root)]
        notes.append(f"layout: 4D-association (frames {parts[0].frames[0]}-{parts[0].frames[-1]})")
        det_name = "OpenPose BODY_25 detections grouped per view by part affinity"
    elif dataset in ("shelf", "campus"):
        if not (root / "actorsGT.mat").is_file():
            raise InputError(
                root,
                None,
                f"a {dataset} folder: actorsGT.mat + calibration_{dataset}.json (VoxelPose)"
                + (
                    " or calibration.json + gt.txt + detection/ (4D association)"
                    * (dataset == "shelf")
                ),
                "neither layout",
            )
        data, annotations, note = _voxelpose(root, dataset, frames)
        parts = [data]
        notes += ["layout: VoxelPose (actorsGT.mat)", note]
        det_name = "VoxelPose's Mask R-CNN + HRNet COCO-17 detections"
    elif dataset == "panoptic":
        from rmpl.data.panoptic import DEFAULT_CAMERAS, load_panoptic

        cams = tuple(cameras) if cameras else DEFAULT_CAMERAS
        if sequence is None and not any(root.glob("calibration_*.json")):
            seqs = sorted(p.name for p in root.iterdir() if (p / "hdPose3d_stage1_coco19").is_dir())
            if not seqs:
                raise InputError(root, None, "Panoptic sequence folders", "none")
            parts = [load_panoptic(root, s, cams) for s in seqs]
        else:
            parts = [load_panoptic(root, sequence, cams)]
        det_name = None
    else:
        from rmpl.data.h36m import h36m_subjects, load_h36m

        subjects = [subject] if subject else h36m_subjects(root)
        det = root / "test_h36m_2d_detection.npy"
        src = {"annotations": "gt", "projection": "none"}.get(two_d, "detection")
        if src == "detection" and not det.is_file():
            if two_d == "detections":
                raise InputError(det, None, "the H36M 2D detection .npy", "no such file")
            src = "none"
        if keypoints:
            src = "none"
        parts = [load_h36m(root, s, source=src) for s in subjects]
        det_name = "MMPose's H36M 2D detections (test_h36m_2d_detection.npy)"
        annotations = "h36m" if src == "gt" else None

    rng = np.random.default_rng(seed)
    projected = (
        "2D: ground truth projected with the calibration through the parametric detector "
        f"noise model (rmpl.synth.noise defaults, seed {seed}); NOT a real detector"
    )
    if keypoints:
        parts = _attach_file(parts, keypoints)
        source, protocol = f"2D: user file(s) {', '.join(map(str, keypoints))}", "associate"
    elif two_d == "annotations":
        if annotations is None:
            raise InputError(root, "--2d annotations", "2D annotations in the dataset", "none")
        if isinstance(annotations, np.ndarray):
            ok = np.isfinite(annotations).all(-1)
            parts = [
                dataclasses.replace(parts[0], keypoints=annotations, scores=np.where(ok, 1.0, 0.0))
            ]
        source, protocol = "2D: the dataset's 2D ground-truth annotations (score 1)", "given"
    elif two_d == "projection":
        parts = [keypoints_from_noise_model(p, rng) for p in parts]
        source, protocol = projected, "given"
    elif det_name is not None and all(_has_2d(p) for p in parts):
        source, protocol = f"2D: {det_name}", "associate"
    elif two_d == "detections":
        raise InputError(root, "--2d detections", "2D detections in the dataset", "none found")
    else:
        if det_name is not None:
            notes.append(f"the dataset's 2D detections hold no keypoint: fell back to {projected}")
        parts = [keypoints_from_noise_model(p, rng) for p in parts]
        source, protocol = projected, "given"
    if protocol == "associate" and all(p.num_people == 1 for p in parts):
        protocol = "single"
    if dataset == "h36m" and protocol == "given":
        protocol = "given"
    if not any(_has_2d(p) for p in parts):
        raise InputError(root, "2D", "2D keypoints in frames with ground truth", "none")
    return EvalSet(tuple(parts), dataset, source, protocol, pcp, tuple(notes))


# --------------------------------------------------------------------------- reprojection


def reprojection_check(evset: EvalSet) -> tuple[float, float, int]:
    """Distance of the projected ground truth to the 2D input, pixels.

    For every frame, view and ground-truth person, the 2D person of that view with the
    smallest median joint distance to the person's projection (COCO-17 joints both
    define); this is a check of calibration, units and frame alignment.

    Returns:
        (median, 90th percentile) of those per person-view medians in pixels, and their
        count; NaN and 0 when no 2D person overlaps a projected person.
    """
    best: list[float] = []
    for data in evset.parts:
        X = _gt_coco(data)  # (T, P, 17, 3)
        T, P = X.shape[:2]
        uv = data.rig.project(X.reshape(T, P * 17, 3)).reshape(T, -1, P, 17, 2)
        kp = data.keypoints  # (T, V, N, 17, 2)
        d = np.linalg.norm(uv[:, :, :, None] - kp[:, :, None], axis=-1)  # (T, V, P, N, 17)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(d, axis=-1)  # (T, V, P, N)
            m = np.nanmin(np.where(np.isfinite(med), med, np.inf), axis=-1) if d.size else med
        m = np.asarray(m).ravel()
        best += m[np.isfinite(m)].tolist()
    if not best:
        return float("nan"), float("nan"), 0
    b = np.asarray(best)
    return float(np.median(b)), float(np.percentile(b, 90)), len(b)


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
        preds: (view label, condition index, method) -> list of (subset index, (n, 17, 3)).
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
    reprojection: tuple[float, float, int] = (float("nan"), float("nan"), 0)
    scored: str = ""  # how finished results were matched (evaluate_poses); "" = the protocol


def _per_person_input(data: MultiViewDataset, views: tuple[int, ...], protocol: str, assoc):
    """The 2D people handed to the methods for one part and view subset.

    Returns:
        keypoints (M, k, 17, 2), scores (M, k, 17), frame index (M,), ground-truth slot
        (M,) (-1: to be matched).
    """
    from rmpl.pipeline.association import associate

    kp_all = data.keypoints[:, list(views)]  # (T, k, N, 17, 2)
    sc_all = data.scores[:, list(views)]
    T, k, N = kp_all.shape[:3]
    if protocol == "given":
        # (T, k, P, 17, 2) -> (T * P, k, 17, 2): one input per frame and person
        P = data.num_people
        kp = np.moveaxis(kp_all[:, :, :P], 2, 1).reshape(T * P, k, 17, 2)
        sc = np.moveaxis(sc_all[:, :, :P], 2, 1).reshape(T * P, k, 17)
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
        empty = np.zeros((0, k, 17))
        return np.zeros((0, k, 17, 2)), empty, np.zeros(0, int), np.zeros(0, int)
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
    """Place predictions (M, 17, 3) onto ground-truth slots: (T, P, 17, 3), NaN if unmatched."""
    from rmpl.pipeline.association import match_poses

    T, P = gt_frames.shape[:2]
    out = np.full((T, P, 17, 3), np.nan)
    given = slot >= 0
    out[frame[given], slot[given]] = pred[given]
    todo = np.flatnonzero(~given)
    if todo.size:
        for t in np.unique(frame[todo]):
            rows = todo[frame[todo] == t]
            match = match_poses(pred[rows], gt_frames[t], gate, joints)
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
    gts = [_gt_coco(p) for p in evset.parts]
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
        :class:`Evaluation` (see :func:`results_table` and friends for the numbers).
    """
    from tqdm import tqdm

    from rmpl.pipeline.association import AssociationConfig

    cfg = config or EvalConfig()
    conditions = cfg.conditions()
    ev, gts, present = _scored(evset, list(methods), view_sets, cfg)
    joints = ev.joints

    reps = cfg.calib_reps
    runs = sum(reps if c is not None else 1 for _, c in conditions)
    rigs = {}
    if cfg.calib_noise is not None:  # one draw of the whole rig per repetition and part
        for r in range(reps):
            for i, part in enumerate(evset.parts):
                rng = np.random.default_rng([cfg.seed, 1, r, i])
                rigs[r, i] = _perturbed_rig(part.rig, *cfg.calib_noise, rng)
    total = sum(len(s) for s in view_sets.values()) * len(evset.parts) * (1 + runs)
    bar = tqdm(total=total, desc="evaluate", unit="step", disable=not progress)
    for label, subsets in view_sets.items():
        for (ci, _), name in itertools.product(enumerate(conditions), methods):
            ev.preds[label, ci, name] = []
        for si, views in enumerate(subsets):
            assoc = AssociationConfig(min_views=min(2, len(views)))
            inputs = []
            for part in evset.parts:
                inputs.append(_per_person_input(part, views, evset.protocol, assoc))
                bar.update()
            for ci, (p, calib) in enumerate(conditions):
                for r in range(reps if calib is not None else 1):
                    per_method = {m: [] for m in methods}
                    for i, (part, inp) in enumerate(zip(evset.parts, inputs, strict=True)):
                        kp, sc, frame, slot = inp
                        rng = np.random.default_rng([cfg.seed, 2, ci, si, i, r])
                        kp, sc = _dropout(kp, sc, p, rng)
                        rig = (rigs[r, i] if calib is not None else part.rig)[list(views)]
                        for name, method in methods.items():
                            pred = method(kp, sc, rig) if len(kp) else np.zeros((0, 17, 3))
                            placed = _assign(pred, frame, slot, gts[i], joints, cfg.match_gate)
                            per_method[name].append(placed[present[i]])
                        bar.update()
                    for name in methods:
                        ev.preds[label, ci, name].append(np.concatenate(per_method[name]))
    bar.close()
    return ev


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
    row = {int(f): t for t, f in enumerate(part.frames)}
    for name, poses in results.items():
        pts = poses.points
        if poses.skeleton != "coco17":
            pts = convert(pts, poses.skeleton, "coco17")
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
        pred, frame = np.concatenate(pred), np.concatenate(frame)
        placed = _assign(pred, frame, np.full(len(frame), -1), gts[0], ev.joints, cfg.match_gate)
        ev.preds["all", 0, name] = [placed[present[0]]]
    return ev


# --------------------------------------------------------------------------- metrics


def pose_metrics(
    pred: np.ndarray,
    gt: np.ndarray,
    joints: Sequence[int],
    pck_threshold: float = 0.150,
) -> dict[str, float]:
    """MPJPE, KP* MPJPE, PA-MPJPE (mm), PCK and coverage (%) of poses.

    Args:
        pred: (n, 17, 3) COCO-17, metres; NaN = not estimated.
        gt: (n, 17, 3), metres; NaN = not annotated (not scored).
        joints: COCO-17 indices to score.
        pck_threshold: metres.

    Returns:
        ``mpjpe``, ``kpstar`` (the :data:`~rmpl.skeleton.KP_STAR` joints among ``joints``),
        ``pa_mpjpe`` (per-pose similarity alignment on the estimated joints, poses with at
        least 4), ``pck`` (a missing estimate counts as wrong), ``coverage`` (estimated
        share of annotated joints). MPJPE and PA-MPJPE leave missing estimates out.
    """
    joints = list(joints)
    p, g = pred[:, joints], gt[:, joints]
    present = np.isfinite(g).all(-1)
    e = np.linalg.norm(p - g, axis=-1)
    ok = present & np.isfinite(e)
    star = np.isin(joints, KP_STAR)
    out = {
        "mpjpe": 1000 * float(e[ok].mean()) if ok.any() else np.nan,
        "kpstar": 1000 * float(e[:, star][ok[:, star]].mean()) if ok[:, star].any() else np.nan,
        "pa_mpjpe": np.nan,
        "pck": 100
        * float((ok & (np.nan_to_num(e, nan=np.inf) <= pck_threshold)).sum())
        / max(int(present.sum()), 1)
        if present.any()
        else np.nan,
        "coverage": 100 * float(ok.sum()) / max(int(present.sum()), 1) if present.any() else np.nan,
    }
    enough = ok.sum(-1) >= 4
    if enough.any():
        pp = np.where(ok[enough, :, None], p[enough], np.nan)
        aligned = procrustes_align(pp, g[enough])
        ea = np.linalg.norm(aligned - g[enough], axis=-1)
        out["pa_mpjpe"] = 1000 * float(ea[ok[enough]].mean())
    return out


def _pcp_by_actor(pred, native, person) -> dict[str, float]:
    """PCP (%) per actor label over poses, Shelf-14 parts + torso (to the mid-hip)."""
    parts = pcp_parts(shelf15(pred), _with_mid_hip(native), PCP_PARTS)  # (n, 10)
    out = {}
    for a in np.unique(person):
        sel = person == a
        out[str(a)] = 100 * float(parts[sel].mean()) if sel.any() else np.nan
    return out


def _mean(values) -> float:
    """Mean of the finite values; NaN when there are none."""
    v = np.asarray(list(values), float)
    return float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else float("nan")


def _condition_label(p: float, calib) -> tuple[float, str]:
    c = "none" if calib is None else f"{calib[0]:g} deg, {1000 * calib[1]:g} mm"
    return p, c


def pcp_actors(ev: Evaluation) -> list[str]:
    """Actor labels PCP is reported for (actors 1-3 that appear)."""
    labels = [f"actor {i}" for i in range(1, PCP_ACTORS + 1)]
    return [a for a in labels if (ev.person == a).any()]


def _common_mask(ev: Evaluation, label: str, ci: int, k: int) -> np.ndarray:
    """Joints every method estimated in entry ``k``, shape (n, 17)."""
    ok = np.isfinite(ev.gt).all(-1)
    for m in ev.methods:
        ok &= np.isfinite(ev.preds[label, ci, m][k]).all(-1)
    return ok


def results_rows(ev: Evaluation) -> list[dict]:
    """One row per view setting, condition and method (metrics averaged over subsets)."""
    rows = []
    conds = ev.config.conditions()
    for label in ev.view_sets:
        for ci, (p, calib) in enumerate(conds):
            for m in ev.methods:
                entries = ev.preds[label, ci, m]
                per = [
                    pose_metrics(pred, ev.gt, ev.joints, ev.config.pck_threshold)
                    for pred in entries
                ]
                row = {"views": label, "method": m}
                row["mpjpe"] = _mean(r["mpjpe"] for r in per)
                row["coverage"] = _mean(r["coverage"] for r in per)
                for key in ("kpstar", "pa_mpjpe", "pck"):
                    row[key] = _mean(r[key] for r in per)
                common = []
                for k, pred in enumerate(entries):
                    mask = _common_mask(ev, label, ci, k)[:, ev.joints]
                    e = np.linalg.norm(pred[:, ev.joints] - ev.gt[:, ev.joints], axis=-1)
                    common.append(1000 * e[mask].mean() if mask.any() else np.nan)
                row["mpjpe_common"] = _mean(common)
                if ev.evset.pcp:
                    actors = pcp_actors(ev)
                    pcps = [_pcp_by_actor(pred, ev.native, ev.person) for pred in entries]
                    for a in actors:
                        row[f"pcp_{a.replace(' ', '')}"] = _mean(x.get(a, np.nan) for x in pcps)
                    row["pcp_mean"] = (
                        _mean(row[f"pcp_{a.replace(' ', '')}"] for a in actors)
                        if actors
                        else np.nan
                    )
                row["dropout"], row["calib_noise"] = _condition_label(p, calib)
                rows.append(row)
    return rows


def per_joint_rows(ev: Evaluation) -> list[dict]:
    """MPJPE and coverage per joint, view setting, condition and method."""
    rows = []
    for label in ev.view_sets:
        for ci, (p, calib) in enumerate(ev.config.conditions()):
            for m in ev.methods:
                entries = ev.preds[label, ci, m]
                for j in ev.joints:
                    per = [pose_metrics(x, ev.gt, [j], ev.config.pck_threshold) for x in entries]
                    d, c = _condition_label(p, calib)
                    rows.append(
                        {
                            "views": label,
                            "method": m,
                            "joint": COCO17.joints[j],
                            "mpjpe": _mean(r["mpjpe"] for r in per),
                            "coverage": _mean(r["coverage"] for r in per),
                            "pck": _mean(r["pck"] for r in per),
                            "dropout": d,
                            "calib_noise": c,
                        }
                    )
    return rows


def per_group_rows(ev: Evaluation, by: str) -> list[dict]:
    """Metrics per person ("person") or clip ("clip"), view setting, condition and method."""
    groups = ev.person if by == "person" else ev.clip
    rows = []
    for label in ev.view_sets:
        for ci, (p, calib) in enumerate(ev.config.conditions()):
            for m in ev.methods:
                entries = ev.preds[label, ci, m]
                for gname in np.unique(groups):
                    sel = groups == gname
                    per = [
                        pose_metrics(x[sel], ev.gt[sel], ev.joints, ev.config.pck_threshold)
                        for x in entries
                    ]
                    row = {"views": label, "method": m, by: str(gname), "poses": int(sel.sum())}
                    for key in ("mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage"):
                        row[key] = _mean(r[key] for r in per)
                    if ev.evset.pcp:
                        row["pcp"] = _mean(
                            _pcp_by_actor(x[sel], ev.native[sel], ev.person[sel]).get(
                                str(gname), np.nan
                            )
                            if by == "person"
                            else np.nan
                            for x in entries
                        )
                    row["dropout"], row["calib_noise"] = _condition_label(p, calib)
                    rows.append(row)
    return rows


def joint_errors_mm(ev: Evaluation, label: str, ci: int, method: str) -> dict[str, np.ndarray]:
    """Every finite per-joint error (mm) of a view setting, condition and method, by joint."""
    out = {}
    for j in ev.joints:
        e = [np.linalg.norm(x[:, j] - ev.gt[:, j], axis=-1) for x in ev.preds[label, ci, method]]
        e = np.concatenate(e) * 1000 if e else np.zeros(0)
        out[COCO17.joints[j]] = e[np.isfinite(e)]
    return out


# --------------------------------------------------------------------------- text


def fmt(x: float) -> str:
    """A table cell: one decimal, an em dash for NaN."""
    if isinstance(x, str | int | np.integer):
        return str(x)
    return "—" if not np.isfinite(x) else f"{x:.1f}"


COLUMN_TITLES = {
    "views": "views",
    "method": "method",
    "mpjpe": "MPJPE (mm)",
    "coverage": "coverage (%)",
    "kpstar": "KP* MPJPE (mm)",
    "pa_mpjpe": "PA-MPJPE (mm)",
    "pck": "PCK@{pck} (%)",
    "mpjpe_common": "MPJPE common joints (mm)",
    "pcp_mean": "PCP mean (%)",
    "dropout": "dropout p",
    "calib_noise": "calib. noise",
    "joint": "joint",
    "person": "person",
    "clip": "clip",
    "poses": "poses",
    "pcp": "PCP (%)",
    "height": "camera height (m)",
    "angle": "angle (deg)",
}


def markdown_table(rows: list[dict], columns: list[str], pck_mm: float = 150) -> str:
    """Rows as a Markdown table of the given columns (numbers right-aligned)."""
    titles = []
    for c in columns:
        t = COLUMN_TITLES.get(c) or (
            f"PCP {c[4:].replace('actor', 'actor ')} (%)" if c.startswith("pcp_") else c
        )
        titles.append(t.replace("{pck}", f"{pck_mm:g}mm"))
    text = ["| " + " | ".join(titles) + " |"]
    text.append(
        "|"
        + "|".join(
            "---" if c in ("views", "method", "joint", "person", "clip") else "---:"
            for c in columns
        )
        + "|"
    )
    for r in rows:
        text.append("| " + " | ".join(fmt(r.get(c, np.nan)) for c in columns) + " |")
    return "\n".join(text) + "\n"


def header_lines(ev: Evaluation) -> list[str]:
    """What was evaluated and how: dataset, 2D source, protocol, joints, perturbations."""
    es, cfg = ev.evset, ev.config
    frames = sum(len(p) for p in es.parts)
    lines = [
        f"- dataset: {es.name} ({', '.join(p.name for p in es.parts)}; {frames} frames, "
        f"{es.num_views} cameras, {len(ev.gt)} annotated poses)",
        f"- {es.source}",
        f"- scored: {ev.scored}" if ev.scored else f"- association protocol: {es.protocol_text}",
        "- scored joints (COCO-17 names the ground truth defines): "
        + ", ".join(COCO17.joints[j] for j in ev.joints),
        f"- PCK threshold {1000 * cfg.pck_threshold:g} mm (a missing joint is wrong); "
        "MPJPE / PA-MPJPE leave missing joints out (see coverage); metrics are averaged "
        "over the view subsets of a setting",
    ]
    if es.pcp:
        lines.append(
            "- PCP: Shelf/Campus convention (a part is correct when the mean of its end-point "
            "errors is at most half its length), ten parts (head, arms, legs, torso to the "
            "mid-hip), actors 1-3; the predicted neck and head top are derived from COCO-17"
        )
        ears = [COCO17.index("left_ear"), COCO17.index("right_ear")]
        if not any((p.scores[..., ears] > 0).any() for p in es.parts):
            lines.append(
                "- the 2D has no ears, so the predicted neck and head top (derived from them) "
                "are missing: the head and torso parts count as wrong (PCP at most 80%)"
            )
    med, p90, n = ev.reprojection
    if n:
        lines.append(
            f"- ground truth projected onto the 2D input: median {med:.1f} px, 90th percentile "
            f"{p90:.1f} px over {n} person-views (nearest 2D person)"
        )
    if any(p > 0 for p in cfg.dropout):
        lines.append(
            "- keypoint dropout: each keypoint of the per-person input removed with "
            f"probability p (after association), seed {cfg.seed}"
        )
    if cfg.calib_noise is not None:
        deg, m = cfg.calib_noise
        lines.append(
            f"- calibration noise: extrinsics rotated by N(0, {deg:g} deg) and camera centres "
            f"moved by N(0, {1000 * m:g} mm) per camera, given to the methods (association "
            f"uses the true rig); mean of {cfg.calib_reps} draws, seed {cfg.seed}"
        )
    lines += [f"- {n}" for n in es.notes]
    return lines


def write_csv(path: Path, rows: list[dict]) -> None:
    """Rows to CSV atomically (the union of their keys, in first-seen order)."""
    import csv
    import io

    from rmpl.io.atomic import atomic_path

    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys)
    writer.writeheader()
    for r in rows:
        writer.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()})
    with atomic_path(path) as tmp:
        tmp.write_text(buf.getvalue())
