"""Identities that hold: fragments re-linked across gaps, duplicates merged, ghosts
dropped, a known number of people (rmpl.pipeline.identity), on synthetic 3D people."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.pipeline.identity import IdentityConfig, resolve, view_counts
from rmpl.pipeline.tracking import track_indices
from rmpl.skeleton import COCO17

FPS = 25.0
# Heights above the floor and sideways offsets of the COCO-17 joints, as fractions of the
# stature (Drillis & Contini's proportions, roughly).
_FIGURE = {
    "nose": (0.0, 0.06, 0.936), "left_eye": (0.02, 0.05, 0.945),
    "right_eye": (-0.02, 0.05, 0.945), "left_ear": (0.045, 0.0, 0.94),
    "right_ear": (-0.045, 0.0, 0.94), "left_shoulder": (0.129, 0.0, 0.818),
    "right_shoulder": (-0.129, 0.0, 0.818), "left_elbow": (0.14, 0.0, 0.63),
    "right_elbow": (-0.14, 0.0, 0.63), "left_wrist": (0.14, 0.02, 0.485),
    "right_wrist": (-0.14, 0.02, 0.485), "left_hip": (0.095, 0.0, 0.53),
    "right_hip": (-0.095, 0.0, 0.53), "left_knee": (0.07, 0.01, 0.285),
    "right_knee": (-0.07, 0.01, 0.285), "left_ankle": (0.07, 0.0, 0.039),
    "right_ankle": (-0.07, 0.0, 0.039),
}  # fmt: skip
FIGURE = np.array([_FIGURE[n] for n in COCO17.joints])  # (17, 3)


def walk(height, start, velocity, frames, T, rng, noise=0.01):
    """One person's poses (T, 17, 3), NaN outside ``frames``: a standing body of
    ``height`` m whose feet move from ``start`` (x, y) at ``velocity`` (m/s)."""
    body = FIGURE * height
    t = np.arange(T)[:, None] / FPS
    xy = np.asarray(start, float) + t * np.asarray(velocity, float)
    out = (
        body[None] + np.column_stack([xy, np.zeros(T)])[:, None] + rng.normal(0, noise, (T, 17, 3))
    )
    absent = np.ones(T, bool)
    absent[list(frames)] = False
    out[absent] = np.nan
    return out


def scene(people, seed=0):
    """Per-frame shuffled detections (N_t, 17, 3) from people (T, 17, 3) each, and per
    frame the true person of each detection."""
    rng = np.random.default_rng(seed)
    T = len(people[0])
    frames, truth = [], []
    for t in range(T):
        here = [k for k, p in enumerate(people) if np.isfinite(p[t]).all()]
        rng.shuffle(here)
        frames.append(np.array([people[k][t] for k in here]).reshape(len(here), 17, 3))
        truth.append(here)
    return frames, truth


def run_identity(frames, config=None, **kwargs):
    index = track_indices(frames)  # the tracker's defaults: gate 0.5 m, 10 frames missed
    return index, resolve(frames, index, config, FPS, **kwargs)


def owners(index, truth):
    """Per identity, the set of true people its detections belong to."""
    return [{truth[t][index[t, p]] for t in np.flatnonzero(index[:, p] >= 0)}
            for p in range(index.shape[1])]  # fmt: skip


def test_a_track_broken_by_a_gap_is_relinked():
    rng = np.random.default_rng(1)
    T = 100
    person = walk(1.75, (-1.5, 0.0), (1.2, 0.0), [*range(40), *range(60, T)], T, rng)
    frames, truth = scene([person])
    index, found = run_identity(frames)
    assert index.shape[1] == 2  # the tracker alone loses the person in the 20-frame gap
    assert found.index.shape[1] == 1
    assert (found.index[:, 0] >= 0).sum() == 80
    assert [m["kind"] for m in found.merges] == ["relinked"]
    assert found.merges[0]["gap_frames"] == 21


def test_two_people_who_cross_unseen_keep_their_identities():
    """Two people of the same build cross while no camera sees them (frames 38-52, the
    crossing at 45): each reappears nearer where the other vanished, and their motion
    carries each to its own continuation, not the other's."""
    rng = np.random.default_rng(2)
    T = 90
    seen = [*range(38), *range(53, T)]
    speed = 2.0 / (45 / FPS)  # both reach x = 0 at frame 45
    a = walk(1.70, (-2.0, 0.2), (speed, 0.0), seen, T, rng)
    b = walk(1.70, (2.0, -0.2), (-speed, 0.0), seen, T, rng)
    frames, truth = scene([a, b])
    index, found = run_identity(frames)
    assert index.shape[1] == 4  # the tracker alone loses both
    assert found.index.shape[1] == 2
    assert sorted(map(sorted, owners(found.index, truth))) == [[0], [1]]


def test_a_duplicate_is_merged_and_a_neighbour_is_not():
    """One person seen twice (a copy 5 cm off, frames 20-45) is merged into the person; a
    real second person standing 45 cm beside them keeps a track of their own."""
    rng = np.random.default_rng(3)
    T = 60
    a = walk(1.80, (0.0, 0.0), (0.3, 0.0), range(T), T, rng)
    twin = walk(1.80, (0.05, 0.0), (0.3, 0.0), range(20, 46), T, rng)
    neighbour = walk(1.65, (0.0, 0.45), (0.3, 0.0), range(T), T, rng)
    frames, truth = scene([a, twin, neighbour])
    _, found = run_identity(frames)
    assert found.index.shape[1] == 2
    merged = [m for m in found.merges if m["kind"] == "duplicate"]
    assert len(merged) == 1 and merged[0]["frames_dropped"] == 26
    groups = sorted(map(sorted, owners(found.index, truth)))
    assert groups == [[0], [2]]  # the twin's frames all coincide with the person's


def test_a_person_who_returns_keeps_their_identity_when_the_body_matches():
    """A tall person leaves and comes back 3 s later elsewhere; meanwhile a short person
    appears: the body tells them apart."""
    rng = np.random.default_rng(4)
    T = 160
    tall = walk(1.88, (-1.0, 0.0), (0.5, 0.0), [*range(30), *range(105, T)], T, rng)
    short = walk(1.50, (1.0, 1.0), (0.0, -0.5), range(45, 90), T, rng)
    frames, truth = scene([tall, short])
    _, found = run_identity(frames)
    assert found.index.shape[1] == 2
    assert sorted(map(sorted, owners(found.index, truth))) == [[0], [1]]
    relinked = [m for m in found.merges if m["kind"] == "relinked"]
    assert len(relinked) == 1 and relinked[0]["body_difference"] < 0.05


def test_a_body_that_does_not_match_is_not_relinked():
    rng = np.random.default_rng(5)
    T = 120
    tall = walk(1.90, (0.0, 0.0), (0.0, 0.0), range(40), T, rng)
    child = walk(1.30, (0.0, 0.0), (0.0, 0.0), range(70, T), T, rng)
    frames, _ = scene([tall, child])
    _, found = run_identity(frames)
    assert found.index.shape[1] == 2 and not found.merges


def test_people_folds_fragments_into_the_known_count():
    """Two people; one of them is lost twice and returns far away faster than anyone walks
    (the re-link refuses it). With --people 2 the fragments join; a third fragment present
    with both people is dropped."""
    rng = np.random.default_rng(6)
    T = 120
    a = walk(1.80, (0.0, 0.0), (0.0, 0.0), range(T), T, rng)
    b1 = walk(1.60, (-3.0, 2.0), (0.0, 0.0), range(0, 40), T, rng)
    b2 = walk(1.60, (3.0, 2.0), (0.0, 0.0), range(45, T), T, rng)
    ghost = walk(1.70, (0.0, 3.5), (0.0, 0.0), range(50, 70), T, rng)
    frames, truth = scene([a, b1, b2, ghost])
    _, free = run_identity(frames)
    assert free.index.shape[1] == 4
    _, two = run_identity(frames, IdentityConfig(people=2))
    assert two.index.shape[1] == 2
    assert sorted(map(sorted, owners(two.index, truth))) == [[0], [1, 2]]
    assert [(d["kind"], d["frames"]) for d in two.drops] == [("people", 20)]


def _rig():
    from rmpl.geometry.camera import Camera, Rig, look_at

    K = np.array([[800.0, 0, 500], [0, 800, 500], [0, 0, 1]])
    cams = []
    for v, a in enumerate(np.deg2rad(45 + 90 * np.arange(4))):
        R, t = look_at(np.array([5 * np.cos(a), 5 * np.sin(a), 2.0]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(1000, 1000), name=f"cam{v}"))
    return Rig(tuple(cams))


class _Seen:
    """An association's scores (N, V, J): which views detect each person."""

    def __init__(self, views_per_person, num_views=4):
        self.scores = np.zeros((len(views_per_person), num_views, 17))
        for n, k in enumerate(views_per_person):
            self.scores[n, :k] = 0.9


def test_a_ghost_only_two_of_four_cameras_detect_is_dropped():
    """A short track that 2 views detect where all 4 cameras look is a ghost; a person the
    4 views detect, just as short, is kept; with 2 views counted as enough, both stay."""
    rng = np.random.default_rng(7)
    T = 60
    person = walk(1.75, (-0.5, 0.0), (0.3, 0.0), range(T), T, rng)
    ghost = walk(1.70, (1.0, 1.0), (0.0, 0.0), range(10, 20), T, rng)
    brief = walk(1.70, (-1.0, -1.0), (0.0, 0.0), range(30, 40), T, rng)
    frames, truth = scene([person, ghost, brief])
    seen = [_Seen([4 if k != 1 else 2 for k in here]) for here in truth]
    views, cameras = view_counts(seen, frames, _rig())
    assert max(c.max() for c in cameras if len(c)) == 4
    _, found = run_identity(frames, views=views, cameras=cameras)
    assert sorted(map(sorted, owners(found.index, truth))) == [[0], [2]]
    assert [d["kind"] for d in found.drops] == ["ghost"]
    lenient = IdentityConfig(ghost_max_views=1)
    _, kept = run_identity(frames, lenient, views=views, cameras=cameras)
    assert kept.index.shape[1] == 3


def test_nobody_anywhere_gives_no_identity():
    frames = [np.zeros((0, 17, 3)) for _ in range(5)]
    found = resolve(frames, track_indices(frames), fps=FPS)
    assert found.index.shape == (5, 0) and found.to_json()["tracks"] == 0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"people": 0}, "--people"), ({"max_speed": -1.0}, "max_speed"),
     ({"min_frames": 0}, "min_frames")],
)  # fmt: skip
def test_bad_settings_are_one_clear_error(kwargs, field):
    with pytest.raises(InputError) as e:
        IdentityConfig(**kwargs)
    assert e.value.field == field


def test_an_index_of_other_frames_is_refused():
    frames = [np.zeros((1, 17, 3)) for _ in range(3)]
    with pytest.raises(InputError, match="index"):
        resolve(frames, np.zeros((4, 1), int))
