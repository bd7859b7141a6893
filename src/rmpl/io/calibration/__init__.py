"""Camera calibration files: read many formats into a :class:`~rmpl.geometry.camera.Rig`.

Every reader returns cameras in rmpl's convention (see :mod:`rmpl.geometry.camera`):
world -> camera ``x = R X + t``, centre ``C = -R^T t``, pixels from the top-left corner,
OpenCV distortion ``(k1, k2, p1, p2, k3)``, lengths in metres.

Formats (``FORMATS[name] = (reader, writer or None)``):

============  =====  ==================================================================
name          write  file and units
============  =====  ==================================================================
rmpl-toml     yes    our own TOML, described below; units from ``[metadata] units``
rmpl-json     yes    the same document as JSON
anipose       yes    anipose / Pose2Sim TOML: one table per camera with ``name``,
                     ``size``, ``matrix``, ``distortions`` (4 or 5), ``rotation``
                     (Rodrigues), ``translation``, ``fisheye``; plus ``[metadata]``.
                     Pose2Sim writes metres; anipose uses the unit of the calibration
                     board (often mm), so pass ``units`` when it is not metres.
panoptic      yes    CMU Panoptic ``calibration_<seq>.json``; ``t`` in centimetres;
                     ``camera_type`` picks ``hd`` (default), ``vga``, ``kinect-color``
                     or ``all``. Cameras are named as in the file (``"00_03"``).
shelf4d       yes    4D-association Shelf/Campus ``calibration.json``: per camera ``K``
                     (9 numbers), ``RT`` (12 numbers, row-major ``[R | t]``), ``imgSize``;
                     metres; no distortion (writing a distorted camera is refused).
voxelpose     yes    VoxelPose ``calibration_shelf.json`` / ``calibration_campus.json``:
                     per camera ``R``, ``T`` (the camera CENTRE in world millimetres),
                     ``fx fy cx cy``, ``k`` (k1 k2 k3), ``p`` (p1 p2). No image size
                     and no skew.
easymocap     yes    EasyMocap OpenCV FileStorage YAML: ``intri.yml`` (``names``,
                     ``K_<name>``, ``dist_<name>``, optional ``H_<name>``/``W_<name>``)
                     and ``extri.yml`` (``R_<name>`` Rodrigues, ``Rot_<name>``,
                     ``T_<name>``) in one folder; metres. Pass the folder or either file.
h36m          no     Human3.6M ``camera-parameters.json`` (``intrinsics`` per camera id,
                     ``extrinsics`` per subject; ``t`` in millimetres); ``subject``
                     picks the subject (default ``S1``). Image sizes are the dataset's.
h36m-pkl      no     the H36M ``cameras.pkl`` used by mmpose: a dict keyed by
                     ``(subject, camera id)`` with ``R`` (camera -> world, i.e. the
                     transpose of rmpl's R), ``T`` (camera centre, metres), ``f``, ``c``,
                     ``k``, ``p``, ``w``, ``h``. Loaded with an unpickler that accepts
                     only plain containers and numpy arrays.
qualisys      no     Qualisys ``.qca.txt`` XML as read by Pose2Sim: video cameras only,
                     sorted by serial; focal length and principal point in 1/64 pixel,
                     divided by ``binning_factor`` and rescaled to the video resolution,
                     principal point shifted by the video window offset; distortion
                     (k1 k2 p1 p2) divided by 64 and the binning factor as Pose2Sim does;
                     ``transform`` holds the camera pose (position in mm, rotation with
                     the camera axes as columns) whose y and z axes are flipped to reach
                     OpenCV's camera frame.
============  =====  ==================================================================

``units`` (``"m"``, ``"cm"`` or ``"mm"``) is the length unit of the translations in the
file. ``None`` means the format's own unit above; a value overrides it.

The rmpl format (TOML shown; the JSON form holds the same keys)::

    [metadata]
    format = "rmpl"
    version = 1
    units = "m"
    convention = "world->camera x = R X + t; ..."

    [[cameras]]
    name = "cam0"
    K = [[1000.0, 0.0, 640.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]]   # pixels
    R = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]             # world->camera
    t = [0.0, 0.0, 3.0]                                                 # in `units`
    dist = [0.0, 0.0, 0.0, 0.0, 0.0]                                    # k1 k2 p1 p2 k3
    size = [1280, 720]                                                  # width, height

``name``, ``K``, ``R`` and ``t`` are required; ``dist`` defaults to zeros and ``size`` to
unknown. Every reader validates what it reads and raises :class:`rmpl.errors.InputError`
naming the file and the field for missing keys, wrong shapes, non-finite numbers, matrices
that are not rotations, empty files and unknown formats.

Layout: one module per format family: :mod:`.native` (rmpl TOML and JSON),
:mod:`.anipose`, :mod:`.panoptic`, :mod:`.shelf` (4D-association and VoxelPose),
:mod:`.easymocap`, :mod:`.h36m` and :mod:`.qualisys`. :mod:`.registry` maps a format name
to its reader and writer and tells a file's format; :mod:`._base` holds the validation
every reader shares.
"""

from __future__ import annotations

import logging
from pathlib import Path

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.io.calibration._base import CAMERA_TYPES, UNITS, CalibOptions
from rmpl.io.calibration._write import write_all
from rmpl.io.calibration.h36m import load_plain_pickle
from rmpl.io.calibration.registry import FORMATS, detect_format, lookup, output_format, writable

__all__ = [
    "FORMATS",
    "UNITS",
    "CAMERA_TYPES",
    "CalibOptions",
    "detect_format",
    "load_plain_pickle",
    "load_rig",
    "save_rig",
]

log = logging.getLogger(__name__)


def load_rig(
    path: str | Path,
    format: str | None = None,
    *,
    units: str | None = None,
    camera_type: str = "hd",
    subject: str = "S1",
    binning_factor: int = 1,
) -> Rig:
    """Read a calibration file (or an EasyMocap folder) into a rig.

    Args:
        path: the calibration file; for EasyMocap the folder or either YAML file.
        format: a key of :data:`FORMATS`; None detects it from the extension and content.
        units: length unit of the file's translations ("m", "cm", "mm"); None for the
            format's own unit (see the module docstring).
        camera_type: Panoptic only: "hd", "vga", "kinect-color" or "all".
        subject: Human3.6M only: the subject whose extrinsics to read.
        binning_factor: Qualisys only: the pixel binning factor.

    Returns:
        The V cameras, translations in metres.

    Raises:
        InputError: the file is missing, empty, of an unknown format, or holds a bad field.
    """
    path = Path(path)
    name = format or detect_format(path)
    reader = lookup(path, name)[0]
    options = CalibOptions(units, camera_type, subject, binning_factor)
    rig = reader(path, options)
    log.debug("read %d cameras (%s) from %s as %s", len(rig), ", ".join(rig.names), path, name)
    return rig


def save_rig(
    rig: Rig,
    path: str | Path,
    format: str | None = None,
    *,
    units: str | None = None,
    camera_type: str = "hd",
) -> None:
    """Write a rig; its files (two for EasyMocap) appear whole and together, or not at all.

    Args:
        rig: the V cameras, translations in metres.
        path: output file; for EasyMocap a folder (or its ``intri.yml``).
        format: a writable key of :data:`FORMATS`; None picks it from the extension
            (``.toml`` rmpl-toml, ``.json`` rmpl-json, ``.yml``/``.yaml`` or no extension
            easymocap).
        units: length unit to write translations in; None for the format's own unit.
        camera_type: Panoptic only: the ``type`` written for every camera; "all" derives
            it from Panoptic names ("00_*" hd, "50_*" kinect-color, others vga).

    Raises:
        InputError: unknown or read-only format, or a rig the format cannot represent
            (distortion for shelf4d, skew for voxelpose, unsafe names for easymocap).
    """
    path = Path(path)
    name = format or output_format(path)
    writer = lookup(path, name)[1]
    if writer is None:
        raise InputError(path, "format", f"a writable format, one of {writable()}", name)
    files = writer(rig, path, CalibOptions(units=units, camera_type=camera_type))
    write_all(files)
    log.debug("wrote %d cameras to %s as %s", len(rig), path, name)
