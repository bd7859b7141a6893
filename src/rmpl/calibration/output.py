"""Write a calibration and its report as one unit: every file whole, or none.

Formats (``--format``, else from the suffix as ``rmpl convert-calib`` does): ``rmpl-toml``
(the default, ``.toml``), ``rmpl-json`` (``.json``), ``pose2sim`` (Pose2Sim's Calib.toml)
and ``anipose`` (anipose's calibration.toml; both in metres), ``easymocap`` (a folder with
``intri.yml`` and ``extri.yml``). The report (``calibration.md``, ``calibration.json``,
``calibration.png``) goes beside the calibration file (inside an EasyMocap folder).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.io.calibration import FORMATS, CalibOptions
from rmpl.io.calibration._write import write_all
from rmpl.io.calibration.registry import output_format

if TYPE_CHECKING:  # the chain (SciPy, OpenCV) is not imported to list the formats
    from rmpl.calibration.calibrate import Calibration

__all__ = ["OUTPUT_FORMATS", "write_calibration"]

#: ``--format`` name -> the calibration writer's format name.
OUTPUT_FORMATS = {
    "rmpl-toml": "rmpl-toml",
    "rmpl-json": "rmpl-json",
    "pose2sim": "anipose",
    "anipose": "anipose",
    "easymocap": "easymocap",
}


def write_calibration(cal: Calibration, out: str | Path, fmt: str | None = None) -> list[Path]:
    """Write ``cal`` to ``out`` and its report beside it; returns the files written."""
    from rmpl.calibration.report import report_files

    out = Path(out)
    if cal.fisheye:
        raise InputError(
            out, "--fisheye", "a pinhole lens model for the calibration formats rmpl writes "
            "(the fisheye lenses are in the report only); drop --fisheye", "fisheye",
        )  # fmt: skip
    name = OUTPUT_FORMATS[fmt] if fmt else output_format(out)
    writer = FORMATS[name][1]
    files = dict(writer(cal.rig, out, CalibOptions(units="m")))
    folder = out if name == "easymocap" else out.parent
    md, js, png = report_files(cal, str(out))
    stem = "calibration" if folder / "calibration.json" not in files else "calibration.report"
    files[folder / f"{stem}.md"] = md
    files[folder / f"{stem}.json"] = js
    write_all(files)
    picture = folder / f"{stem}.png"
    with atomic_path(picture) as tmp:
        tmp.write_bytes(png)
    return [*files, picture]
