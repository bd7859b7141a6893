"""``rmpl calibrate`` from boards: views -> lenses -> spanning tree -> bundle adjustment ->
world -> a :class:`~rmpl.geometry.camera.Rig` and what the report says about it.

Camera names come from the extrinsics folders or videos (as ``rmpl run --videos`` names
views); intrinsics sources and a given calibration's cameras are matched to them by name,
else by order when there are as many. A camera without intrinsics images calibrates its
lens from its extrinsics views. With ``--calib`` the lenses are kept as given; otherwise
the bundle adjustment refines them too.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.calibration.boards import Board
from rmpl.calibration.bundle import Adjusted, Observations, adjust
from rmpl.calibration.extrinsics import chain_cameras, inverse, solve_board_poses
from rmpl.calibration.frames import (
    GRID,
    CameraViews,
    coverage,
    read_views,
    select_views,
    source_names,
)
from rmpl.calibration.intrinsics import Intrinsics, calibrate_intrinsics
from rmpl.calibration.world import parse_origin, to_world, world_from_board, world_from_camera
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig

__all__ = ["Calibration", "calibrate_boards"]

log = logging.getLogger(__name__)

#: Most images a camera's lens is calibrated from (chosen by coverage, then sharpness).
MAX_LENS_VIEWS = 40


@dataclass
class Calibration:
    """A calibration and its account: the rig, per camera its lens calibration, its
    views, RMS, centre standard deviations; the world's definition; timings."""

    rig: Rig
    board: Board
    lenses: list[Intrinsics]
    rms: list[float]
    centre_std_mm: list[list[float]]
    views_used: list[int]
    views_dropped: list[list[str]]
    coverage: list[np.ndarray]
    world: str
    fisheye: bool = False
    seconds: float = 0.0
    edges: list[tuple[str, str, int]] = field(default_factory=list)
    adjusted: Adjusted | None = None


def _match(names: list[str], other: list[str], what: str) -> list[int]:
    """Index into ``other`` of each of ``names``: by name, else by order."""
    if set(names) <= set(other):
        return [other.index(n) for n in names]
    if len(other) == len(names):
        return list(range(len(names)))
    raise InputError(
        None, what, f"cameras named like the extrinsics ({', '.join(names)}) or as many",
        ", ".join(other),
    )  # fmt: skip


def _lenses(board, names, ext, intr_paths, calib, fisheye, progress):
    """Per camera: its lens (Intrinsics) and the separate views it was computed from."""
    lenses, separate = [], []
    intr_names = source_names(intr_paths) if intr_paths else []
    order = _match(names, intr_names, "--intrinsics") if intr_paths else []
    rig_order = _match(names, calib.names, "--calib") if calib is not None else []
    for v, name in enumerate(names):
        if calib is not None:
            cam = calib[rig_order[v]]
            size = cam.size or (ext[v].size if ext else None)
            lenses.append(Intrinsics(cam.K, cam.dist, size, used=["(from --calib)"]))
            separate.append(None)
            continue
        views = ext[v] if ext else None
        if intr_paths:
            views = read_views(intr_paths[order[v]], board, name, progress=progress)
            separate.append(views)
        else:
            separate.append(None)
        keys = select_views(views, MAX_LENS_VIEWS)
        lens = calibrate_intrinsics(
            views.named(keys), board, views.size, fisheye=fisheye, camera=name, source=views.source
        )
        log.info("camera %s: lens from %d images, RMS %.2f px", name, len(lens.used), lens.rms)
        lenses.append(lens)
    return lenses, separate


def calibrate_boards(
    board: Board,
    intrinsics: list[str | Path],
    extrinsics: list[str | Path],
    *,
    calib: Rig | None = None,
    fisheye: bool = False,
    origin: str = "board",
    progress: bool = True,
) -> Calibration:
    """Calibrate cameras from board images or videos (see the module).

    Raises:
        InputError: any bad input, one line naming the camera, the file and what was expected.
    """
    start = time.perf_counter()
    sources = list(extrinsics) or list(intrinsics)
    if not sources:
        raise InputError(None, "--extrinsics", "at least one folder of images or video", "none")
    names = source_names(sources)
    ext = [
        read_views(p, board, n, progress=progress)
        for p, n in zip(extrinsics, names[: len(extrinsics)], strict=True)
    ]
    lenses, separate = _lenses(board, names, ext, list(intrinsics) if extrinsics else sources,
                               calib, fisheye, progress)  # fmt: skip
    if not extrinsics or fisheye:
        if fisheye and extrinsics:
            log.warning("fisheye lenses: the camera poses are not computed (pinhole only)")
        views = [s or e for s, e in zip(separate, ext or separate, strict=True)]
        return _lenses_only(board, names, lenses, views, fisheye, start)
    return _extrinsics(board, names, ext, separate, lenses, calib is None, origin, start)


def _lenses_only(board, names, lenses, views, fisheye, start) -> Calibration:
    """Lenses without extrinsics: every camera at the origin."""
    cams = []
    for ln, name in zip(lenses, names, strict=True):
        dist = np.zeros(5) if fisheye else ln.dist[:5]
        cams.append(Camera(ln.K, np.eye(3), np.zeros(3), dist, ln.size, name))
    V = len(names)
    return Calibration(
        Rig(tuple(cams)),
        board,
        lenses,
        [ln.rms for ln in lenses],
        [[np.nan] * 3] * V,
        [len(ln.used) for ln in lenses],
        [ln.dropped for ln in lenses],
        [_coverage(v) for v in views],
        "no extrinsics: every camera at the origin",
        fisheye,
        time.perf_counter() - start,
    )


def _coverage(views: CameraViews | None) -> np.ndarray:
    out = np.zeros((GRID, GRID), int)
    if views is not None:
        for det in views.views.values():
            out += coverage(det.corners, views.size)
    return out


def _observations(board, ext, separate, chain, poses_sep):
    """Corners of every view, with their board-pose index, and the initial board poses."""
    cams, pose_idx, pts, pix, labels, T_wb, instants = [], [], [], [], {}, [], {}
    flipped = board.flipped_ids()
    for f in sorted(chain.T_wb):
        instants[f] = len(T_wb)
        T_wb.append(chain.T_wb[f])
    for v, cam in enumerate(ext):
        for f, det in cam.views.items():
            if f not in chain.T_wb or f not in chain.flips[v]:
                continue
            ids = flipped[det.ids] if chain.flips[v][f] else det.ids
            p = instants[f]
            cams.append(np.full(len(ids), v)), pose_idx.append(np.full(len(ids), p))
            pts.append(board.points[ids]), pix.append(det.corners)
            labels[v, p] = f"{cam.source.name}/{cam.labels[f]}"
    for v, views in enumerate(separate):
        if views is None:
            continue
        for k, T_cb in poses_sep[v].items():
            det, p = views.views[k], len(T_wb)
            T_wb.append(inverse(chain.T_cw[v]) @ T_cb)
            cams.append(np.full(len(det), v)), pose_idx.append(np.full(len(det), p))
            pts.append(board.points[det.ids]), pix.append(det.corners)
            labels[v, p] = f"{views.source.name}/{views.labels[k]}"
    obs = Observations(np.concatenate(cams), np.concatenate(pose_idx), np.concatenate(pts),
                       np.concatenate(pix), labels)  # fmt: skip
    return obs, T_wb, instants


def _extrinsics(board, names, ext, separate, lenses, free_lens, origin, start) -> Calibration:
    poses = [
        solve_board_poses(c.views, ln.K, ln.dist, board) for c, ln in zip(ext, lenses, strict=True)
    ]
    chain = chain_cameras(poses, names, board)
    poses_sep = [
        {}
        if s is None
        else solve_board_poses({k: s.views[k] for k in _used(s, ln)}, ln.K, ln.dist, board)
        for s, ln in zip(separate, lenses, strict=True)
    ]
    obs, T_wb0, instants = _observations(board, ext, separate, chain, poses_sep)
    adj = adjust(obs, [ln.K for ln in lenses], [ln.dist for ln in lenses], chain.T_cw, T_wb0,
                 chain.reference, names, free_lens=free_lens,
                 lens_std=[ln.std for ln in lenses])  # fmt: skip
    camera = parse_origin(origin, names)
    if camera is None:
        seen = {f: sum(f in c.views for c in ext) for f in instants}
        first = min((f for f, n in seen.items() if n >= 2), default=min(instants))
        G = world_from_board(adj.T_wb[instants[first]])
        label = ext[0].labels.get(first, first)
        world = f"board at {label} (instant {first}): origin at its first inner corner, z up"
    else:
        G = world_from_camera(adj.T_cw[names.index(camera)])
        world = f"camera {camera}: origin at its centre, its axes (x right, y down, z forward)"
    T_cw = to_world(adj.T_cw, G)
    rig = Rig(tuple(Camera(adj.K[v], T[:3, :3], T[:3, 3], adj.dist[v], ext[v].size, names[v])
                    for v, T in enumerate(T_cw)))  # fmt: skip
    Rg = G[:3, :3]
    std = [np.sqrt(np.clip(np.diag(Rg @ c @ Rg.T), 0, None)) * 1000 for c in adj.centre_cov]
    std[chain.reference] = np.full(3, np.nan)  # the reference: it fixes the frame
    world += f"; centre std relative to {names[chain.reference]}"
    used = [sum(1 for (c, _p) in adj.view_rms if c == v) for v in range(len(names))]
    dropped = [
        ln.dropped + [lab for c, lab in adj.dropped if c == v] for v, ln in enumerate(lenses)
    ]
    cover = [_coverage(ext[v]) + _coverage(separate[v]) for v in range(len(names))]
    edges = [(names[a], names[b], n) for a, b, n in chain.edges]
    seconds = time.perf_counter() - start
    stds = [s.tolist() for s in std]
    return Calibration(
        rig,
        board,
        lenses,
        adj.rms.tolist(),
        stds,
        used,
        dropped,
        cover,
        world,
        False,
        seconds,
        edges,
        adj,
    )


def _used(views: CameraViews, lens: Intrinsics) -> list[int]:
    by_label = {views.labels[k]: k for k in views.views}
    return [by_label[n] for n in lens.used if n in by_label]
