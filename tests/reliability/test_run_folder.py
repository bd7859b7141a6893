"""``rmpl run``'s output folder changes as a unit: a failed export, or a kill -9 at any
point of the export, leaves the previous complete set or the new one, never a mix."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.io.atomic import JOURNAL, MANIFEST, recover_folder
from rmpl.io.poses import load_poses
from tests.reliability._faults import run_killed

EXAMPLE = Path(__file__).resolve().parents[2] / "src/rmpl/examples/walk"
BASE = ["run", "--calib", str(EXAMPLE / "calibration.toml"), "--keypoints",
        str(EXAMPLE / "keypoints.json"), "--method", "triangulate", "--no-pictures"]  # fmt: skip
OLD = ["--filter", "none", "--formats", "npz,json,trc,c3d,bvh"]
NEW = ["--filter", "butterworth", "--formats", "npz,json,trc,c3d"]


def outputs(folder: Path) -> dict[str, object]:
    """What a user sees: every file name, and the points of each readable pose file (two
    processes may differ in the last bits of a float, so sets are compared with a tolerance).
    """
    got: dict[str, object] = {"names": sorted(p.name for p in folder.iterdir())}
    for name in ("poses.npz", "poses.json", "poses.trc"):
        if (folder / name).exists():
            got[name] = np.nan_to_num(load_poses(folder / name).points, nan=-99.0)
    return got


def same(a: dict, b: dict) -> bool:
    return (
        a.keys() == b.keys()
        and a["names"] == b["names"]
        and all(np.allclose(a[k], b[k], atol=1e-5) for k in a if k != "names")
    )


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    """The old and the new complete set, each made by an uninterrupted run."""
    made = {}
    for key, extra in (("old", OLD), ("new", NEW)):
        out = tmp_path_factory.mktemp(key) / "out"
        out.mkdir()
        (out / "notes.txt").write_text("mine")
        assert main(BASE + ["--out", str(out), *extra]) == 0
        made[key] = outputs(out)
    assert not np.allclose(made["old"]["poses.json"], made["new"]["poses.json"], atol=1e-3)
    return made


def old_folder(tmp_path: Path) -> Path:
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")  # a user's file
    assert main(BASE + ["--out", str(out), *OLD]) == 0
    return out


# The export's os.replace calls: 4 files into the staging folder, then the 2 Pose2Sim files
# into its pose-3d/ (the reports are written in place), the journal (7th), then the commit's
# moves. Killing at each point covers staging, journal and commit.
@pytest.mark.parametrize("n", [1, 4, 5, 6, 7, 8, 10, 14])
def test_kill_during_export_leaves_one_complete_set(tmp_path, sets, n):
    out = old_folder(tmp_path)
    args = BASE + ["--out", str(out), *NEW]
    run_killed(
        f"""
        from rmpl.cli import main
        from rmpl.io import atomic
        kill_at(atomic.os, "replace", {n})
        main({args!r})
        """,
        tmp_path,
    )
    recover_folder(out)  # what the next run does first
    got = outputs(out)
    assert same(got, sets["old"]) or same(got, sets["new"]), got["names"]
    assert (out / "notes.txt").read_text() == "mine"


def test_reader_finishes_an_interrupted_commit(tmp_path, sets):
    out = old_folder(tmp_path)
    args = BASE + ["--out", str(out), *NEW]
    run_killed(
        f"""
        from rmpl.cli import main
        from rmpl.io import atomic
        kill_at(atomic.os, "replace", 9)
        main({args!r})
        """,
        tmp_path,
    )
    assert (out / JOURNAL).exists()
    load_poses(out / "poses.json")  # a reader rolls the commit forward
    assert same(outputs(out), sets["new"])


def test_failed_export_keeps_the_old_set(tmp_path, sets, monkeypatch):
    out = old_folder(tmp_path)
    import rmpl.io.poses as poses_io

    real = poses_io._write_c3d

    def broken(*args, **kwargs):
        raise RuntimeError("the disk filled up")

    monkeypatch.setattr(poses_io, "_write_c3d", broken)
    with pytest.raises(RuntimeError, match="disk"):
        main(BASE + ["--out", str(out), *NEW])
    assert same(outputs(out), sets["old"])
    monkeypatch.setattr(poses_io, "_write_c3d", real)
    assert main(BASE + ["--out", str(out), *NEW]) == 0
    assert same(outputs(out), sets["new"])  # the old set's BVH went with it
    assert json.loads((out / MANIFEST).read_text())["outputs"] == [
        "pose-3d", "poses.c3d", "poses.json", "poses.npz", "poses.trc", "report.json",
        "report.md"]  # fmt: skip
