"""Per-person TRC and C3D files that Pose2Sim's kinematics step (OpenSim scaling + IK) reads.

rmpl's lifter gives COCO-17 joints, or HALPE-26 (COCO-17, then head top, neck, mid-hip and
six foot points). Pose2Sim (checked on 0.10.49) runs OpenSim on them with its ``COCO_17``
pose model (``pose_model = 'COCO_17'`` or ``'Body'`` in its Config.toml, with
``use_augmentation = false``; marker set ``Markers_Coco17.xml``, setup files
``Scaling_Setup_Pose2Sim_Coco17.xml`` / ``IK_Setup_Pose2Sim_Coco17.xml``), or its
``HALPE_26`` one (``pose_model = 'HALPE_26'`` or ``'Body_with_feet'``; ``Markers_Halpe26.xml``
and the ``Halpe26`` setup files), whose IK also drives the ankles, subtalar joints and toes
from the heel and toe markers. :data:`POSE_MODELS` holds both; the poses' joint set picks
one (:func:`pose_model`). What this module writes, per person, to match:

Files
    ``<folder>/<stem>_p<person id>.trc`` and ``.c3d``, one person each, as Pose2Sim's
    triangulation writes one TRC per person into a trial's ``pose-3d/`` folder. Pose2Sim's
    kinematics takes every ``*.trc`` of ``pose-3d/`` whose name does not contain ``_LSTM``
    or ``_scaling`` (only the ``*_filt*`` ones when any exist), and names its outputs
    (``<trc stem>.osim``, ``<trc stem>.mot``) after the file.
Markers (COCO-17 poses, ``COCO_17``)
    Pose2Sim's names, in the order of its ``COCO_17`` skeleton tree: ``Hip`` (the midpoint
    of the hips), ``RHip RKnee RAnkle LHip LKnee LAnkle``, ``Neck`` (the midpoint of the
    shoulders, where ``Markers_Coco17.xml`` puts it: on the torso at shoulder height),
    ``Nose REye LEye REar LEar RShoulder RElbow RWrist LShoulder LElbow LWrist``. The IK
    uses the 14 that ``Markers_Coco17.xml`` defines (:data:`IK_MARKERS`); OpenSim ignores
    markers that have no IK task (eyes, ears, ``Hip``), which are written for viewers and
    for Pose2Sim's height estimate (it uses ``Hip``).
Markers (HALPE-26 poses, ``HALPE_26``)
    One marker per joint: the lifter's own ``mid_hip``, ``neck`` and ``head_top`` are
    ``Hip``, ``Neck`` and ``Head``; where ``mid_hip`` is missing (triangulated 2D without
    it, e.g. OpenPose BODY_25B), ``Hip`` is the midpoint of the hips, as rmpl defines
    ``mid_hip``, and where ``neck`` is missing (BODY_25B has only an upper neck) ``Neck`` is
    the midpoint of the shoulders (:data:`HALPE26_FALLBACKS`). In the order of Pose2Sim's
    ``HALPE_26`` tree: ``Hip RHip RKnee RAnkle RBigToe RSmallToe RHeel LHip LKnee LAnkle LBigToe
    LSmallToe LHeel Neck Head Nose``, then ``REye LEye REar LEar`` (HALPE-26 has them;
    Pose2Sim's tree leaves them out and OpenSim ignores them), then ``RShoulder RElbow
    RWrist LShoulder LElbow LWrist``. The IK uses the 22 that ``Markers_Halpe26.xml``
    defines (:data:`HALPE26_IK_MARKERS`: all but the eyes and ears).
TRC layout
    What OpenSim's ``TRCFileAdapter`` and Pose2Sim's ``read_trc`` read:
    ``PathFileType 4 (X/Y/Z) <file name>``, the ``DataRate ... OrigNumFrames`` keys and
    values, ``Frame# Time <marker>...`` (each name over its three columns), ``X1 Y1 Z1 ...``,
    a blank line, one tab-separated row per frame. The marker-name line, the axes line and
    every data row end with a tab, so all have the same number of fields: Pose2Sim reads the
    axes line as the column header of the rows (pandas), and a header one field short would
    turn ``Frame#`` into the index and shift every column. ``Frame#`` is the rmpl frame
    number + 1, ``Time`` is frame / fps seconds. A missing coordinate is an empty field
    (OpenSim reads NaN).
Orientation
    ``"pose2sim-y-up"`` (default): Pose2Sim's own Z-up -> Y-up mapping, file (X, Y, Z) =
    world (y, z, x), so that the files overlay Pose2Sim's of the same trial; OpenSim's
    models are Y-up. It assumes a Z-up world (Qualisys and Shelf calibrations are); ``rmpl
    run`` turns any other world so that its up axis is +z first
    (:func:`rmpl.pipeline.outputs.z_up_world`).
    ``"z-up"``: world axes as they are.
Units
    ``"m"`` (default) or ``"mm"``. Pose2Sim's scaling reads TRC numbers as metres (it
    compares marker distances with the model's), so its kinematics needs ``"m"``; ``"mm"``
    is for other tools (Visual3D, Vicon Nexus). C3D stores ``POINT:UNITS`` accordingly.
Missing joints (``missing``)
    OpenSim's IK accepts a missing marker (NaN) in a frame: it solves that frame with the
    other markers (checked with OpenSim 4.6: a 20-frame gap in one knee marker runs through,
    and that knee's angle then drifts, unconstrained). Pose2Sim's scaling accepts NaN too,
    but its frame selection (hip and knee flexion below 90 degrees) falls back to all
    frames when a leg or shoulder marker is NaN anywhere. So, with the IK markers of the
    pose model (:data:`IK_MARKERS` or :data:`HALPE26_IK_MARKERS`):

    - ``"gaps"`` (default): frames from the first to the last one in which all IK markers
      are present; a marker missing in between is left empty.
    - ``"interpolate"``: the same frames, every gap filled linearly per coordinate (no empty
      field; eyes and ears outside their first and last sighting stay empty).
    - ``"complete"``: only the frames in which all IK markers are present (the ``Time``
      column then has jumps; the C3D marks the dropped frames' points invalid).

    A person with no frame that has all IK markers gets no file (logged).
C3D
    Through the ``c3d`` package, as :mod:`rmpl.io.poses`: float points, residual -1 for a
    missing point and 0 otherwise, contiguous frames from the first to the last written
    one (frames in between that are not written are missing points), ``POINT:X_SCREEN`` /
    ``Y_SCREEN`` naming the horizontal and the up axis.

Pose2Sim's marker names of both pose models were read from its ``skeletons.py`` and
``OpenSim_Setup/Markers_*.xml`` (0.10.49).
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.io.poses import Poses3D

__all__ = [
    "HALPE26_FALLBACKS",
    "HALPE26_IK_MARKERS",
    "HALPE26_MARKERS",
    "IK_MARKERS",
    "MISSING",
    "ORIENTATIONS",
    "POSE2SIM_MARKERS",
    "POSE_MODELS",
    "PoseModel",
    "pose_model",
    "write_pose2sim",
]

log = logging.getLogger(__name__)

ORIENTATIONS = ("pose2sim-y-up", "z-up")
MISSING = ("gaps", "interpolate", "complete")
_UNITS = {"m": 1.0, "mm": 1e-3}  # metres per unit

#: Pose2Sim marker name -> the rmpl COCO-17 joints it is the mean of, in the order of
#: Pose2Sim's COCO_17 skeleton tree (eyes and ears placed where its COCO_133 tree has them).
POSE2SIM_MARKERS: dict[str, tuple[str, ...]] = {
    "Hip": ("left_hip", "right_hip"),
    "RHip": ("right_hip",),
    "RKnee": ("right_knee",),
    "RAnkle": ("right_ankle",),
    "LHip": ("left_hip",),
    "LKnee": ("left_knee",),
    "LAnkle": ("left_ankle",),
    "Neck": ("left_shoulder", "right_shoulder"),
    "Nose": ("nose",),
    "REye": ("right_eye",),
    "LEye": ("left_eye",),
    "REar": ("right_ear",),
    "LEar": ("left_ear",),
    "RShoulder": ("right_shoulder",),
    "RElbow": ("right_elbow",),
    "RWrist": ("right_wrist",),
    "LShoulder": ("left_shoulder",),
    "LElbow": ("left_elbow",),
    "LWrist": ("left_wrist",),
}

#: The markers of Pose2Sim's ``Markers_Coco17.xml`` (the ones its IK and scaling use).
IK_MARKERS: tuple[str, ...] = (
    "Nose",
    "Neck",
    "LShoulder",
    "RShoulder",
    "LElbow",
    "RElbow",
    "LWrist",
    "RWrist",
    "LHip",
    "RHip",
    "LKnee",
    "RKnee",
    "LAnkle",
    "RAnkle",
)

#: Pose2Sim marker name -> the rmpl HALPE-26 joint it is, in the order of Pose2Sim's HALPE_26
#: skeleton tree (eyes and ears, which that tree leaves out, after the nose).
HALPE26_MARKERS: dict[str, tuple[str, ...]] = {
    "Hip": ("mid_hip",),
    "RHip": ("right_hip",),
    "RKnee": ("right_knee",),
    "RAnkle": ("right_ankle",),
    "RBigToe": ("right_big_toe",),
    "RSmallToe": ("right_small_toe",),
    "RHeel": ("right_heel",),
    "LHip": ("left_hip",),
    "LKnee": ("left_knee",),
    "LAnkle": ("left_ankle",),
    "LBigToe": ("left_big_toe",),
    "LSmallToe": ("left_small_toe",),
    "LHeel": ("left_heel",),
    "Neck": ("neck",),
    "Head": ("head_top",),
    "Nose": ("nose",),
    "REye": ("right_eye",),
    "LEye": ("left_eye",),
    "REar": ("right_ear",),
    "LEar": ("left_ear",),
    "RShoulder": ("right_shoulder",),
    "RElbow": ("right_elbow",),
    "RWrist": ("right_wrist",),
    "LShoulder": ("left_shoulder",),
    "LElbow": ("left_elbow",),
    "LWrist": ("left_wrist",),
}

#: HALPE_26 markers taken from other joints where their own is missing: the mid-hip is the
#: midpoint of the hips by definition (rmpl.synth.body).
HALPE26_FALLBACKS: dict[str, tuple[str, ...]] = {
    "Hip": ("left_hip", "right_hip"),
    "Neck": ("left_shoulder", "right_shoulder"),  # BODY_25B's 2D has an upper neck, no neck
}

#: The markers of Pose2Sim's ``Markers_Halpe26.xml`` (the ones its IK and scaling use).
HALPE26_IK_MARKERS: tuple[str, ...] = (
    "Nose",
    "Head",
    "Neck",
    "LShoulder",
    "RShoulder",
    "LElbow",
    "RElbow",
    "LWrist",
    "RWrist",
    "Hip",
    "LHip",
    "RHip",
    "LKnee",
    "RKnee",
    "LAnkle",
    "RAnkle",
    "LBigToe",
    "LSmallToe",
    "LHeel",
    "RBigToe",
    "RSmallToe",
    "RHeel",
)


@dataclass(frozen=True)
class PoseModel:
    """One of Pose2Sim's pose models, for the rmpl joint set that maps onto it.

    Attributes:
        name: Pose2Sim's ``pose_model`` (its Config.toml ``[pose]`` key).
        markers: marker name -> the rmpl joints it is the mean of, in the file's order.
        ik_markers: the markers its IK and scaling use (its ``Markers_*.xml``).
        fallbacks: marker name -> the joints whose mean stands in where ``markers``'
            joints are missing.
    """

    name: str
    markers: dict[str, tuple[str, ...]]
    ik_markers: tuple[str, ...]
    fallbacks: dict[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)


#: rmpl joint set -> Pose2Sim's pose model for it.
POSE_MODELS: dict[str, PoseModel] = {
    "coco17": PoseModel("COCO_17", POSE2SIM_MARKERS, IK_MARKERS),
    "halpe26": PoseModel("HALPE_26", HALPE26_MARKERS, HALPE26_IK_MARKERS, HALPE26_FALLBACKS),
}


def pose_model(skeleton: str, where=None) -> PoseModel:
    """Pose2Sim's pose model for rmpl's joint set ``skeleton``; InputError for another set
    (``where``: the file or folder to name)."""
    if skeleton not in POSE_MODELS:
        expected = " or ".join(f"{k} poses ({m.name})" for k, m in POSE_MODELS.items())
        raise InputError(where, "skeleton", expected, skeleton)
    return POSE_MODELS[skeleton]


# Z-up world -> Pose2Sim's Y-up file: (X, Y, Z)_file = (y, z, x)_world, a cyclic permutation.
_POSE2SIM_Y_UP = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
# C3D POINT:X_SCREEN / Y_SCREEN: a horizontal axis and the up axis of the file.
_SCREEN = {"pose2sim-y-up": ("+Z", "+Y"), "z-up": ("+X", "+Z")}


def marker_points(
    points: np.ndarray,
    joints: tuple[str, ...],
    markers: dict[str, tuple[str, ...]] = POSE2SIM_MARKERS,
    fallbacks: dict[str, tuple[str, ...]] | None = None,
) -> np.ndarray:
    """rmpl joints -> Pose2Sim markers.

    Args:
        points: joints in any units, shape (*, J, 3), NaN = missing; ``joints`` names the J.
        joints: the joint names of ``points`` (rmpl's COCO-17 or HALPE-26 names).
        markers: the pose model's markers (:attr:`PoseModel.markers`; default COCO_17's).
        fallbacks: :attr:`PoseModel.fallbacks`: stand-ins where a marker is missing.

    Returns:
        Markers, shape (*, M, 3), in the order of ``markers``; a derived marker (COCO_17's
        ``Hip``, ``Neck``) is NaN when either of its joints is.

    >>> from rmpl.skeleton import COCO17
    >>> p = np.zeros((17, 3)); p[5], p[6] = [0, 0, 1.4], [0.4, 0, 1.4]
    >>> marker_points(p, COCO17.joints)[7].tolist()  # Neck
    [0.2, 0.0, 1.4]
    """
    index = {name: i for i, name in enumerate(joints)}
    out = np.empty((*points.shape[:-2], len(markers), 3))
    for m, (name, sources) in enumerate(markers.items()):
        out[..., m, :] = points[..., [index[s] for s in sources], :].mean(-2)  # NaN stays NaN
        if fallbacks and name in fallbacks:
            other = points[..., [index[s] for s in fallbacks[name]], :].mean(-2)
            out[..., m, :] = np.where(np.isnan(out[..., m, :]), other, out[..., m, :])
    return out


def to_file_axes(points: np.ndarray, orientation: str) -> np.ndarray:
    """World coordinates (Z up) -> the file's axes, shape (*, 3) -> (*, 3).

    >>> to_file_axes(np.array([1.0, 2.0, 3.0]), "pose2sim-y-up").tolist()
    [2.0, 3.0, 1.0]
    """
    return points @ _POSE2SIM_Y_UP.T if orientation == "pose2sim-y-up" else points.copy()


def fill_gaps(x: np.ndarray) -> np.ndarray:
    """Linear interpolation over NaN runs along the first axis, shape (T, *) -> (T, *).

    Values before the first or after the last finite one of a column stay NaN.

    >>> fill_gaps(np.array([1.0, np.nan, 3.0, np.nan])).tolist()
    [1.0, 2.0, 3.0, nan]
    """
    flat = x.reshape(len(x), -1).copy()
    t = np.arange(len(x))
    for c in range(flat.shape[1]):
        ok = np.isfinite(flat[:, c])
        if ok.sum() < 2:
            continue
        inside = (t > t[ok][0]) & (t < t[ok][-1]) & ~ok
        flat[inside, c] = np.interp(t[inside], t[ok], flat[ok, c])
    return flat.reshape(x.shape)


def select_frames(
    markers: np.ndarray, missing: str, model: PoseModel = POSE_MODELS["coco17"]
) -> tuple[np.ndarray, np.ndarray]:
    """Which frames of one person to write, and their markers.

    Args:
        markers: one person's markers, shape (T, M, 3) in the order of ``model.markers``.
        missing: one of :data:`MISSING`.
        model: the pose model (default COCO_17).

    Returns:
        Row indices into T, shape (K,), increasing; and the markers of those rows, shape
        (K, M, 3) (gaps filled for ``"interpolate"``). K = 0 when no frame has all of
        ``model.ik_markers``.
    """
    names = list(model.markers)
    ik = [names.index(m) for m in model.ik_markers]
    complete = np.isfinite(markers[:, ik]).all((-1, -2))  # (T,)
    if not complete.any():
        return np.zeros(0, int), markers[:0]
    if missing == "complete":
        rows = np.flatnonzero(complete)
        return rows, markers[rows]
    first, last = np.flatnonzero(complete)[[0, -1]]
    rows = np.arange(first, last + 1)
    kept = markers[rows]
    return rows, fill_gaps(kept) if missing == "interpolate" else kept


def write_pose2sim(
    poses: Poses3D,
    folder: str | Path,
    stem: str = "poses",
    *,
    orientation: str = "pose2sim-y-up",
    units: str = "m",
    missing: str = "gaps",
    formats: tuple[str, ...] = ("trc", "c3d"),
    min_frames: int = 1,
) -> list[Path]:
    """Write one TRC and one C3D per person, as Pose2Sim's kinematics step reads them.

    Args:
        poses: COCO-17 or HALPE-26 poses (Pose2Sim's COCO_17 or HALPE_26 markers), world
            metres, Z up, with a frame rate.
        folder: output folder (created); a Pose2Sim trial's ``pose-3d/`` folder works.
        stem: file names are ``<stem>_p<person id>.<format>``.
        orientation: ``"pose2sim-y-up"`` (file = world (y, z, x)) or ``"z-up"``.
        units: ``"m"`` or ``"mm"`` (Pose2Sim's kinematics needs ``"m"``).
        missing: ``"gaps"``, ``"interpolate"`` or ``"complete"`` (see the module docstring).
        formats: any of ``"trc"``, ``"c3d"``.
        min_frames: a person present (any joint) in fewer frames gets no file (logged):
            a fragment too short for OpenSim's scaling and IK to say anything.

    Returns:
        The paths written, person by person (TRC before C3D). Each file is written
        atomically, and all are built before the first is written.

    Raises:
        InputError: neither COCO-17 nor HALPE-26, no frame rate, no frames or people, an
            unknown option, a bad ``stem``, or no person with all of the pose model's IK
            markers in some frame.
    """
    folder = Path(folder)
    _check_options(folder, stem, orientation, units, missing, formats)
    try:
        poses = dataclasses.replace(poses)  # validate again: fields may have changed since
    except InputError as e:
        raise InputError(folder, e.field, e.expected, e.got) from None
    model = pose_model(poses.skeleton, folder)
    if poses.fps is None:
        raise InputError(folder, "fps", "a frame rate in Poses3D.fps for TRC and C3D files")
    if poses.num_frames == 0 or poses.num_people == 0:
        raise InputError(folder, "points", "at least one frame and one person", poses.points.shape)
    if "c3d" in formats and poses.frames[0] < 0:
        raise InputError(folder, "frames", "frame numbers >= 0 for C3D", int(poses.frames[0]))

    markers = marker_points(poses.points, poses.joint_names, model.markers, model.fallbacks)
    names = tuple(model.markers)
    ik = ", ".join(model.ik_markers)
    files: list[tuple[Path, str, object]] = []
    present = ~np.isnan(poses.points).all((-1, -2))  # (T, P)
    for p, pid in enumerate(poses.person_ids.tolist()):
        if present[:, p].sum() < min_frames:
            log.info("person %d: %d frames (< %d); no Pose2Sim file", pid,
                     int(present[:, p].sum()), min_frames)  # fmt: skip
            continue
        rows, pts = select_frames(markers[:, p], missing, model)
        if len(rows) == 0:
            log.warning("person %d: no frame with all of %s; no Pose2Sim file", pid, ik)
            continue
        pts = to_file_axes(pts, orientation) / _UNITS[units]
        frames = poses.frames[rows]
        for fmt in formats:
            path = folder / f"{stem}_p{pid}.{fmt}"
            if fmt == "trc":
                text = trc_text(pts, frames, poses.fps, units, path.name, names)
                files.append((path, fmt, text))
            else:
                writer = _c3d_writer(pts, frames, poses.fps, units, orientation, names)
                files.append((path, fmt, writer))
    if not files:
        raise InputError(folder, "points", f"a person in {min_frames}+ frames with all of {ik} "
                         "in some frame", "none")  # fmt: skip
    for path, fmt, content in files:
        with atomic_path(path) as tmp:
            if fmt == "trc":
                tmp.write_text(content, encoding="utf-8")
            else:
                with warnings.catch_warnings(), open(tmp, "wb") as f:
                    warnings.filterwarnings("ignore", "No analog data", UserWarning)
                    content.write(f)
    log.debug("wrote %d Pose2Sim files into %s", len(files), folder)
    return [path for path, _, _ in files]


def _check_options(folder, stem, orientation, units, missing, formats) -> None:
    if orientation not in ORIENTATIONS:
        raise InputError(folder, "orientation", f"one of {ORIENTATIONS}", orientation)
    if units not in _UNITS:
        raise InputError(folder, "units", "'m' or 'mm'", units)
    if missing not in MISSING:
        raise InputError(folder, "missing", f"one of {MISSING}", missing)
    if not formats or not set(formats) <= {"trc", "c3d"}:
        raise InputError(folder, "formats", "one or both of 'trc', 'c3d'", formats)
    if not stem or "/" in stem or "\\" in stem or stem.startswith("."):
        raise InputError(folder, "stem", "a plain file name stem", stem)
    if "_LSTM" in stem or "_scaling" in stem:  # names Pose2Sim's kinematics skips
        raise InputError(folder, "stem", "a stem without '_LSTM' or '_scaling'", stem)


def trc_text(
    pts: np.ndarray,
    frames: np.ndarray,
    fps: float,
    units: str,
    name: str,
    markers: tuple[str, ...] = tuple(POSE2SIM_MARKERS),
) -> str:
    """One person's TRC file.

    Args:
        pts: markers in file units and axes, shape (K, M, 3), in the order of ``markers``.
        frames: rmpl frame numbers of the K rows, shape (K,).
        fps: frames per second.
        units: ``"m"`` or ``"mm"``, written in the header.
        name: the file name, written in the first line.
        markers: the M marker names (default: all of :data:`POSE2SIM_MARKERS`, COCO_17's).
    """
    K, M, _ = pts.shape
    rate = f"{fps:.12g}"
    header = [
        f"PathFileType\t4\t(X/Y/Z)\t{name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        "\t".join([rate, rate, str(K), str(M), units, rate, str(int(frames[0]) + 1), str(K)]),
        "Frame#\tTime\t" + "".join(f"{m}\t\t\t" for m in markers),
        "\t\t" + "".join(f"X{i}\tY{i}\tZ{i}\t" for i in range(1, M + 1)),
        "",
    ]
    flat = pts.reshape(K, 3 * M)
    text = np.char.mod("%.6f" if units == "m" else "%.3f", flat)  # micrometres either way
    text[np.isnan(flat)] = ""
    time = np.char.mod("%.6f", frames / fps)
    rows = [
        f"{f + 1}\t{t}\t" + "".join(v + "\t" for v in row)
        for f, t, row in zip(frames.tolist(), time, text.tolist(), strict=True)
    ]
    return "\n".join(header + rows) + "\n"


def _c3d_writer(
    pts: np.ndarray,
    frames: np.ndarray,
    fps: float,
    units: str,
    orientation: str,
    markers: tuple[str, ...] = tuple(POSE2SIM_MARKERS),
):
    """A ``c3d.Writer`` holding one person's markers (named ``markers``), frames
    ``frames[0]..frames[-1]``."""
    import c3d

    first, last = int(frames[0]), int(frames[-1])
    block = np.zeros((last - first + 1, pts.shape[1], 5), np.float32)
    block[..., 3] = -1.0  # residual -1: no point
    ok = np.isfinite(pts).all(-1)
    rows = frames - first
    block[rows, :, :3] = np.where(ok[..., None], pts, 0.0)
    block[rows, :, 3] = np.where(ok, 0.0, -1.0)
    writer = c3d.Writer(point_rate=fps, analog_rate=0.0, point_units=units)
    writer.set_point_labels(list(markers))
    writer.set_screen_axis(*_SCREEN[orientation])
    writer.set_start_frame(first + 1)
    no_analog = np.zeros((0, 0), np.float32)
    writer.add_frames([(frame, no_analog) for frame in block])
    return writer
