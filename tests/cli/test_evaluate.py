import numpy as np
import pytest

from rmpl.cli import main
from rmpl.synth.motion import PoseSet, save_pose_set


def standing_poses(n, rng):
    base = np.array(
        [
            [0, -0.08, 1.62],
            [0.03, -0.07, 1.66],
            [-0.03, -0.07, 1.66],
            [0.07, 0, 1.64],
            [-0.07, 0, 1.64],
            [0.18, 0, 1.42],
            [-0.18, 0, 1.42],
            [0.2, 0, 1.15],
            [-0.2, 0, 1.15],
            [0.2, -0.05, 0.9],
            [-0.2, -0.05, 0.9],
            [0.1, 0, 0.95],
            [-0.1, 0, 0.95],
            [0.1, 0, 0.5],
            [-0.1, 0, 0.5],
            [0.1, 0, 0.08],
            [-0.1, 0, 0.08],
        ]
    )
    return (base + rng.normal(0, 0.03, (n, 17, 3))).astype(np.float32)


def test_evaluate_synthetic_writes_tables(tmp_path, capsys):
    rng = np.random.default_rng(0)
    n = 40
    bank = PoseSet(
        standing_poses(n, rng),
        np.array(["01"] * 20 + ["03"] * 20),
        np.array(["c"] * n),
        np.arange(n),
    )
    save_pose_set(tmp_path / "bank.npz", bank)
    out = tmp_path / "res"
    assert (
        main(
            [
                "evaluate",
                "--dataset",
                "synthetic",
                "--root",
                str(tmp_path / "bank.npz"),
                "--methods",
                "triangulate,robust",
                "--views",
                "2,4",
                "--samples",
                "30",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    text = (out / "results.md").read_text()
    assert text.count("| triangulate |") == 2 and text.count("| robust |") == 2
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 5 and rows[0].startswith("views,method")
    # Four views triangulate better than two.
    csv = [r.split(",") for r in rows[1:]]
    tri = {int(r[0]): float(r[3]) for r in csv if r[1] == "triangulate"}
    assert tri[4] < tri[2]


def test_evaluate_unknown_method(tmp_path, capsys):
    code = main(
        ["evaluate", "--dataset", "synthetic", "--root", str(tmp_path), "--methods", "magic"]
    )
    assert code == 2
    assert "magic" in capsys.readouterr().err


@pytest.mark.shared
def test_evaluate_shelf_triangulation(shared_data, tmp_path):
    root = shared_data / "shelf_dev"
    assert (
        main(
            [
                "evaluate",
                "--dataset",
                "shelf",
                "--root",
                str(root),
                "--methods",
                "triangulate",
                "--views",
                "all",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    row = (tmp_path / "results.csv").read_text().splitlines()[1].split(",")
    mpjpe, coverage = float(row[2]), float(row[3])
    assert 30 < mpjpe < 80 and coverage > 95  # real detections, five views
