"""``rmpl calibrate --from-people`` / ``--refine``: read, calibrate, write the calibration
and its report (``calibration.md`` and ``calibration.json`` beside ``--out``), atomically.

The report gives each camera's reprojection RMS (pixels, observations kept) and the
1-sigma uncertainty of its centre (the largest axis of the bundle adjustment's covariance,
millimetres), the people and frames used, the scale's source and uncertainty, the floor,
and with ``--refine`` how far each camera moved.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError

__all__ = ["report_dict", "report_markdown", "run_cli"]

log = logging.getLogger(__name__)


def report_dict(cal, mode: str, sync: dict | None = None) -> dict:
    return {
        "format": "rmpl.calibration-report",
        "version": 1,
        "method": mode,
        "cameras": [
            {
                "name": c.name,
                "reprojection_rms_px": round(float(cal.rms[v]), 3),
                "centre_sd_mm": round(1000 * float(cal.centre_sd[v]), 2),
                "centre_sd_of_distance": None
                if not len(cal.centre_sd_relative)
                else round(float(cal.centre_sd_relative[v]), 4),
                "centre_m": [round(float(x), 4) for x in c.center],
            }
            for v, c in enumerate(cal.rig)
        ],
        "scale": {"source": cal.scale_source, "relative_sd": round(float(cal.scale_sd), 4)},
        "floor": cal.floor,
        "people": cal.people,
        "frames_used": [int(f) for f in cal.frames_used],
        "observations": {"kept": cal.observations[0], "total": cal.observations[1]},
        "moved": cal.moved,
        "sync": sync,
        "warnings": cal.warnings,
    }


def _sync_line(sync: dict | None) -> str:
    if not sync:
        return "Synchronisation: none (the cameras taken as started together)."
    offsets = {n: c["offset_frames"] for n, c in sync["cameras"].items()}
    return f"Synchronisation: {sync.get('source')}, offsets in frames {offsets}."


def report_markdown(doc: dict) -> str:
    lines = [f"# Calibration from people ({doc['method']})", ""]
    if doc.get("warnings"):
        lines += [f"**WARNING: {w}.**" for w in doc["warnings"]] + [""]
    lines += [
        "| camera | reprojection RMS (px) | centre 1-sigma (mm) | of its distance to the people |",
        "|---|---|---|---|",
    ]
    for c in doc["cameras"]:
        rel = c.get("centre_sd_of_distance")
        rel = "" if rel is None else f"{100 * rel:.1f}%"
        lines.append(f"| {c['name']} | {c['reprojection_rms_px']:.2f} | "
                     f"{c['centre_sd_mm']:.1f} | {rel} |")  # fmt: skip
    sc = doc["scale"]
    obs = doc["observations"]
    lines += [
        "",
        f"Scale: {sc['source']}, +-{100 * sc['relative_sd']:.1f}%.",
        f"Floor: {doc['floor']}.",
        _sync_line(doc.get("sync")),
        f"People: {len(doc['people'])}; frames used: {len(doc['frames_used'])}; "
        f"observations kept: {obs['kept']} of {obs['total']}.",
    ]
    for p in doc["people"]:
        lines.append(
            f"- person {p['person']}: {p['frames']} frames, per camera {p['frames_per_camera']}, "
            f"{p['observations']} "
            f"observations, stature {p['stature_m']} m"
        )
    if doc["moved"]:
        lines += ["", "| camera | rotation moved (deg) | centre moved (mm) |", "|---|---|---|"]
        for m in doc["moved"]:
            lines.append(
                f"| {m['camera']} | {m['rotation_deg']:.2f} | {1000 * m['centre_m']:.0f} |"
            )
    return "\n".join(lines) + "\n"


def _report_paths(out: Path) -> tuple[Path, Path]:
    md, js = out.parent / "calibration.md", out.parent / "calibration.json"
    if out.resolve() in (md.resolve(), js.resolve()):
        md, js = out.with_name(out.stem + ".report.md"), out.with_name(out.stem + ".report.json")
    return md, js


def _load(args: argparse.Namespace):
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    if not getattr(args, "calib", None):
        raise InputError(None, "--calib", "the intrinsics (a calibration file)")
    spec = InputSpec(
        args.calib,
        getattr(args, "keypoints", None),
        getattr(args, "videos", None),
        skeleton=getattr(args, "skeleton", None),
        sync=getattr(args, "sync", None),
    )
    cache = Path(args.out).with_suffix(".keypoints2d.npz") if spec.videos else None
    inputs = load_inputs(spec, cache)
    sync = getattr(args, "sync", None)
    if sync is not None:
        from rmpl.calibration.sync import synced_inputs

        if sync == "auto":
            raise InputError(None, "--sync", "a sync.json from rmpl sync (auto needs a "
                             "calibration's extrinsics)", sync)  # fmt: skip
        inputs = synced_inputs(inputs, sync, args.calib)
    return inputs


def run_cli(args: argparse.Namespace) -> int:
    """Calibrate from people (``args.from_people``) or correct ``args.refine``; writes
    ``args.out`` in ``args.format`` and the report beside it. Returns 0, or 3 when a
    camera's place is unreliable (everything is written; the report and log warn)."""
    from rmpl.calibration.people import calibrate_from_people
    from rmpl.io.atomic import atomic_path
    from rmpl.io.calibration import load_rig, save_rig

    if not getattr(args, "out", None):
        raise InputError(None, "--out", "an output calibration file")
    inputs = _load(args)
    refine = getattr(args, "refine", None)
    start = None
    if refine:
        start = load_rig(refine)
        if start.names != inputs.rig.names:
            raise InputError(refine, "cameras", f"the cameras {inputs.rig.names}", start.names)
    dist = getattr(args, "camera_distance", None)
    dist = None if not dist else (str(dist[0]), str(dist[1]), _metres(dist[2]))
    source = ", ".join(getattr(args, "keypoints", None) or getattr(args, "videos", None) or [])
    cal = calibrate_from_people(
        inputs.keypoints,
        inputs.scores,
        inputs.rig,
        start=start,
        height=getattr(args, "height", None),
        camera_distance=dist,
        max_frames=getattr(args, "max_frames", None) or 200,
        source=source,
    )
    out = Path(args.out)
    save_rig(cal.rig, out, getattr(args, "format", None))
    doc = report_dict(cal, "refine" if refine else "from people", getattr(inputs, "sync", None))
    md, js = _report_paths(out)
    with atomic_path(js) as tmp:
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    with atomic_path(md) as tmp:
        tmp.write_text(report_markdown(doc), encoding="utf-8")
    for c in doc["cameras"]:
        log.info(
            "%s: %.2f px RMS, centre +-%.1f mm",
            c["name"],
            c["reprojection_rms_px"],
            c["centre_sd_mm"],
        )
    log.info("scale: %s (+-%.1f%%); wrote %s and %s", cal.scale_source, 100 * cal.scale_sd, out, md)
    for w in cal.warnings:
        log.warning("WARNING: %s", w)
    return 3 if cal.warnings else 0


def _metres(x) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        v = float("nan")
    if not np.isfinite(v) or v <= 0:
        raise InputError(None, "--camera-distance", "CAM_A CAM_B METRES with METRES > 0", x)
    return v
