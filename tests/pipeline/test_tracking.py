"""Tracking 3D people over time: crossings, entries, exits, dropouts and teleports."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.pipeline.tracking import track, track_indices

J = 17
FPS = 30.0


def _body(height: float, seed: int) -> np.ndarray:
    """A rough standing body of the given height, shape (J, 3), feet at z = 0."""
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(-0.2, 0.2, J), rng.uniform(-0.15, 0.15, J), np.linspace(0.0, height, J)]
    )


def _scene(
    paths: dict[int, np.ndarray], T: int, seed: int, noise: float = 0.01, same_body: bool = False
):
    """Shuffled per-frame detections from people's root paths, shape (T, 3) each, NaN rows
    where absent. Returns the frames and, per frame, the true id of each detection."""
    rng = np.random.default_rng(seed)
    bodies = {pid: _body(1.6, 0) if same_body else _body(1.5 + 0.1 * pid, pid) for pid in paths}
    frames, truth = [], []
    for t in range(T):
        here = [pid for pid, path in paths.items() if np.isfinite(path[t]).all()]
        rng.shuffle(here)
        people = [bodies[pid] + paths[pid][t] + rng.normal(0, noise, (J, 3)) for pid in here]
        frames.append(np.array(people).reshape(len(here), J, 3))
        truth.append(here)
    return frames, truth


def _id_switches(index: np.ndarray, truth: list[list[int]]) -> tuple[int, dict[int, set]]:
    """Identity switches (a true person's track changes between its detections) and the
    set of tracks each true person was given."""
    last: dict[int, int] = {}
    used: dict[int, set] = {}
    switches = 0
    for t, ids in enumerate(truth):
        for p in np.flatnonzero(index[t] >= 0):
            pid = ids[index[t, p]]
            switches += pid in last and last[pid] != p
            last[pid] = p
            used.setdefault(pid, set()).add(int(p))
    return switches, used


def _line(start, velocity, T: int, frames: range | None = None) -> np.ndarray:
    path = np.asarray(start, float) + np.arange(T)[:, None] * np.asarray(velocity, float) / FPS
    if frames is not None:
        absent = np.ones(T, bool)
        absent[list(frames)] = False
        path[absent] = np.nan
    return path


def test_two_people_crossing_keep_their_identities():
    T = 120
    paths = {0: _line([-3, 0.0, 0], [1.5, 0, 0], T), 1: _line([3, 0.2, 0], [-1.5, 0, 0], T)}
    frames, truth = _scene(paths, T, seed=0)
    index = track_indices(frames)
    switches, used = _id_switches(index, truth)
    assert index.shape == (T, 2)
    assert switches == 0
    assert used == {0: {0}, 1: {1}} or used == {0: {1}, 1: {0}}


def test_fast_look_alikes_passing_close_need_the_velocity_prediction():
    # Two identical bodies running at 4 m/s (13 cm a frame), 10 cm apart when they pass:
    # matching on the last position alone swaps them; the constant-velocity prediction
    # does not.
    T = 60
    paths = {0: _line([-3, 0.0, 0], [4.0, 0, 0], T), 1: _line([3, 0.1, 0], [-4.0, 0, 0], T)}
    for seed in range(3):
        frames, truth = _scene(paths, T, seed=seed, same_body=True)
        switches, used = _id_switches(track_indices(frames), truth)
        assert switches == 0 and all(len(s) == 1 for s in used.values())


def test_four_people_crossing_diagonally_at_one_point():
    T = 90
    paths = {
        i: _line(
            -2.5 * np.array([np.cos(a), np.sin(a), 0]), 1.6 * np.array([np.cos(a), np.sin(a), 0]), T
        )
        for i, a in enumerate(np.deg2rad([0, 70, 160, 250]))
    }
    frames, truth = _scene(paths, T, seed=1)
    switches, used = _id_switches(track_indices(frames), truth)
    assert switches == 0
    assert sorted(len(s) for s in used.values()) == [1, 1, 1, 1]


def test_people_entering_leaving_and_dropping_out_briefly():
    T = 120
    paths = {
        0: _line([0, 0, 0], [1.0, 0, 0], T, range(0, 60)),  # leaves at frame 60
        1: _line([0, 2, 0], [0.0, -0.5, 0], T, [*range(0, 70), *range(78, 120)]),  # 8 missed
        2: _line([4, 0, 0], [-1.0, 0.5, 0], T, range(40, 120)),  # enters at frame 40
    }
    frames, truth = _scene(paths, T, seed=2)
    tracks, ids = track(frames, max_missed=10)
    index = track_indices(frames, max_missed=10)
    switches, used = _id_switches(index, truth)
    assert switches == 0
    assert ids.tolist() == [0, 1, 2] and tracks.shape == (T, 3, J, 3)
    assert all(len(s) == 1 for s in used.values())
    for pid, path in paths.items():
        (p,) = used[pid]
        np.testing.assert_array_equal(np.isfinite(tracks[:, p, 0, 0]), np.isfinite(path[:, 0]))
    t = 100
    for k, pid in enumerate(truth[t]):  # the tracks hold the detections themselves
        (p,) = used[pid]
        np.testing.assert_array_equal(tracks[t, p], frames[t][k])


def test_a_dropout_longer_than_max_missed_starts_a_new_track():
    T = 60
    path = _line([0, 0, 0], [0.5, 0, 0], T, [*range(0, 20), *range(32, 60)])  # 12 missed
    frames, _ = _scene({0: path}, T, seed=3)
    assert track_indices(frames, max_missed=10).shape[1] == 2
    assert track_indices(frames, max_missed=12).shape[1] == 1


def test_gating_gives_a_teleporting_person_a_new_track():
    T = 60
    path = _line([0, 0, 0], [1.0, 0, 0], T)
    path[30:] += [0.0, 3.0, 0.0]  # jumps 3 m sideways at frame 30
    frames, _ = _scene({0: path}, T, seed=4)
    tracks, ids = track(frames, max_distance=0.5)
    assert ids.tolist() == [0, 1]
    np.testing.assert_array_equal(np.isfinite(tracks[:, 0, 0, 0]), np.arange(T) < 30)
    np.testing.assert_array_equal(np.isfinite(tracks[:, 1, 0, 0]), np.arange(T) >= 30)
    assert track(frames, max_distance=5.0)[0].shape[1] == 1  # a wide gate follows the jump


def test_min_length_drops_spurious_people_and_empty_rows_are_ignored():
    T = 40
    frames, _ = _scene({0: _line([0, 0, 0], [1.0, 0, 0], T)}, T, seed=5)
    frames[10] = np.concatenate([frames[10], _body(1.7, 9)[None] + [5.0, 5.0, 0.0]])
    frames[20] = np.concatenate([frames[20], np.full((1, J, 3), np.nan)])  # an empty slot
    frames[25] = np.zeros((0, J, 3))
    assert track_indices(frames).shape[1] == 2  # the ghost at frame 10 is its own track
    index = track_indices(frames, min_length=3)
    assert index.shape[1] == 1 and index[25, 0] == -1 and index[20, 0] == 0


def test_missing_joints_still_match():
    T = 30
    frames, truth = _scene(
        {0: _line([0, 0, 0], [1, 0, 0], T), 1: _line([1, 1, 0], [0, 1, 0], T)}, T, seed=6
    )
    rng = np.random.default_rng(7)
    for people in frames:
        people[rng.random(people.shape[:2]) < 0.3] = np.nan
    switches, used = _id_switches(track_indices(frames), truth)
    assert switches == 0 and all(len(s) == 1 for s in used.values())


def test_a_padded_array_is_accepted():
    frames, _ = _scene(
        {0: _line([0, 0, 0], [1, 0, 0], 10), 1: _line([2, 0, 0], [0, 1, 0], 10)}, 10, seed=8
    )
    tracks, ids = track(np.stack(frames))
    assert tracks.shape == (10, 2, J, 3) and ids.tolist() == [0, 1]


@pytest.mark.parametrize(
    ("frames", "kwargs", "field"),
    [
        ([np.zeros((1, J, 2))], {}, "poses_per_frame[0]"),
        ([np.zeros((1, J, 3)), np.zeros((1, 5, 3))], {}, "poses_per_frame[1]"),
        ([], {}, "poses_per_frame"),
        ([np.zeros((1, J, 3))], {"max_distance": 0.0}, "max_distance"),
        ([np.zeros((1, J, 3))], {"max_missed": -1}, "max_missed"),
        ([np.zeros((1, J, 3))], {"min_length": 0}, "min_length"),
    ],
)
def test_bad_input_names_the_field(frames, kwargs, field):
    with pytest.raises(InputError) as e:
        track(frames, **kwargs)
    assert e.value.field == field
