"""A self-contained HTML viewer for 3D poses: one file that opens offline in any browser.

:func:`write_viewer` writes a page with the skeletons (left side red, right side blue,
joints and the middle of the body in each person's colour), the cameras as frusta with
their names, a floor grid and the world axes (x red, y green, z blue, 0.5 m long), a
play/pause button, a frame scrubber and orbit controls (drag to orbit, right-drag or
shift-drag to pan, wheel to zoom, double-click to reset the view; space plays, arrow keys
step). ``page.html?frame=N`` opens paused at frame index N.

The page carries its own copy of three.js (vendored under ``vendor/``, MIT) and the poses
as JSON in world metres rounded to 1 mm, so it needs no network. The world is turned so
that its up axis is up on screen; see ``up`` in :func:`write_viewer`.

When the scene is built the page sets, on ``<body>``: ``data-loaded="1"``, ``data-frames``,
``data-people``, ``data-bones`` (bones per person), ``data-cameras``, and for the frame
shown ``data-frame`` and ``data-visible-bones`` (bones with both joints present);
``data-webgl`` is ``"1"`` or ``"0"``, ``data-rendered`` counts drawn frames, and a failure
sets ``data-error``. Tests and scripts read them with a headless browser.
"""

from __future__ import annotations

import html
import json
import re
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.io.atomic import atomic_path
from rmpl.io.poses import Poses3D
from rmpl.skeleton import SKELETONS, Skeleton

__all__ = ["write_viewer", "UP_AXES", "view_rotation", "guess_up"]

THREE_VERSION = "0.170.0"

#: World -> viewer rotation for each up axis; the viewer (three.js) is +Y up.
#: Each is a proper rotation taking the named axis to +Y.
UP_AXES: dict[str, np.ndarray] = {
    "+x": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "-x": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "+y": np.eye(3),
    "-y": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
    "+z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    "-z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
}

_LOW = ("ankle", "heel", "foot", "toe")  # joints near the floor
_HIGH = ("head", "nose", "eye", "ear", "neck", "shoulder")  # joints near the top
_PLACEHOLDER = re.compile(r"__RMPL_(TITLE|DATA|THREE)__")


def view_rotation(up: str) -> np.ndarray:
    """The rotation, shape (3, 3), that turns world axis ``up`` (e.g. ``"+z"``) to +Y.

    >>> view_rotation("+z") @ np.array([0.0, 0.0, 1.0])
    array([0., 1., 0.])
    """
    if up not in UP_AXES:
        raise InputError(None, "up", f"one of {sorted(UP_AXES)}", up)
    return UP_AXES[up]


def _axis_name(v: np.ndarray) -> str:
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "xyz"[k]


def guess_up(
    points: np.ndarray, joint_names: Sequence[str] | None = None, rig: Rig | None = None
) -> str:
    """The world axis that points up: from the bodies, else from the cameras, else +z.

    Bodies: the mean vector from the feet (ankles, heels, toes) to the head and shoulders.
    Cameras: the mean of their image-up directions (cameras are seldom upside down).

    Args:
        points: world points, shape (T, P, J, 3), NaN where missing.
        joint_names: names of the J joints, or None when unknown.
        rig: the cameras, or None.

    Returns:
        One of the keys of :data:`UP_AXES`.

    >>> feet_to_head = np.array([[[[0, 0, 0.1], [0, 0, 1.6]]]])
    >>> guess_up(feet_to_head, ["left_ankle", "head"])
    '+z'
    """
    if joint_names is not None:
        low = [j for j, n in enumerate(joint_names) if any(w in n for w in _LOW)]
        high = [j for j, n in enumerate(joint_names) if any(w in n for w in _HIGH)]
        if low and high:
            lift = _mean_joint(points[..., high, :]) - _mean_joint(points[..., low, :])
            lift = lift[np.isfinite(lift).all(-1)]
            if len(lift) and np.linalg.norm(lift.mean(0)) > 0:
                return _axis_name(lift.mean(0))
    if rig is not None:
        image_up = -rig.R[:, 1, :].mean(0)  # camera -y (image up) in world coordinates
        if np.linalg.norm(image_up) > 1e-6:
            return _axis_name(image_up)
    return "+z"


def _mean_joint(x: np.ndarray) -> np.ndarray:
    """Mean over the joint axis of (*, J, 3) ignoring missing joints; NaN when none."""
    seen = ~np.isnan(x[..., 0])
    total = np.where(seen[..., None], x, 0.0).sum(-2)
    count = seen.sum(-1)[..., None]
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _frusta(rig: Rig, depth: float) -> list[dict]:
    """Each camera's centre, image corners at ``depth`` metres, and an image-up marker."""
    sizes = rig.sizes
    out = []
    for cam, (w, h) in zip(rig, sizes, strict=True):
        if not np.isfinite(w):
            w, h = 2 * cam.K[0, 2], 2 * cam.K[1, 2]
        pix = np.array(
            [[0, 0], [w, 0], [w, h], [0, h], [0.3 * w, 0], [0.7 * w, 0], [0.5 * w, -0.25 * h]],
            float,
        )
        rays = np.linalg.solve(cam.K, np.column_stack([pix, np.ones(len(pix))]).T).T
        world = cam.center + depth * rays @ cam.R  # rows: R^T K^-1 [u, v, 1], z = depth
        out.append({"name": cam.name, "center": cam.center, "corners": world[:4], "up": world[4:]})
    return out


def _resolve(poses, skeleton, fps, person_ids):
    """Points (T, P, J, 3), joint names or None, bones, fps, frame numbers and ids."""
    frames = None
    if isinstance(poses, Poses3D):
        points, frames = poses.points, poses.frames
        skeleton = poses.skeleton if skeleton is None else skeleton
        fps = poses.fps if fps is None else fps
        person_ids = poses.person_ids if person_ids is None else person_ids
    else:
        try:
            points = np.array(poses, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                None, "poses", "Poses3D or an array (T, P, J, 3)", type(poses).__name__
            ) from None
        if points.ndim == 3:
            points = points[:, None]  # one person
    if points.ndim != 4 or points.shape[-1] != 3:
        raise InputError(None, "poses", "shape (T, P, J, 3) or (T, J, 3), metres", points.shape)
    if np.isinf(points).any():
        raise InputError(None, "poses", "finite coordinates or NaN for missing", "inf")
    T, P, J, _ = points.shape
    names, bones = _skeleton(skeleton, J)
    if fps is not None:
        try:
            fps = float(fps)
        except (TypeError, ValueError):
            raise InputError(None, "fps", "a positive frame rate or None", fps) from None
        if not (np.isfinite(fps) and fps > 0):
            raise InputError(None, "fps", "a positive frame rate or None", fps)
    frames = np.arange(T) if frames is None else np.asarray(frames)
    ids = np.arange(P) if person_ids is None else np.asarray(person_ids).ravel()
    if ids.shape != (P,):
        raise InputError(None, "person_ids", f"{P} ids, one per person", ids.shape)
    return points, names, bones, fps, frames, ids


def _skeleton(skeleton, J: int) -> tuple[tuple[str, ...] | None, list[tuple[int, int]]]:
    if skeleton is None:
        fits = [name for name, s in SKELETONS.items() if s.num_joints == J]
        if len(fits) != 1:
            options = " or ".join(fits) or "no rmpl skeleton has that many"
            raise InputError(None, "skeleton", f"a skeleton name for {J} joints ({options})")
        skeleton = fits[0]
    if isinstance(skeleton, str):
        if skeleton not in SKELETONS:
            raise InputError(None, "skeleton", f"one of {sorted(SKELETONS)}", skeleton)
        skeleton = SKELETONS[skeleton]
    if isinstance(skeleton, Skeleton):
        if skeleton.num_joints != J:
            raise InputError(
                None,
                "skeleton",
                f"a skeleton of {J} joints (as the poses)",
                f"{skeleton.name} with {skeleton.num_joints}",
            )
        return skeleton.joints, [tuple(b) for b in skeleton.bones]
    try:
        bones = np.asarray(skeleton, dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        raise InputError(
            None,
            "skeleton",
            "a Skeleton, a skeleton name or (a, b) joint pairs",
            type(skeleton).__name__,
        ) from None
    if not ((bones == np.round(bones)).all() and (bones >= 0).all() and (bones < J).all()):
        raise InputError(
            None, "skeleton", f"bones as pairs of joint indices 0..{J - 1}", bones.tolist()
        )
    return None, [(int(a), int(b)) for a, b in bones]


def _side(names: tuple[str, ...] | None, a: int, b: int) -> str:
    if names is None:
        return "C"
    both = names[a] + " " + names[b]
    left, right = "left" in both, "right" in both
    return "L" if left and not right else "R" if right and not left else "C"


def _numbers(x: np.ndarray) -> str:
    """A flat JSON array of x in millimetre precision, ``null`` for NaN."""
    text = np.char.mod("%.3f", np.ravel(x))
    text[np.isnan(np.ravel(x))] = "null"
    return "[" + ",".join(text.tolist()) + "]"


def _layout(view_pts: np.ndarray, view_cams: np.ndarray) -> dict:
    """Floor height, grid and initial view from the points and cameras (viewer axes)."""
    finite = view_pts[np.isfinite(view_pts).all(-1)]
    every = np.concatenate([finite, view_cams]) if len(view_cams) else finite
    if len(every) == 0:
        every = np.zeros((1, 3))
    floor = float(np.percentile(finite[:, 1], 2)) if len(finite) else 0.0
    centre = np.median(finite, 0) if len(finite) else every.mean(0)
    lo, hi = every[:, [0, 2]].min(0), every[:, [0, 2]].max(0)
    size = float(2 * np.ceil((np.max(hi - lo) + 2.0) / 2))  # even metres with 1 m margin
    mid = np.round((lo + hi) / 2)
    radius = float(max(np.linalg.norm(every - centre, axis=1).max(), 1.0))
    return {
        "floor": floor,
        "grid": {"center": mid.tolist(), "size": size, "step": 0.5 if size <= 12 else 1.0},
        "target": [float(centre[0]), float(centre[1]), float(centre[2])],
        "radius": radius,
    }


def _page(data_json: str, title: str) -> str:
    pkg = resources.files("rmpl.viz.viewer")
    template = (pkg / "template.html").read_text(encoding="utf-8")
    three = (pkg / "vendor" / "three.module.min.js").read_text(encoding="utf-8")
    parts = {
        "TITLE": html.escape(title),
        "DATA": data_json.replace("<", "\\u003c"),  # no "</script" inside the element
        "THREE": json.dumps(three).replace("<", "\\u003c"),
    }
    return _PLACEHOLDER.sub(lambda m: parts[m.group(1)], template)


def write_viewer(
    poses: Poses3D | np.ndarray,
    path: str | Path,
    skeleton: Skeleton | str | Sequence[tuple[int, int]] | None = None,
    cameras: Rig | None = None,
    fps: float | None = None,
    *,
    up: str | None = None,
    title: str | None = None,
    person_ids: Sequence[int] | None = None,
) -> Path:
    """Write one self-contained, offline HTML page that plays the poses in 3D.

    Args:
        poses: a :class:`~rmpl.io.poses.Poses3D`, or world points in metres of shape
            (T, P, J, 3) or (T, J, 3), NaN where missing.
        path: the ``.html`` file to write (atomically).
        skeleton: a :class:`~rmpl.skeleton.Skeleton`, a name in
            :data:`~rmpl.skeleton.SKELETONS`, or bones as (a, b) joint index pairs (drawn
            in the person's colour, no sides). Default: the Poses3D's skeleton, or the only
            skeleton with J joints.
        cameras: the rig, drawn as frusta with names; or None.
        fps: playback rate; default the Poses3D's, else 30 (shown as unknown).
        up: the world's up axis, ``"+z"``, ``"-y"``, ...; default: guessed from the bodies
            (feet to head), else from the cameras' image-up, else ``"+z"``.
        title: page title; default the file name.
        person_ids: one id per person for the legend; default the Poses3D's, or 0..P-1.

    Returns:
        The path written.

    Raises:
        InputError: poses of the wrong shape, a skeleton that does not fit them, ...
    """
    path = Path(path)
    points, names, bones, fps, frames, ids = _resolve(poses, skeleton, fps, person_ids)
    if cameras is not None and not isinstance(cameras, Rig):
        raise InputError(None, "cameras", "an rmpl Rig or None", type(cameras).__name__)
    if up is None:
        up = guess_up(points, names, cameras)
    view_pts, scene = _scene(points, cameras, up)
    meta = {
        "title": title or path.stem,
        **_playback(points.shape, fps, frames, ids, names, bones),
        **scene,
    }
    unc = poses.uncertainty if isinstance(poses, Poses3D) else None
    _write_page(path, meta, view_pts, unc)
    return path


def _write_page(path: Path, meta: dict, view_pts: np.ndarray, uncertainty=None) -> None:
    """The page with ``meta`` and then the points (viewer axes) as its data, atomically.
    ``uncertainty`` (T, P, J) metres, when given, colours the joints."""
    data = json.dumps(meta)[:-1] + ',"points":' + _numbers(view_pts)
    if uncertainty is not None:
        data += ',"uncertainty":' + _numbers(uncertainty)
    data += "}"
    page = _page(data, meta["title"])
    with atomic_path(path) as tmp:
        tmp.write_text(page, encoding="utf-8")


def _playback(shape: tuple, fps, frames, ids, names, bones) -> dict:
    """The page data on what is played: rate, frames, people and bones of poses ``shape``
    (T, P, J, 3)."""
    T, P, J, _ = shape
    return {
        "fps": fps or 30.0,
        "fpsKnown": fps is not None,
        "frames": frames.tolist(),
        "numFrames": T,
        "numPeople": P,
        "numJoints": J,
        "personIds": ids.tolist(),
        "bones": bones,
        "sides": [_side(names, a, b) for a, b in bones],
    }


def _scene(points: np.ndarray, cameras: Rig | None, up: str) -> tuple[np.ndarray, dict]:
    """The points (T, P, J, 3) turned to viewer axes (+Y up), and the page data on the
    scene: the axes, the camera frusta, the floor, grid and initial view."""
    R = view_rotation(up)
    view_pts = points @ R.T  # (T, P, J, 3) in viewer axes, +Y up
    centres = np.zeros((0, 3)) if cameras is None else cameras.centers @ R.T
    layout = _layout(view_pts, centres)
    depth = float(np.clip(0.08 * layout["radius"], 0.15, 1.0))
    cams = [] if cameras is None else _frusta(cameras, depth)
    scene = {
        "up": up,
        "axes": R.T.tolist(),  # rows: world x, y, z in viewer axes
        "cameras": [
            {
                "name": c["name"],
                "center": (c["center"] @ R.T).tolist(),
                "corners": (c["corners"] @ R.T).tolist(),
                "up": (c["up"] @ R.T).tolist(),
            }
            for c in cams
        ],
        "threeVersion": THREE_VERSION,
        **layout,
    }
    return view_pts, scene
