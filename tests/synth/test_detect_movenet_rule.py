"""The rule that chooses rmpl run's default detector (rmpl.benchmarks.detector.choose_default)
and the benchmark's scene scoring helpers, on made-up figures (plain numpy)."""

from __future__ import annotations

import numpy as np

from rmpl.benchmarks.detector import Score, _shown, choose_default


def _s(name, recall, precision, seconds, feet=True) -> Score:
    return Score(name, 100, 300, recall, precision, 0.03, 0.9 if feet else 0.0, seconds, feet)


def test_highest_recall_among_the_precise_with_feet():
    scores = [
        _s("no-feet", 0.99, 0.99, 0.01, feet=False),  # not eligible: no heels or toes
        _s("imprecise", 0.97, 0.90, 0.1),  # below 95% precision
        _s("a", 0.90, 0.96, 0.5),
        _s("b", 0.86, 0.99, 0.1),
    ]
    assert choose_default(scores).detector == "a"


def test_within_one_point_of_recall_the_faster_wins():
    scores = [_s("slow", 0.905, 0.97, 0.5), _s("fast", 0.897, 0.96, 0.2), _s("c", 0.88, 1, 0.1)]
    assert choose_default(scores).detector == "fast"


def test_none_precise_enough_the_most_precise_and_none_eligible():
    assert choose_default([_s("a", 0.9, 0.90, 0.1), _s("b", 0.5, 0.94, 0.1)]).detector == "b"
    assert choose_default([_s("a", 0.9, 0.99, 0.1, feet=False)]) is None


def test_a_view_shows_a_body_with_six_limb_joints_inside_and_not_hidden():
    proj = np.full((2, 1, 17, 2), 50.0)  # 2 views, 1 body, every joint at (50, 50)
    proj[1, 0, 5:11] = -10.0  # view 1: shoulders, elbows, wrists outside
    hidden = np.zeros((2, 1, 17), bool)
    truth = {"projected": proj, "hidden": hidden, "size": np.array([[100, 100], [100, 100]])}
    assert _shown(truth).tolist() == [[True], [True]]  # view 1 keeps its 6 leg joints
    hidden[1, 0, 11] = True  # and one of them drawn over by someone else
    assert _shown(truth).tolist() == [[True], [False]]
