"""HALPE-26 poses -> Pose2Sim's HALPE_26 markers (rmpl.io.pose2sim), read back with the
``c3d`` package and the layout parser of tests/io/test_pose2sim.py; the marker names are
checked against Pose2Sim's own (its skeleton tree and Markers_Halpe26.xml) when the OpenSim
venv is there."""

from __future__ import annotations

import re

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.io.pose2sim import (
    HALPE26_IK_MARKERS,
    HALPE26_MARKERS,
    POSE2SIM_MARKERS,
    pose_model,
    write_pose2sim,
)
from rmpl.io.poses import Poses3D
from rmpl.skeleton import HALPE26
from tests.io.test_pose2sim import _opensim_python, read_c3d, read_trc

NAMES = list(HALPE26_MARKERS)
J = {name: i for i, name in enumerate(HALPE26.joints)}


def _people(T=5, P=1, seed=0, fps=30.0) -> Poses3D:
    rng = np.random.default_rng(seed)
    return Poses3D(rng.uniform(-2.0, 2.0, (T, P, 26, 3)), skeleton="halpe26", fps=fps)


def test_halpe26_poses_get_the_halpe_26_markers(tmp_path):
    poses = _people(T=4)
    trc_path, c3d_path = write_pose2sim(poses, tmp_path, orientation="z-up")
    trc = read_trc(trc_path)
    assert trc["markers"] == NAMES and len(NAMES) == 26
    assert trc["header"]["NumMarkers"] == "26"
    assert set(HALPE26_IK_MARKERS) <= set(NAMES)
    x = poses.points[:, 0]
    for marker, joint in {
        "Hip": "mid_hip",
        "Neck": "neck",
        "Head": "head_top",
        "LHeel": "left_heel",
        "RBigToe": "right_big_toe",
        "LSmallToe": "left_small_toe",
        "RKnee": "right_knee",
    }.items():
        np.testing.assert_allclose(trc["points"][:, NAMES.index(marker)], x[:, J[joint]], atol=1e-6)
    c = read_c3d(c3d_path)
    assert c["labels"] == NAMES
    np.testing.assert_allclose(c["points"], trc["points"], atol=1e-5)  # float32 in C3D
    assert (c["residual"] == 0).all()


def test_coco17_poses_keep_the_coco_17_markers(tmp_path):
    rng = np.random.default_rng(1)
    poses = Poses3D(rng.uniform(-1, 1, (3, 1, 17, 3)), fps=30.0)
    trc = read_trc(write_pose2sim(poses, tmp_path, formats=("trc",))[0])
    assert trc["markers"] == list(POSE2SIM_MARKERS)
    assert pose_model("coco17").name == "COCO_17" and pose_model("halpe26").name == "HALPE_26"


def test_the_hip_marker_falls_back_to_the_hips_midpoint(tmp_path):
    """Triangulated HALPE-26 from a detector without a mid-hip (BODY_25B): Hip is the
    midpoint of the hips, as rmpl defines the mid-hip; the frames are still written."""
    poses = _people(T=3, seed=2)
    poses.points[:, 0, J["mid_hip"]] = np.nan
    trc = read_trc(write_pose2sim(poses, tmp_path, orientation="z-up", formats=("trc",))[0])
    x = poses.points[:, 0]
    want = (x[:, J["left_hip"]] + x[:, J["right_hip"]]) / 2
    np.testing.assert_allclose(trc["points"][:, NAMES.index("Hip")], want, atol=1e-6)
    assert len(trc["frame"]) == 3


def test_a_missing_foot_marker_is_an_empty_field_inside_the_span(tmp_path):
    poses = _people(T=6, seed=3)
    poses.points[2, 0, J["left_heel"]] = np.nan
    trc = read_trc(write_pose2sim(poses, tmp_path, formats=("trc",))[0])
    heel = trc["points"][:, NAMES.index("LHeel")]
    assert np.isnan(heel[2]).all() and np.isfinite(np.delete(heel, 2, 0)).all()


def test_no_frame_with_every_halpe_ik_marker_is_refused(tmp_path):
    poses = _people(T=3, seed=4)
    poses.points[:, 0, J["right_heel"]] = np.nan  # a foot marker the IK needs, never seen
    with pytest.raises(InputError, match="RHeel"):
        write_pose2sim(poses, tmp_path)
    assert not list(tmp_path.iterdir())


def test_other_joint_sets_are_one_input_error(tmp_path):
    poses = Poses3D(np.zeros((2, 1, 14, 3)), skeleton="shelf14", fps=25.0)
    with pytest.raises(InputError, match="halpe26") as e:
        write_pose2sim(poses, tmp_path)
    assert e.value.field == "skeleton"


@pytest.mark.benchmark
def test_marker_names_are_pose2sims(tmp_path):
    """Our HALPE_26 names are the nodes of Pose2Sim's HALPE_26 tree (plus HALPE's eyes and
    ears, which that tree leaves out), and our IK markers those of Markers_Halpe26.xml."""
    import subprocess

    python = _opensim_python()
    code = (
        "from pathlib import Path\n"
        "from anytree import PreOrderIter\n"
        "import Pose2Sim.skeletons as s\n"
        "print(' '.join(n.name for n in PreOrderIter(s.HALPE_26)))\n"
        "print((Path(s.__file__).parent / 'OpenSim_Setup' / 'Markers_Halpe26.xml').read_text())\n"
    )
    out = subprocess.run([str(python), "-c", code], capture_output=True, text=True, check=True)
    tree, xml = out.stdout.split("\n", 1)
    assert set(tree.split()) == set(NAMES) - {"REye", "LEye", "REar", "LEar"}
    assert [n for n in NAMES if n in tree.split()] == tree.split()  # the tree's order
    assert set(re.findall(r'<Marker name="([^"]+)"', xml)) == set(HALPE26_IK_MARKERS)
