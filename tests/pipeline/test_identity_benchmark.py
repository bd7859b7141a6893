"""The identity benchmark (rmpl.benchmarks.identity): its matching on synthetic ground
truth, and on Shelf the issue's targets (a benchmark: it runs rmpl run)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.benchmarks.identity import main, recording_table, shelf_table


def _gt_and_tracks():
    """Two actors over 20 frames (actor 2 annotated in frames 0-9 only); actor 1 split into
    two tracks at frame 12, actor 2 one track."""
    T = 20
    rng = np.random.default_rng(0)
    gt = np.full((T, 4, 15, 3), np.nan)
    gt[:, 0] = rng.normal(0, 0.3, (15, 3))
    gt[:10, 1] = rng.normal(0, 0.3, (15, 3)) + [3.0, 0, 0]
    from rmpl.benchmarks.identity import _SHELF_TO_COCO

    tracks = np.full((T, 3, 17, 3), np.nan)
    tracks[:12, 0, _SHELF_TO_COCO] = gt[:12, 0, :12] + 0.02
    tracks[12:, 1, _SHELF_TO_COCO] = gt[12:, 0, :12] - 0.02
    tracks[:10, 2, _SHELF_TO_COCO] = gt[:10, 1, :12]
    return gt, tracks


def test_each_actors_longest_track_share():
    gt, tracks = _gt_and_tracks()
    result = shelf_table(tracks, gt)
    assert result["tracks"] == 3
    assert result["actors"] == [
        {"actor": 1, "annotated_frames": 20, "longest_track_share": 0.6, "tracks": 2},
        {"actor": 2, "annotated_frames": 10, "longest_track_share": 1.0, "tracks": 1},
    ]


def test_a_swap_shows_as_a_torso_step():
    T = 10
    tracks = np.zeros((T, 2, 17, 3))
    tracks[:, 1] += [2.0, 0, 0]
    tracks[5:] = tracks[5:, ::-1]  # the two people swap tracks at frame 5
    rows = recording_table(tracks, 25.0)["rows"]
    assert [r["largest_torso_step_m"] for r in rows] == [2.0, 2.0]


@pytest.mark.benchmark
@pytest.mark.shared
def test_shelf_targets(shared_data, tmp_path):
    """Each annotated actor's longest track holds >= 95% of its frames; <= 6 tracks."""
    root = shared_data / "shelf_dev"
    if not root.is_dir():
        pytest.skip("shelf_dev absent")
    assert main(["shelf", "--root", str(root), "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "identity.json").read_text())
    assert result["tracks"] <= 6
    assert all(a["longest_track_share"] >= 0.95 for a in result["actors"])
