"""Held-out-view reprojection errors: the evaluation for recordings without ground truth."""

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.evaluate.heldout import heldout_rows, heldout_view_errors
from rmpl.geometry.triangulate import triangulate
from tests.cli.test_commands import make_scene


def _scene(views=4, people=5, seed=0):
    from rmpl.geometry.camera import Camera, Rig, look_at

    rng = np.random.default_rng(seed)
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views
        eye = np.array([5 * np.cos(a), 5 * np.sin(a), 2.0])
        R, t = look_at(eye, np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(1280, 720), name=f"c{v}"))
    rig = Rig(tuple(cams))
    X = rng.uniform(-0.4, 0.4, (people, 17, 3)) + [0, 0, 1]
    kp = rig.project(X)  # (N, V, J, 2)
    return rig, X, kp, np.full(kp.shape[:-1], 0.9)


def _tri(kp, sc, rig):
    if len(rig) < 2:
        return np.full((kp.shape[0], kp.shape[-2], 3), np.nan)
    return triangulate(kp, sc, rig).points


def test_exact_triangulation_reprojects_exactly_and_offsets_show():
    rig, X, kp, sc = _scene()

    def shifted(kp, sc, rig):  # every joint 10 cm off along world x
        return _tri(kp, sc, rig) + [0.1, 0, 0]

    ev = heldout_view_errors(kp, sc, rig, {"tri": _tri, "shifted": shifted}, [1, 2, 3])
    assert ev.subsets == {1: 12, 2: 12, 3: 4}
    assert np.isnan(ev.px[1]["tri"]).all()  # one view: triangulation answers nothing
    for k in (2, 3):
        assert ev.px[k]["tri"].max() < 1e-6
        assert len(ev.px[k]["tri"]) == 17 * 5 * ev.subsets[k]
        # 10 cm across a ray at ~5 m is up to ~20 px at f=1000, and never more than 10 cm.
        assert 2 < np.nanmean(ev.px[k]["shifted"]) < 25
        assert np.nanmax(ev.mm[k]["shifted"]) <= 100 + 1e-6
    rows = {(r["views"], r["method"]): r for r in heldout_rows(ev)}
    assert rows[2, "tri"]["coverage"] == 100.0 and rows[2, "tri"]["px_common"] < 1e-6
    assert rows[2, "shifted"]["mm_common"] > 20


def test_held_out_view_is_never_given_to_the_method():
    rig, X, kp, sc = _scene(views=3)
    seen = []

    def spy(kp, sc, rig):
        seen.append(tuple(rig.names))
        return _tri(kp, sc, rig)

    heldout_view_errors(kp, sc, rig, {"spy": spy}, [2])
    assert sorted(seen) == [("c0", "c1"), ("c0", "c2"), ("c1", "c2")]


def test_low_confidence_references_are_skipped_and_bad_sizes_refused():
    rig, X, kp, sc = _scene(views=3, people=2)
    sc[:, 2, :5] = 0.2  # view 2's first five joints are unreliable references
    ev = heldout_view_errors(kp, sc, rig, {"tri": _tri}, [2], min_score=0.5)
    assert len(ev.px[2]["tri"]) == 2 * (17 + 17 + 12)
    with pytest.raises(ValueError, match="1..2"):
        heldout_view_errors(kp, sc, rig, {"tri": _tri}, [3])
    with pytest.raises(ValueError, match="views of 2D"):
        heldout_view_errors(kp, sc, rig[[0, 1]], {"tri": _tri}, [1])
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ValueError, match="min_score"):
            heldout_view_errors(kp, sc, rig, {"tri": _tri}, [2], min_score=bad)
    # A missing held-out detection (score 0) is never a reference.
    sc[:, 2, 5:8] = 0.0
    kp[:, 2, 5:8] = np.nan
    ev = heldout_view_errors(kp, sc, rig, {"tri": _tri}, [2], min_score=0.1)
    assert len(ev.px[2]["tri"]) == 2 * (17 + 17 + 14)
    # Held out 0 or 1, those joints are seen by one input view only: no triangulation.
    assert np.isnan(ev.px[2]["tri"]).sum() == 2 * 2 * 3


def test_cli_recording(tmp_path, capsys):
    make_scene(tmp_path, views=3)
    out = tmp_path / "res"
    args = [
        "evaluate",
        "--dataset",
        "recording",
        "--calib",
        str(tmp_path / "calib.toml"),
        "--keypoints",
        str(tmp_path / "kp.json"),
        "--methods",
        "triangulate,robust",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    text = (out / "results.md").read_text()
    assert "held-out" in text and "| 2 | triangulate |" in text
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 2  # k = 1, 2 for two methods
    # Options that cannot apply are refused with one line, and nothing is written.
    capsys.readouterr()
    assert main(args[:-2] + ["--root", "x", "--out", str(tmp_path / "no")]) == 2
    assert "--root" in capsys.readouterr().err and not (tmp_path / "no").exists()
    assert main(args[:-2] + ["--views", "3"]) == 2
    assert "--views" in capsys.readouterr().err
    assert main(args[:-2] + ["--min-score", "0"]) == 2
    assert "--min-score" in capsys.readouterr().err
    assert main(args[:-2] + ["--cameras", "a,b"]) == 2
    assert "--cameras" in capsys.readouterr().err
    assert main(args[:-2] + ["--dropout", "0.0", "--out", str(tmp_path / "r2")]) == 0


def test_cli_recording_gives_the_floor_to_one_view_methods(tmp_path):
    # --floor reaches the rmpl+floor methods on a recording (it was once parsed and dropped):
    # the floor-reading model answers differently on two floors, and results.md names it.
    make_scene(tmp_path, views=3)
    args = ["evaluate", "--dataset", "recording", "--calib", str(tmp_path / "calib.toml"),
            "--keypoints", str(tmp_path / "kp.json"), "--views", "1",
            "--methods", "rmpl+floor:none@floor26"]  # fmt: skip
    tables = {}
    for floor in ("z=0", "z=0.6"):
        out = tmp_path / floor
        assert main([*args, "--floor", floor, "--out", str(out)]) == 0
        text = (out / "results.md").read_text()
        height = floor.split("=")[1]
        assert f"= {float(height):.3f} m" in text, text[:1500]
        tables[floor] = (out / "results.csv").read_text()
    assert tables["z=0"] != tables["z=0.6"]
