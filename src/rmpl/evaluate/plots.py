"""PNG plots of ``rmpl evaluate`` results (matplotlib, Agg backend, atomic writes).

Every function takes already computed numbers (errors in millimetres) and a path, and
writes one figure. No plot is written partially: the file appears only when complete.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["joint_boxplot", "joint_bars", "sweep_plot"]

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
