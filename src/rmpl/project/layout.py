"""Find the trials of a project folder: Pose2Sim's layout and rmpl's own.

**Pose2Sim** (its README, "batch processing"): a session folder holds ``calibration/`` and a
``Config.toml``; below it trial folders (optionally grouped in participant folders), each
with its own ``Config.toml`` and its ``videos/``; after Pose2Sim's pose estimation a trial
has ``pose/`` (one OpenPose JSON folder per camera), after its synchronisation
``pose-sync/``. A single trial (``calibration/``, ``videos/``, ``Config.toml`` in one
folder) is a project of one trial.

**rmpl's own**: ``PROJECT/calibration/`` and one folder per trial holding its videos, its
image folders (one per camera) or its 2D files (rmpl, COCO or OpenPose JSON, per-camera
OpenPose folders). An ``rmpl.toml`` at any level sets ``rmpl run`` options
(:mod:`rmpl.project.options`).

A trial's input, the first found: ``pose-sync/``, ``pose/`` (2D), ``videos/`` (video files,
or image folders); else, in the trial folder itself, 2D files or folders, video files, image
folders. Its calibration: the nearest ``calibration/`` from the trial up to the project (a
trial's own overrides the project's); in it the one calibration file (with several,
Pose2Sim's converted ``Calib*.toml``; EasyMocap's ``intri.yml`` folder as a whole). A folder
without inputs is a participant when trials are below it, a trial without inputs (an error
of that trial) when it has a configuration file, and is passed over otherwise.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from rmpl.project.options import CONFIG_NAME, POSE2SIM_CONFIG

__all__ = ["Trial", "find_trials"]

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm", ".mpg", ".mpeg")
KEYPOINT_SUFFIXES = (".json", ".npz")
CALIB_SUFFIXES = (".toml", ".json", ".yml", ".yaml", ".pkl", ".pickle", ".xml", ".qca", ".txt")
#: Folders of a trial that are never inputs (Pose2Sim's outputs, calibration).
_NOT_INPUTS = {"calibration", "pose-3d", "pose-associated", "opensim", "kinematics"}
_MAX_DEPTH = 3  # session / participant / trial


@dataclass
class Trial:
    """One trial of a project.

    Attributes:
        name: its folder relative to the project, ``/``-separated (the project's own name
            for a one-trial project).
        folder: its folder.
        calib: its calibration file (or EasyMocap folder), None when none was found.
        source: ``"keypoints"``, ``"videos"`` or ``"images"``; None without inputs.
        inputs: the paths for ``rmpl run --<source>``.
        configs: the ``rmpl.toml`` files that apply, the project's first.
        pose2sim: the Pose2Sim ``Config.toml`` files that apply, the session's first.
        layout: ``"pose2sim"`` (inputs in videos/, pose/ or pose-sync/) or ``"rmpl"``.
        missing: what the layout could not find, one line each: key ``"calib"`` or
            ``"source"`` (an ``rmpl.toml`` naming ``calib`` or an input makes up for it).
        notes: what the layout chose, for the log and the summary.
    """

    name: str
    folder: Path
    calib: Path | None = None
    source: str | None = None
    inputs: list[Path] = field(default_factory=list)
    configs: list[Path] = field(default_factory=list)
    pose2sim: list[Path] = field(default_factory=list)
    layout: str = "rmpl"
    missing: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _visible_dirs(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith("."))


def _files(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    return sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and not p.name.startswith(".") and p.name.lower().endswith(suffixes)
    )


def _image_dirs(folder: Path) -> list[Path]:
    from rmpl.pipeline.detect2d import IMAGE_SUFFIXES

    return [d for d in _visible_dirs(folder) if _files(d, IMAGE_SUFFIXES)]


def _is_output(folder: Path) -> bool:
    """An output folder of rmpl (a run's or a batch's), never an input."""
    return any(
        (folder / n).is_file() for n in ("summary.json", "report.json", ".rmpl-outputs.json")
    )


def _json_dirs(folder: Path) -> list[Path]:
    return [d for d in _visible_dirs(folder) if _files(d, (".json",)) and not _is_output(d)]


def _pose2sim_inputs(folder: Path) -> tuple[str, list[Path], str] | None:
    for name in ("pose-sync", "pose"):
        d = folder / name
        if d.is_dir() and (_json_dirs(d) or _files(d, KEYPOINT_SUFFIXES)):
            return "keypoints", [d], f"2D from {name}/"
    d = folder / "videos"
    if d.is_dir():
        if videos := _files(d, VIDEO_SUFFIXES):
            return "videos", videos, f"{len(videos)} videos from videos/"
        if images := _image_dirs(d):
            return "images", images, f"{len(images)} image folders from videos/"
    return None


def _own_inputs(folder: Path) -> tuple[str, list[Path], str] | None:
    names = {CONFIG_NAME.lower(), POSE2SIM_CONFIG.lower()}
    files = [p for p in _files(folder, KEYPOINT_SUFFIXES) if p.name.lower() not in names]
    subdirs = [d for d in _json_dirs(folder) if d.name not in _NOT_INPUTS]
    if files or subdirs:
        found = files + subdirs
        names = ", ".join(p.name for p in found[:4]) + (" ..." if len(found) > 4 else "")
        return "keypoints", found, f"2D from {names}"
    if videos := _files(folder, VIDEO_SUFFIXES):
        return "videos", videos, f"{len(videos)} videos"
    if images := [d for d in _image_dirs(folder) if d.name not in _NOT_INPUTS]:
        return "images", images, f"{len(images)} image folders"
    return None


def _inputs(folder: Path) -> tuple[str, tuple[str, list[Path], str] | None]:
    found = _pose2sim_inputs(folder)
    if found is not None:
        return "pose2sim", found
    return "rmpl", _own_inputs(folder)


def _calibration_file(folder: Path) -> tuple[Path | None, str | None]:
    """The calibration in a ``calibration/`` folder, or (None, why not)."""
    if (folder / "intri.yml").is_file():
        return folder, None
    files = _files(folder, CALIB_SUFFIXES)
    if len(files) == 1:
        return files[0], None
    converted = [f for f in files if f.name.lower().startswith("calib") and f.suffix == ".toml"]
    if len(converted) == 1:
        return converted[0], None
    if not files:
        return None, f"{folder}: expected a calibration file, got none"
    names = ", ".join(f.name for f in files)
    return (
        None,
        f"{folder}: expected one calibration file (or calib = ... in rmpl.toml), got {names}",
    )


def _describe(trial: Trial, root: Path) -> None:
    """Fill the trial's inputs and calibration, or what is missing."""
    trial.layout, found = _inputs(trial.folder)
    if found is None:
        trial.missing["source"] = (
            f"{trial.folder}: expected videos, image folders or 2D files, got none"
        )
    else:
        trial.source, trial.inputs, note = found
        trial.notes.append(note)
    for d in [trial.folder, *trial.folder.parents]:
        if (d / "calibration").is_dir():
            trial.calib, why = _calibration_file(d / "calibration")
            if why:
                trial.missing["calib"] = why
            return
        if d == root:
            break
    trial.missing["calib"] = (
        f"{trial.folder}: expected a calibration/ folder here or above it (up to {root}), "
        "or calib = ... in rmpl.toml, got none"
    )


def _configs(folder: Path, root: Path, name: str) -> list[Path]:
    chain = [folder]
    while chain[-1] != root and root in chain[-1].parents:
        chain.append(chain[-1].parent)
    return [d / name for d in reversed(chain) if (d / name).is_file()]


def _walk(folder: Path, root: Path, skip: set[Path], depth: int) -> list[Trial]:
    """The trials at or below ``folder``: the folder itself when it has inputs (the project
    folder only with Pose2Sim's input folders, or with nothing below), else those below."""
    if folder != root and _inputs(folder)[1] is not None:
        return [_trial(folder, root)]
    if folder == root and _pose2sim_inputs(folder) is not None:
        return [_trial(folder, root)]
    found: list[Trial] = []
    for d in _visible_dirs(folder) if depth > 0 else []:
        if d.name not in _NOT_INPUTS and d.resolve() not in skip and not _is_output(d):
            found += _walk(d, root, skip, depth - 1)
    if found:
        return found
    if folder == root:
        return [_trial(folder, root)] if _own_inputs(folder) is not None else []
    if (folder / CONFIG_NAME).is_file() or (folder / POSE2SIM_CONFIG).is_file():
        return [_trial(folder, root)]  # a trial without inputs: said, not passed over
    log.info("%s: no inputs and no trial below it; passed over", folder)
    return []


def _trial(folder: Path, root: Path) -> Trial:
    name = folder.relative_to(root).as_posix() if folder != root else root.resolve().name
    trial = Trial(name=name, folder=folder)
    trial.configs = _configs(folder, root, CONFIG_NAME)
    trial.pose2sim = _configs(folder, root, POSE2SIM_CONFIG)
    _describe(trial, root)
    return trial


def find_trials(root: str | Path, skip: list[Path] | None = None) -> list[Trial]:
    """The trials of the project at ``root``, in name order.

    Args:
        root: the project (session) folder, or one trial's folder.
        skip: folders not to look into (the output folder, when inside the project).

    Returns:
        The trials; one whose inputs or calibration were not found says so in ``missing``.
    """
    from rmpl.errors import InputError

    root = Path(root)
    if not root.is_dir():
        raise InputError(root, None, "a project folder", "no such folder")
    skipped = {p.resolve() for p in skip or []}
    trials = _walk(root, root, skipped, _MAX_DEPTH)
    return sorted(trials, key=lambda t: t.name)
