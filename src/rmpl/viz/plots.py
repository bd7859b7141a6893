"""Pictures of results: 3D skeletons with the cameras, and 2D reprojection overlays."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rmpl.geometry.camera import Rig
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17, Skeleton

__all__ = ["plot_skeletons", "plot_reprojection"]

_COLORS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]


def _bone_color(skeleton: Skeleton, a: int, b: int) -> str:
    names = skeleton.joints[a] + skeleton.joints[b]
    return (
        "tab:red"
        if "left" in names and "right" not in names
        else ("tab:blue" if "right" in names and "left" not in names else "0.3")
    )


def plot_skeletons(
    poses: np.ndarray,
    path: str | Path,
    rig: Rig | None = None,
    frames: list[int] | None = None,
    skeleton: Skeleton = COCO17,
    reference: np.ndarray | None = None,
    title: str = "",
) -> Path:
    """Draw 3D skeletons (left side red, right blue) with camera centres, to a PNG.

    Args:
        poses: (T, P, J, 3) or (T, J, 3) world metres.
        path: output PNG.
        rig: cameras to draw (optional).
        frames: which frames to draw side by side (default: up to 4 spread over T).
        reference: optional ground truth, same shape as ``poses``, drawn dashed grey.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P = np.asarray(poses, float)
    if P.ndim == 3:
        P = P[:, None]
    ref = None if reference is None else np.asarray(reference, float).reshape(P.shape)
    T = P.shape[0]
    frames = frames or sorted(set(np.linspace(0, T - 1, min(4, T)).astype(int).tolist()))
    panels = len(frames) + (rig is not None)
    fig = plt.figure(figsize=(4.2 * panels, 4.6))
    if rig is not None:  # a top view of the cameras and the person's path
        _top_view(fig.add_subplot(1, panels, 1), rig, P)
    centre = np.nanmean(P[frames], axis=(0, 1, 2))
    half = 1.0  # half the side of the cube shown, grown to fit every frame so far
    for k, t in enumerate(frames):
        ax = fig.add_subplot(1, panels, k + 1 + (rig is not None), projection="3d")
        X, X_ref = P[t], None if ref is None else ref[t]
        half = _skeleton_panel(ax, X, X_ref, skeleton, centre, half)
        ax.set_title(f"frame {t}", fontsize=9)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _top_view(ax, rig: Rig, P: np.ndarray) -> None:
    """The cameras seen from above, and the path of the people's mean (T, P, J, 3)."""
    C = rig.centers
    ax.scatter(*C[:, :2].T, marker="^", color="k")
    for c, name in zip(C, rig.names, strict=True):
        ax.annotate(name, c[:2], fontsize=7)
    path_xy = np.nanmean(P, axis=(1, 2))[:, :2]
    ax.plot(*path_xy.T, color="tab:green", lw=2, label="person")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("top view: cameras and path", fontsize=9)


def _skeleton_panel(ax, X, X_ref, skeleton: Skeleton, centre, half: float) -> float:
    """One frame's people X (P, J, 3) and reference (or None) in a cube around them (or
    ``centre`` when none is seen) of half side ``half`` at least; returns the half side."""
    seen = np.isfinite(X).any()
    mid = np.nanmean(X, axis=(0, 1)) if seen else centre
    half = max(half, float(np.nanmax(np.abs(X - mid))) + 0.1) if seen else half
    for p in range(X.shape[0]):
        for a, b in skeleton.bones:
            if X_ref is not None:
                ax.plot(*X_ref[p, [a, b]].T, color="0.6", ls="--", lw=1)
            ax.plot(*X[p, [a, b]].T, color=_bone_color(skeleton, a, b), lw=2)
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    return half


def _save(fig, path: str | Path) -> Path:
    """Write the figure to a PNG atomically and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
    return path


def plot_reprojection(
    keypoints: np.ndarray,
    scores: np.ndarray,
    poses: np.ndarray,
    rig: Rig,
    path: str | Path,
    frame: int = 0,
    skeleton: Skeleton = COCO17,
) -> Path:
    """Per view: the input 2D keypoints (dots) and the 3D result projected back (lines).

    Args:
        keypoints: (T, V, J, 2) pixels. scores: (T, V, J). poses: (T, J, 3) world metres.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    V = len(rig)
    proj = rig.project(np.asarray(poses[frame], float))  # (V, J, 2)
    fig, axes = plt.subplots(1, V, figsize=(3.2 * V, 3.0), squeeze=False)
    for v, ax in enumerate(axes[0]):
        cam = rig[v]
        ok = scores[frame, v] > 0
        ax.scatter(*keypoints[frame, v, ok].T, s=10, c="k", label="2D input")
        for a, b in skeleton.bones:
            ax.plot(*proj[v, [a, b]].T, color=_bone_color(skeleton, a, b), lw=1.5)
        if cam.size:
            ax.set_xlim(0, cam.size[0])
            ax.set_ylim(cam.size[1], 0)
        else:
            ax.invert_yaxis()
        ax.set_aspect("equal")
        ax.set_title(cam.name, fontsize=8)
        ax.tick_params(labelsize=6)
    fig.tight_layout()
    return _save(fig, path)
