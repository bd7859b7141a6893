"""The calibration's report: ``calibration.md``, ``calibration.json`` and ``calibration.png``.

Per camera: the reprojection RMS in pixels, the images used and dropped (named), the
board-coverage map (how many views covered each cell of a 12 x 12 grid of the image) and
the camera centre's standard deviation from the bundle adjustment's covariance (relative
to the reference camera, which fixes the frame, and the board's scale).
"""

from __future__ import annotations

import io
import json

import numpy as np

from rmpl.calibration.calibrate import Calibration

__all__ = ["report_files"]


def _num(x: float, fmt: str = ".2f") -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, fmt)


def report_json(cal: Calibration, calib_path: str) -> dict:
    cams = []
    for v, cam in enumerate(cal.rig):
        lens = cal.lenses[v]
        cams.append({
            "name": cam.name,
            "rms_px": cal.rms[v],
            "lens_rms_px": lens.rms,
            "focal_px": [float(cam.K[0, 0]), float(cam.K[1, 1])],
            "principal_point_px": [float(cam.K[0, 2]), float(cam.K[1, 2])],
            "distortion": [float(d) for d in lens.dist] if cal.fisheye else cam.dist.tolist(),
            "centre_m": cam.center.tolist(),
            "centre_std_mm": [float(s) for s in cal.centre_std_mm[v]],
            "lens_images_used": list(lens.used),
            "views_used": int(cal.views_used[v]),
            "dropped": list(cal.views_dropped[v]),
            "coverage": cal.coverage[v].tolist(),
        })  # fmt: skip
    return {
        "calibration": calib_path,
        "board": cal.board.spec(),
        "lens_model": "fisheye (k1..k4)" if cal.fisheye else "pinhole (k1, k2, p1, p2, k3)",
        "world": cal.world,
        "links": [{"cameras": [a, b], "shared_views": n} for a, b, n in cal.edges],
        "seconds": cal.seconds,
        "cameras": cams,
    }


def report_markdown(doc: dict) -> str:
    lines = [
        "# Camera calibration", "",
        f"- calibration: `{doc['calibration']}`", f"- board: `{doc['board']}`",
        f"- lens model: {doc['lens_model']}", f"- world: {doc['world']}",
        f"- took {doc['seconds']:.1f} s", "",
        "| camera | RMS px | lens RMS px | focal px | centre m | centre std mm | views | dropped |",
        "|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for c in doc["cameras"]:
        centre = ", ".join(f"{x:.3f}" for x in c["centre_m"])
        std = ", ".join(_num(s, ".1f") for s in c["centre_std_mm"])
        lines.append(
            f"| {c['name']} | {_num(c['rms_px'])} | {_num(c['lens_rms_px'])} | "
            f"{c['focal_px'][0]:.1f} | {centre} | {std} | {c['views_used']} | {len(c['dropped'])} |"
        )
    if doc["links"]:
        lines += ["", "Cameras linked by shared board views (the spanning tree):", ""]
        lines += [f"- {a} - {b}: {n} views" for (a, b), n in
                  ((x["cameras"], x["shared_views"]) for x in doc["links"])]  # fmt: skip
    dropped = [(c["name"], d) for c in doc["cameras"] for d in c["dropped"]]
    if dropped:
        lines += ["", "Dropped as outliers:", ""] + [f"- {n}: {d}" for n, d in dropped]
    lines += ["", "Board coverage of each image (darker: more views): `calibration.png`.", ""]
    return "\n".join(lines)


def coverage_png(cal: Calibration) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    V = len(cal.rig)
    fig, axes = plt.subplots(1, V, figsize=(3.2 * V, 2.6), squeeze=False)
    for ax, cam, cover, rms in zip(axes[0], cal.rig, cal.coverage, cal.rms, strict=True):
        w, h = cam.size or (1, 1)
        ax.imshow(cover, cmap="Greys", extent=(0, w, h, 0), vmin=0)
        ax.set_title(f"{cam.name}: {_num(rms)} px", fontsize=9)
        ax.set_xticks([]), ax.set_yticks([])
    fig.suptitle("board coverage (views per image cell)", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


def report_files(cal: Calibration, calib_path: str) -> tuple[str, str, bytes]:
    """(markdown, JSON text, PNG bytes) of the report."""
    doc = report_json(cal, calib_path)
    return report_markdown(doc), json.dumps(doc, indent=1), coverage_png(cal)
