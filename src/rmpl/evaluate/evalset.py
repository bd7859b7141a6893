"""Real datasets with 3D ground truth, and the 2D input every method is given.

:func:`load_eval_set` reads a dataset through :mod:`rmpl.data` and chooses its 2D source:
a user file, the dataset's detections, its 2D annotations, or the ground truth projected
through the parametric detector noise model. The result, an :class:`EvalSet`, says where
the 2D came from and which protocol matches estimates to the ground truth (see
:mod:`rmpl.evaluate.harness`). A new dataset plugs in as one loader in :data:`_LOADERS`.

Shape glossary: ``T`` frames, ``V`` views, ``P`` ground-truth people, ``N`` 2D people per
view, ``J`` joints. Units: metres, pixels.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.data.base import MultiViewDataset, coco17_by_name
from rmpl.errors import InputError
from rmpl.skeleton import COCO17, SHELF14

__all__ = [
    "DATASETS",
    "MATCH_GATE",
    "TWO_D_SOURCES",
    "EvalSet",
    "gt_coco",
    "keypoints_from_noise_model",
    "load_eval_set",
    "reprojection_check",
]

log = logging.getLogger(__name__)

DATASETS = ("synthetic", "shelf", "campus", "panoptic", "h36m")
#: Where the 2D input comes from (``auto``: a user file, else the dataset's detections when
#: they hold any keypoint, else the projection of the ground truth + the noise model).
TWO_D_SOURCES = ("auto", "detections", "annotations", "projection")
MATCH_GATE = 0.5  # metres, mean distance of the evaluated joints


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
        two_d: the 2D source in one word, for the tables: "detections", "annotations",
            "projection" or "keypoints" (a user file).
    """

    parts: tuple[MultiViewDataset, ...]
    name: str
    source: str
    protocol: str
    pcp: bool = False
    notes: tuple[str, ...] = ()
    two_d: str = "detections"

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


# --------------------------------------------------------------------------- 2D input


def gt_coco(data: MultiViewDataset) -> np.ndarray:
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
    X = gt_coco(data)  # (T, P, 17, 3)
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


# --------------------------------------------------------------------------- datasets


def _shelf4d(root: Path) -> MultiViewDataset:
    """Shelf in the 4D-association layout, with each view's candidates grouped into people."""
    from tqdm import tqdm

    from rmpl.data.shelf import load_shelf
    from rmpl.pipeline.association import group_people

    data = load_shelf(root)
    groups = [  # COCO-17 people (MultiViewDataset's 2D), as the published tables used
        [group_people(c, output=COCO17.name) for c in frame]
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


@dataclass
class _Loaded:
    """A dataset as read, before its 2D source is chosen.

    Attributes:
        parts: the dataset parts, with the dataset's own 2D (or none).
        detector: a description of the dataset's detections, None when it has none.
        annotations: the 2D annotations (T, V, P, 17, 2) pixels, "h36m" when they are
            already in ``parts``, or None.
        notes: header lines (layout, frames used).
        missing: why the dataset has no usable detections, when it is known.
    """

    parts: list[MultiViewDataset]
    detector: str | None = None
    annotations: np.ndarray | str | None = None
    notes: list[str] = dataclasses.field(default_factory=list)
    missing: str | None = None


def _load_shelf_campus(dataset: str, root: Path, frames: str, **_) -> _Loaded:
    if dataset == "shelf" and (root / "gt.txt").is_file():
        parts = [_shelf4d(root)]
        note = f"layout: 4D-association (frames {parts[0].frames[0]}-{parts[0].frames[-1]})"
        return _Loaded(
            parts, "OpenPose BODY_25 detections grouped per view by part affinity", None, [note]
        )
    if not (root / "actorsGT.mat").is_file():
        raise InputError(
            root,
            None,
            f"a {dataset} folder: actorsGT.mat + calibration_{dataset}.json (VoxelPose)"
            + " or calibration.json + gt.txt + detection/ (4D association)" * (dataset == "shelf"),
            "neither layout",
        )
    data, annotations, note = _voxelpose(root, dataset, frames)
    pred = root / f"pred_{dataset}_maskrcnn_hrnet_coco.pkl"
    return _Loaded(
        [data],
        "VoxelPose's Mask R-CNN + HRNet COCO-17 detections",
        annotations,
        ["layout: VoxelPose (actorsGT.mat)", note],
        None if data.keypoints is not None else f"its detections file {pred} is missing",
    )


def _load_panoptic(dataset: str, root: Path, sequence, cameras, **_) -> _Loaded:
    from rmpl.data.panoptic import DEFAULT_CAMERAS, load_panoptic

    cams = tuple(cameras) if cameras else DEFAULT_CAMERAS
    if sequence is None and not any(root.glob("calibration_*.json")):
        seqs = sorted(p.name for p in root.iterdir() if (p / "hdPose3d_stage1_coco19").is_dir())
        if not seqs:
            raise InputError(root, None, "Panoptic sequence folders", "none")
        parts = [load_panoptic(root, s, cams) for s in seqs]
    else:
        parts = [load_panoptic(root, sequence, cams)]
    return _Loaded(parts, missing="Panoptic comes with no 2D detections")


def _load_h36m(dataset: str, root: Path, subject, two_d: str, keypoints, **_) -> _Loaded:
    from rmpl.data.h36m import h36m_subjects, load_h36m

    subjects = [subject] if subject else h36m_subjects(root)
    det = root / "test_h36m_2d_detection.npy"
    src = {"annotations": "gt", "projection": "none"}.get(two_d, "detection")
    missing = None
    if src == "detection" and not det.is_file():
        if two_d == "detections":
            raise InputError(det, None, "the H36M 2D detection .npy", "no such file")
        src, missing = "none", f"its detections file {det} is missing"
    if keypoints:
        src = "none"
    return _Loaded(
        [load_h36m(root, s, source=src) for s in subjects],
        "MMPose's H36M 2D detections (test_h36m_2d_detection.npy)",
        "h36m" if src == "gt" else None,
        missing=missing,
    )


_LOADERS = {
    "shelf": _load_shelf_campus,
    "campus": _load_shelf_campus,
    "panoptic": _load_panoptic,
    "h36m": _load_h36m,
}


def _projected_text(seed: int) -> str:
    return (
        "2D: ground truth projected with the calibration through the parametric detector "
        f"noise model (rmpl.synth.noise defaults, seed {seed}); NOT a real detector"
    )


def _with_annotations(loaded: _Loaded, root: Path) -> list[MultiViewDataset]:
    """The parts with the dataset's 2D annotations as their 2D (score 1 where labelled)."""
    annotations = loaded.annotations
    if annotations is None:
        raise InputError(root, "--2d annotations", "2D annotations in the dataset", "none")
    if isinstance(annotations, str):  # already loaded as the parts' 2D
        return loaded.parts
    ok = np.isfinite(annotations).all(-1)
    scores = np.where(ok, 1.0, 0.0)
    return [dataclasses.replace(loaded.parts[0], keypoints=annotations, scores=scores)]


def _choose_2d(
    loaded: _Loaded, root: Path, two_d: str, keypoints, seed: int
) -> tuple[list[MultiViewDataset], str, str, str]:
    """The parts with their 2D input, the header line naming it, the protocol, and the
    source in one word (:attr:`EvalSet.two_d`)."""
    rng = np.random.default_rng(seed)
    parts, projected = loaded.parts, _projected_text(seed)
    if keypoints:
        parts = _attach_file(parts, keypoints)
        source = f"2D: user file(s) {', '.join(map(str, keypoints))}"
        return parts, source, "associate", "keypoints"
    if two_d == "annotations":
        parts = _with_annotations(loaded, root)
        source = "2D: the dataset's 2D ground-truth annotations (score 1)"
        return parts, source, "given", "annotations"
    if two_d == "projection":
        return [keypoints_from_noise_model(p, rng) for p in parts], projected, "given", "projection"
    if loaded.detector is not None and all(_has_2d(p) for p in parts):
        return parts, f"2D: {loaded.detector}", "associate", "detections"
    if two_d == "detections":
        raise InputError(root, "--2d detections", "2D detections in the dataset", "none found")
    _say_fallback(loaded, root)
    return [keypoints_from_noise_model(p, rng) for p in parts], projected, "given", "projection"


def _say_fallback(loaded: _Loaded, root: Path) -> None:
    """--2d auto without usable detections: a WARNING and a header note saying why the 2D
    is the projected ground truth, so the switch of source is never silent."""
    why = loaded.missing or "its 2D detections hold no keypoint in the evaluated frames"
    text = (
        f"--2d auto: {why}, so the 2D is the ground truth projected through the noise "
        "model, not a detector's output (--2d projection chooses this explicitly)"
    )
    log.warning("%s: %s", root, text)
    loaded.notes.append(text)


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
    """Load a real dataset and its 2D input for :func:`rmpl.evaluate.harness.evaluate`.

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
    loaded = _LOADERS[dataset](
        dataset,
        root,
        frames=frames,
        sequence=sequence,
        cameras=cameras,
        subject=subject,
        two_d=two_d,
        keypoints=keypoints,
    )
    parts, source, protocol, kind = _choose_2d(loaded, root, two_d, keypoints, seed)
    if protocol == "associate" and all(p.num_people == 1 for p in parts):
        protocol = "single"
    if not any(_has_2d(p) for p in parts):
        raise InputError(root, "2D", "2D keypoints in frames with ground truth", "none")
    pcp = dataset in ("shelf", "campus")
    return EvalSet(tuple(parts), dataset, source, protocol, pcp, tuple(loaded.notes), kind)


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
        X = gt_coco(data)  # (T, P, 17, 3)
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
