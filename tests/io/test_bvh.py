"""BVH export, read back by a minimal BVH parser written here (not rmpl's own code)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.io.poses import Poses3D, save_poses
from rmpl.skeleton import COCO17

EXAMPLE = Path(__file__).resolve().parents[2] / "src" / "rmpl" / "examples" / "walk"


def _axis_rotation(axis: str, degrees: np.ndarray) -> np.ndarray:
    a = np.deg2rad(degrees)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((*a.shape, 3, 3))
    i = "XYZ".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    R[..., i, i] = 1
    R[..., j, j], R[..., j, k], R[..., k, j], R[..., k, k] = c, -s, s, c
    return R


def read_bvh(text: str) -> tuple[dict[str, np.ndarray], float]:
    """Parse a BVH file and run forward kinematics: {joint name: (T, 3)}, frame time."""
    tokens = text.split()
    joints, stack, i = [], [], 0  # joints: [name, parent, offset, channels]
    while tokens[i] != "MOTION":
        tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            joints.append([tokens[i + 1], stack[-1] if stack else -1, None, []])
            i += 2
        elif tok == "End":  # End Site: skip its block
            i = tokens.index("}", i) + 1
        elif tok == "{":
            stack.append(len(joints) - 1)
            i += 1
        elif tok == "}":
            stack.pop()
            i += 1
        elif tok == "OFFSET":
            joints[stack[-1]][2] = np.array(tokens[i + 1 : i + 4], float)
            i += 4
        elif tok == "CHANNELS":
            n = int(tokens[i + 1])
            joints[stack[-1]][3] = tokens[i + 2 : i + 2 + n]
            i += 2 + n
        else:
            i += 1
    frames = int(re.search(r"Frames:\s*(\d+)", text).group(1))
    frame_time = float(re.search(r"Frame Time:\s*([\d.eE+-]+)", text).group(1))
    rows = text.split("Frame Time:")[1].splitlines()[1:]
    data = np.array([r.split() for r in rows if r.strip()], float)
    assert data.shape == (frames, sum(len(j[3]) for j in joints))
    pos, rot, col = {}, {}, 0
    for name, parent, offset, channels in joints:
        values = data[:, col : col + len(channels)]
        col += len(channels)
        R = np.broadcast_to(np.eye(3), (frames, 3, 3))
        p = np.broadcast_to(offset, (frames, 3)).copy()
        for c, ch in enumerate(channels):
            if ch.endswith("position"):
                p[:, "XYZ".index(ch[0])] += values[:, c]
            else:
                R = R @ _axis_rotation(ch[0], values[:, c])
        if parent >= 0:
            pname = joints[parent][0]
            p = pos[pname] + np.einsum("tij,j->ti", rot[pname], offset)
            R = rot[pname] @ R
        pos[name], rot[name] = p, R
    return pos, frame_time


def _walk() -> np.ndarray:
    return np.load(EXAMPLE / "ground_truth.npz")["points"][:, 0]  # (T, 17, 3)


def _errors(pos: dict, points: np.ndarray) -> np.ndarray:
    got = np.stack([pos[name] for name in COCO17.joints], axis=1)  # (T, 17, 3)
    return np.linalg.norm(got - points, axis=-1)


#: Bound on the per-joint error, metres: bone lengths are held at their medians.
MAX_ERROR = 0.03


def test_bvh_reproduces_the_walk(tmp_path):
    X = _walk()
    path = save_poses(Poses3D(X[:, None], fps=30.0), tmp_path / "walk.bvh")
    pos, frame_time = read_bvh(path.read_text())
    assert frame_time == pytest.approx(1 / 30)
    err = _errors(pos, X)
    assert err.shape == X.shape[:2]
    assert err.max() < MAX_ERROR, err.max(0).round(3)
    # Bone lengths are constant in the file: the shin length never changes.
    shin = np.linalg.norm(pos["left_ankle"] - pos["left_knee"], axis=-1)
    assert np.ptp(shin) < 1e-5
    # The rest pose is upright: ankles below the pelvis.
    text = path.read_text()
    knee = re.search(r"JOINT left_knee\s*{\s*OFFSET ([-\d. ]+)", text).group(1).split()
    assert float(knee[2]) < -0.3


def test_bvh_in_millimetres_y_up_with_gaps(tmp_path):
    X = _walk()[:20].copy()
    X[5:8] = np.nan  # a gap of three frames
    X[:, 3] = np.nan  # an ear never seen
    frames = np.delete(np.arange(20), [10, 11])  # two frames absent from the poses
    poses = Poses3D(np.delete(X, [10, 11], axis=0)[:, None], fps=25.0, frames=frames)
    path = save_poses(poses, tmp_path / "walk.bvh", units="mm", up_axis="y")
    pos, _ = read_bvh(path.read_text())
    got = np.stack([pos[n] for n in COCO17.joints], axis=1) / 1000  # (20, 17, 3) metres
    assert np.isfinite(got).all() and len(got) == 20
    z_up = got @ np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]).T  # y-up -> z-up
    seen = np.isfinite(X).all(-1)
    seen[:, 3] = False
    seen[[10, 11]] = False  # interpolated, not fitted
    err = np.linalg.norm(z_up - X, axis=-1)[seen]
    assert err.max() < MAX_ERROR
    # Y is up in the file: the head is above the ankles.
    assert (pos["nose"][:, 1] > pos["left_ankle"][:, 1] + 1000).all()


def test_bvh_bad_input_leaves_no_file(tmp_path):
    X = _walk()[:5]
    two = Poses3D(np.stack([X, X + 1], axis=1), fps=30.0)
    with pytest.raises(InputError, match="one person"):
        save_poses(two, tmp_path / "a.bvh")
    with pytest.raises(InputError, match="fps"):
        save_poses(Poses3D(X[:, None]), tmp_path / "a.bvh")
    no_hips = X[:, None].copy()
    no_hips[:, :, 11] = np.nan
    with pytest.raises(InputError, match="hips"):
        save_poses(Poses3D(no_hips, fps=30.0), tmp_path / "a.bvh")
    assert not list(tmp_path.iterdir())
