"""PNG plots of ``rmpl evaluate`` results (matplotlib, Agg backend, atomic writes).

The figure functions (:func:`joint_boxplot`, :func:`joint_bars`, :func:`sweep_plot`) take
already computed numbers (errors in millimetres) and a path, and write one figure; the
``*_plots`` functions choose the figures of one kind of run. No plot is written partially:
the file appears only when complete.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "benchmark_plots",
    "joint_bars",
    "joint_boxplot",
    "sphere_plots",
    "sweep_plot",
    "synthetic_plots",
]

log = logging.getLogger(__name__)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    from rmpl.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    _pyplot().close(fig)
    log.info("wrote %s", path)


def _short(joint: str) -> str:
    return joint.replace("left_", "L ").replace("right_", "R ")


def joint_boxplot(
    errors: dict[str, dict[str, dict[str, np.ndarray]]], path: Path, title: str = ""
) -> None:
    """Per-joint error distributions, one panel per view setting, one box per method.

    Args:
        errors: view label -> method -> joint -> errors (mm), shape (n,).
        path: the PNG to write.
    """
    plt = _pyplot()
    labels = list(errors)
    fig, axes = plt.subplots(len(labels), 1, figsize=(13, 3.2 * len(labels)), squeeze=False)
    for ax, label in zip(axes[:, 0], labels, strict=True):
        methods = list(errors[label])
        joints = list(errors[label][methods[0]]) if methods else []
        width = 0.8 / max(len(methods), 1)
        for i, m in enumerate(methods):
            data = [errors[label][m][j] if errors[label][m][j].size else [np.nan] for j in joints]
            pos = np.arange(len(joints)) + (i - (len(methods) - 1) / 2) * width
            bp = ax.boxplot(
                data,
                positions=pos,
                widths=width * 0.9,
                whis=(5, 95),
                showfliers=False,
                patch_artist=True,
                manage_ticks=False,
            )
            color = f"C{i}"
            for box in bp["boxes"]:
                box.set(facecolor=color, alpha=0.55)
            for med in bp["medians"]:
                med.set(color="black")
            ax.plot([], [], color=color, lw=6, alpha=0.55, label=m)
        ax.set_xticks(np.arange(len(joints)), [_short(j) for j in joints], rotation=45)
        ax.set_ylabel("error (mm)")
        ax.set_title(f"{title} — {label}" if title else label, fontsize=10)
        ax.set_ylim(bottom=0)
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    fig.text(0.01, 0.0, "boxes: quartiles; whiskers: 5th-95th percentile", fontsize=7)
    fig.tight_layout()
    _save(fig, path)


def joint_bars(mpjpe: dict[str, dict[str, dict[str, float]]], path: Path, title: str = "") -> None:
    """Per-joint MPJPE bars, one panel per view setting, one bar per method.

    Args:
        mpjpe: view label -> method -> joint -> MPJPE (mm).
    """
    plt = _pyplot()
    labels = list(mpjpe)
    fig, axes = plt.subplots(len(labels), 1, figsize=(13, 3.0 * len(labels)), squeeze=False)
    for ax, label in zip(axes[:, 0], labels, strict=True):
        methods = list(mpjpe[label])
        joints = list(mpjpe[label][methods[0]]) if methods else []
        width = 0.8 / max(len(methods), 1)
        for i, m in enumerate(methods):
            vals = np.array([mpjpe[label][m][j] for j in joints], float)
            pos = np.arange(len(joints)) + (i - (len(methods) - 1) / 2) * width
            ax.bar(pos, np.nan_to_num(vals), width * 0.95, label=m, color=f"C{i}")
        ax.set_xticks(np.arange(len(joints)), [_short(j) for j in joints], rotation=45)
        ax.set_ylabel("MPJPE (mm)")
        ax.set_title(f"{title} — {label}" if title else label, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    _save(fig, path)


def sweep_plot(
    curves: dict[str, tuple[Sequence[float], Sequence[float]]],
    path: Path,
    xlabel: str,
    ylabel: str = "MPJPE (mm)",
    title: str = "",
) -> None:
    """Lines of y against x, one per curve (e.g. MPJPE vs dropout p per method).

    Args:
        curves: legend label -> (x values, y values); NaN y values leave gaps.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    styles = ["-", "--", ":", "-."]
    methods = sorted({k.split(" | ")[0] for k in curves})
    groups = sorted({k.split(" | ")[1] if " | " in k else "" for k in curves})
    for key, (x, y) in curves.items():
        m = key.split(" | ")[0]
        g = key.split(" | ")[1] if " | " in key else ""
        ax.plot(
            x,
            y,
            marker="o",
            ms=4,
            color=f"C{methods.index(m)}",
            ls=styles[groups.index(g) % len(styles)],
            label=key,
        )
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, path)


# --------------------------------------------------------------------------- figure sets


def _mean_by_joint(errors: dict[str, dict[str, dict[str, np.ndarray]]]):
    """view label -> method -> joint -> mean error (mm), NaN where there is none."""
    return {
        label: {
            m: {j: float(e.mean()) if e.size else np.nan for j, e in d.items()}
            for m, d in per.items()
        }
        for label, per in errors.items()
    }


def _curves(rows: list[dict], keys, x: str, select) -> dict[str, tuple[list, list]]:
    """Legend label -> (x values, MPJPE) of the rows ``select(row, *key)`` keeps."""
    curves = {}
    for label, key in keys.items():
        sel = [r for r in rows if select(r, *key)]
        curves[label] = ([r[x] for r in sel], [r["mpjpe"] for r in sel])
    return curves


def benchmark_plots(out: Path, ev) -> None:
    """The figures of a real-dataset :class:`rmpl.evaluate.harness.Evaluation`: per-joint
    boxes and bars, and MPJPE against dropout, calibration noise and the number of views."""
    from rmpl.evaluate.scoring import joint_errors_mm
    from rmpl.evaluate.tables import results_rows

    cfg, name = ev.config, ev.evset.name
    errors = {
        label: {m: joint_errors_mm(ev, label, 0, m) for m in ev.methods} for label in ev.view_sets
    }
    title = f"{name}, per-joint error"
    joint_boxplot(errors, out / "joint_errors_box.png", title)
    joint_bars(_mean_by_joint(errors), out / "joint_mpjpe_bar.png", title.replace("error", "MPJPE"))
    rows = results_rows(ev)
    pairs = {f"{m} | {label}": (label, m) for label in ev.view_sets for m in ev.methods}
    if len(cfg.dropout) > 1:
        curves = _curves(
            rows,
            pairs,
            "dropout",
            lambda r, v, m: r["views"] == v and r["method"] == m and r["calib_noise"] == "none",
        )
        sweep_plot(
            curves,
            out / "dropout.png",
            "keypoint dropout probability p",
            title=f"{name}: MPJPE vs keypoint dropout",
        )
    if cfg.calib_noise is not None:
        _calib_plot(out, rows, pairs, cfg, name)
    counts = [label for label in ev.view_sets if label.split()[0].isdigit()]
    if len(counts) > 1:
        _views_plot(out, rows, ev.methods, counts, cfg, name)


def _calib_plot(out: Path, rows, pairs, cfg, name: str) -> None:
    curves = _curves(
        rows,
        pairs,
        "dropout",
        lambda r, v, m: r["views"] == v and r["method"] == m and r["dropout"] == cfg.dropout[0],
    )
    curves = {k: ([0, 1], y) for k, (_, y) in curves.items()}
    deg, mm = cfg.calib_noise[0], 1000 * cfg.calib_noise[1]
    sweep_plot(
        curves,
        out / "calib_noise.png",
        f"calibration noise (0 = none, 1 = {deg:g} deg / {mm:g} mm)",
        title=f"{name}: MPJPE with calibration noise",
    )


def _views_plot(out: Path, rows, methods, counts, cfg, name: str) -> None:
    curves = _curves(
        rows,
        {m: (m,) for m in methods},
        "views",
        lambda r, m: (
            r["method"] == m
            and r["views"] in counts
            and r["dropout"] == cfg.dropout[0]
            and r["calib_noise"] == "none"
        ),
    )
    curves = {k: ([int(v.split()[0]) for v in x], y) for k, (x, y) in curves.items()}
    sweep_plot(
        curves,
        out / "views.png",
        "number of views",
        title=f"{name}: MPJPE vs number of views",
    )


def synthetic_plots(out: Path, rows: list[dict], errors, dropout: tuple[float, ...]) -> None:
    """The figures of a synthetic run: per-joint boxes and bars (``errors``: view label ->
    method -> joint -> errors, mm), MPJPE against dropout and the number of views."""
    joint_boxplot(errors, out / "joint_errors_box.png", "synthetic, per-joint error")
    joint_bars(_mean_by_joint(errors), out / "joint_mpjpe_bar.png", "synthetic, per-joint MPJPE")
    methods = list(dict.fromkeys(r["method"] for r in rows))
    counts = list(dict.fromkeys(r["views"] for r in rows))
    if len(dropout) > 1:
        pairs = {f"{m} | {v} views": (m, v) for m in methods for v in counts}
        curves = _curves(
            rows,
            pairs,
            "dropout",
            lambda r, m, v: r["method"] == m and r["views"] == v and r["calib_noise"] == "none",
        )
        sweep_plot(
            curves,
            out / "dropout.png",
            "keypoint dropout probability p",
            title="synthetic: MPJPE vs keypoint dropout",
        )
    if len(counts) > 1:
        curves = _curves(
            rows,
            {m: (m,) for m in methods},
            "views",
            lambda r, m: (
                r["method"] == m and r["dropout"] == dropout[0] and r["calib_noise"] == "none"
            ),
        )
        sweep_plot(
            curves,
            out / "views.png",
            "number of views",
            title="synthetic: MPJPE vs number of views",
        )


def sphere_plots(out: Path, rows: list[dict], heights, angles, methods, radius: float) -> None:
    """The figures of the two-camera sphere sweep: MPJPE against the angle per method and
    height, on all joints and on the joints every method estimated."""

    def at(key: str, h: float, a: float, m: str) -> float:
        return next(
            x[key] for x in rows if x["height"] == h and x["angle"] == a and x["method"] == m
        )

    for key, path, title in (
        ("mpjpe", "sphere.png", f"two cameras on a {radius:g} m sphere: MPJPE vs angle"),
        (
            "mpjpe_common",
            "sphere_common_joints.png",
            "MPJPE vs angle on the joints every method estimated",
        ),
    ):
        curves = {
            f"{m} | {h:g} m": (angles, [at(key, h, a, m) for a in angles])
            for h in heights
            for m in methods
        }
        sweep_plot(curves, out / path, "horizontal angle between the cameras (deg)", title=title)
