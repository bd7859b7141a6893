"""Gap filling, Hampel outliers, Butterworth and 1-euro filters on known signals."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.filters import butterworth, fill_gaps, finite_runs, hampel, one_euro

FPS = 100.0


def _sine(freq: float, seconds: float = 10.0, phase: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(seconds * FPS)) / FPS
    return t, np.sin(2 * np.pi * freq * t + phase)


def _fit(t: np.ndarray, y: np.ndarray, freq: float) -> tuple[float, float]:
    """Amplitude and phase of the ``freq`` component of y, by least squares."""
    A = np.stack([np.sin(2 * np.pi * freq * t), np.cos(2 * np.pi * freq * t)], 1)
    (s, c), *_ = np.linalg.lstsq(A, y, rcond=None)
    return float(np.hypot(s, c)), float(np.arctan2(c, s))


def _walk(T: int = 300, P: int = 2, J: int = 5, seed: int = 0) -> np.ndarray:
    """Smooth synthetic trajectories, shape (T, P, J, 3), metres."""
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None, None, None] / FPS
    amp, freq, phase = (
        rng.uniform(lo, hi, (1, P, J, 3)) for lo, hi in [(0.05, 0.3), (0.3, 2.0), (0, 2 * np.pi)]
    )
    return rng.normal(0, 1, (1, P, J, 3)) + amp * np.sin(2 * np.pi * freq * t + phase)


# --------------------------------------------------------------------------- fill_gaps


def test_fill_gaps_linear_is_exact_on_a_ramp_and_respects_max_gap():
    T = 60
    ramp = np.arange(T, dtype=float)[:, None, None, None] * np.array([1.0, -2.0, 0.5])
    x = np.repeat(ramp, 2, axis=2)  # (T, 1, 2, 3)
    x[:3, 0, 0] = np.nan  # leading gap: never extrapolated
    x[10:15, 0, 0] = np.nan  # 5 frames: filled
    x[20:40, 0, 0] = np.nan  # exactly max_gap = 20 frames: filled
    x[45:66, 0, 1] = np.nan  # 15 frames to the end: trailing, stays NaN
    x[5:26, 0, 1] = np.nan  # 21 frames: too long, stays NaN
    filled, mask = fill_gaps(x, max_gap=20)

    want = np.zeros((T, 1, 2), bool)
    want[10:15, 0, 0] = want[20:40, 0, 0] = True
    np.testing.assert_array_equal(mask, want)
    np.testing.assert_allclose(filled[mask], np.broadcast_to(ramp, x.shape)[mask], atol=1e-12)
    still_nan = np.isnan(x[..., 0]) & ~mask
    assert np.isnan(filled[still_nan]).all()
    assert still_nan[:3, 0, 0].all() and still_nan[5:26, 0, 1].all() and still_nan[45:, 0, 1].all()
    np.testing.assert_array_equal(filled[~np.isnan(x[..., 0])], x[~np.isnan(x[..., 0])])


def test_fill_gaps_max_gap_zero_fills_nothing():
    x = np.arange(10.0)[:, None].repeat(3, 1)
    x[4] = np.nan
    filled, mask = fill_gaps(x, max_gap=0)
    assert not mask.any() and np.isnan(filled[4]).all()
    filled, mask = fill_gaps(x, max_gap=1)
    assert mask[4] and np.allclose(filled[4], 4.0)


def test_fill_gaps_cubic_reproduces_a_cubic_where_linear_does_not():
    t = np.arange(40, dtype=float)
    truth = np.stack([0.001 * t**3 - 0.05 * t**2 + t, 0.02 * t**2, np.ones_like(t)], 1)
    x = truth.copy()
    x[12:20] = np.nan
    cubic, mask = fill_gaps(x, method="cubic")
    linear, _ = fill_gaps(x, method="linear")
    assert mask[12:20].all() and mask.sum() == 8
    np.testing.assert_allclose(cubic, truth, atol=1e-9)
    assert np.abs(linear - truth).max() > 0.1


# --------------------------------------------------------------------------- butterworth


def test_butterworth_passes_low_and_stops_high_frequencies_without_phase_lag():
    t, low = _sine(1.0)
    amp, phase = _fit(t, butterworth(low[:, None], FPS)[:, 0], 1.0)
    assert abs(amp - 1.0) < 0.03
    assert abs(phase - 0.3) < 1e-3  # zero phase: the input's phase, no lag

    t, high = _sine(20.0)
    amp, _ = _fit(t, butterworth(high[:, None], FPS)[:, 0], 20.0)
    assert amp < 0.1


def test_butterworth_order_is_that_of_the_whole_two_pass_filter():
    t, at_cutoff = _sine(6.0)
    amp, _ = _fit(t, butterworth(at_cutoff[:, None], FPS, cutoff=6.0, order=4)[:, 0], 6.0)
    assert 0.45 < amp < 0.55  # two passes of |H|^2 = 1/2: gain 1/2 at the cut-off
    t, above = _sine(12.0)
    amp4, _ = _fit(t, butterworth(above[:, None], FPS, order=4)[:, 0], 12.0)
    amp8, _ = _fit(t, butterworth(above[:, None], FPS, order=8)[:, 0], 12.0)
    # An octave above: 1 / (1 + 2.07^4) ~ 0.05 for two 2nd-order passes (2.07: the octave
    # after bilinear warping); two 4th-order passes would give ~0.003.
    assert 0.03 < amp4 < 0.08
    assert amp8 < 0.01


def test_butterworth_keeps_gaps_and_filters_each_run_on_its_own():
    x = _walk() + np.random.default_rng(1).normal(0, 0.01, (300, 2, 5, 3))
    x[100:110, 0, 2] = np.nan  # one joint
    x[200:205, 1] = np.nan  # a whole person
    x[:1, 0, 0] = np.nan
    x[2:3, 0, 0] = np.nan  # a one-frame run at frame 1
    y = butterworth(x, FPS)
    np.testing.assert_array_equal(np.isnan(y), np.isnan(x))
    assert y[1, 0, 0].tolist() == x[1, 0, 0].tolist()  # a single frame passes unchanged
    alone = butterworth(x[110:, 0, 2], FPS)  # the run after the gap, filtered by itself
    np.testing.assert_allclose(y[110:, 0, 2], alone, atol=1e-12)
    assert np.isfinite(butterworth(x[:4], FPS)[3]).all()  # runs shorter than the padding


def test_butterworth_reduces_noise_on_smooth_motion():
    truth = _walk()
    noisy = truth + np.random.default_rng(2).normal(0, 0.01, truth.shape)
    err_raw = np.sqrt(np.mean((noisy - truth) ** 2))
    err = np.sqrt(np.mean((butterworth(noisy, FPS) - truth) ** 2))
    assert err < 0.5 * err_raw


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"cutoff": 50.0}, "cutoff"),
        ({"cutoff": -1.0}, "cutoff"),
        ({"order": 3}, "order"),
        ({"order": 0}, "order"),
        ({"fps": 0.0}, "fps"),
    ],
)
def test_butterworth_rejects_bad_settings(kwargs, field):
    args = {"fps": FPS, **kwargs}
    with pytest.raises(InputError) as e:
        butterworth(np.zeros((10, 3)), **args)
    assert e.value.field == field


def test_partial_nan_and_inf_are_rejected():
    x = np.zeros((5, 2, 3))
    x[1, 0, 0] = np.nan
    with pytest.raises(InputError, match="every coordinate"):
        butterworth(x, FPS)
    x[1, 0] = 0.0
    x[2, 1, 2] = np.inf
    with pytest.raises(InputError, match="inf"):
        fill_gaps(x)
    with pytest.raises(InputError, match=r"\(T, \*, C\)"):
        hampel(np.zeros(5))


# --------------------------------------------------------------------------- one-euro


def test_one_euro_reduces_jitter_on_a_noisy_constant():
    rng = np.random.default_rng(3)
    x = 1.5 + rng.normal(0, 0.01, (600, 4, 3))
    y = one_euro(x, FPS)
    settled = slice(200, None)
    assert np.std(y[settled]) < 0.3 * np.std(x[settled])
    assert abs(np.mean(y[settled]) - 1.5) < 0.002


def test_one_euro_follows_a_step_and_beta_cuts_the_lag():
    x = np.zeros((300, 1, 3))
    x[100:, 0, 0] = 0.5  # a 0.5 m jump at frame 100
    slow = one_euro(x, FPS, beta=0.0)
    fast = one_euro(x, FPS, beta=2.0)
    assert abs(slow[-1, 0, 0] - 0.5) < 0.01  # caught up within 2 s
    assert slow[99, 0, 0] == 0.0  # causal: nothing moves before the step
    lag_slow, lag_fast = 0.5 - slow[110, 0, 0], 0.5 - fast[110, 0, 0]
    assert 0 < lag_fast < 0.5 * lag_slow
    np.testing.assert_allclose(fast[:, 0, 1:], 0.0)  # other axes untouched


def test_one_euro_restarts_after_a_gap():
    x = np.linspace(0, 1, 50)[:, None].repeat(3, 1)
    x[20:25] = np.nan
    y = one_euro(x, FPS)
    np.testing.assert_array_equal(np.isnan(y), np.isnan(x))
    np.testing.assert_array_equal(y[25], x[25])  # first frame of a run: the observation
    np.testing.assert_array_equal(y[0], x[0])


# --------------------------------------------------------------------------- hampel


def test_hampel_removes_spikes_and_keeps_clean_points():
    rng = np.random.default_rng(4)
    truth = _walk(T=400)
    x = truth + rng.normal(0, 0.005, truth.shape)
    spikes = [(50, 0, 1), (51, 1, 3), (200, 0, 0), (399, 1, 4), (0, 0, 2)]
    for f, p, j in spikes:
        x[f, p, j] += rng.choice([-1, 1], 3) * 0.3
    x[300:303, 0, 3] = np.nan
    y = hampel(x)
    removed = np.isnan(y[..., 0]) & ~np.isnan(x[..., 0])
    for f, p, j in spikes:
        assert removed[f, p, j]
    false_alarms = removed.sum() - len(spikes)
    # A 7-frame MAD is a noisy scale estimate: on Gaussian noise about 2.6% of the points
    # (any of 3 coordinates past 3 sigma) are flagged; fill_gaps bridges them.
    assert false_alarms <= 0.04 * removed.size
    assert np.isnan(y[300:303, 0, 3]).all()
    kept = ~np.isnan(y)
    np.testing.assert_array_equal(y[kept], x[kept])


def test_hampel_min_deviation_spares_tiny_changes_on_flat_data():
    x = np.zeros((20, 3))
    x[10, 0] = 1e-6  # flat data: the MAD is 0
    assert np.isnan(hampel(x)[10]).all()
    assert np.isfinite(hampel(x, min_deviation=1e-3)).all()


def test_hampel_chunks_give_the_same_answer():
    x = _walk(T=200) + np.random.default_rng(5).normal(0, 0.01, (200, 2, 5, 3))
    x[::37, 1, 2] += 0.5
    np.testing.assert_array_equal(hampel(x, chunk=13), hampel(x))


def test_hampel_rejects_an_even_window():
    with pytest.raises(InputError, match="odd"):
        hampel(np.zeros((10, 3)), window=6)


# --------------------------------------------------------------------------- together


def test_finite_runs():
    assert finite_runs(np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], bool)) == [(0, 2), (4, 5), (6, 9)]
    assert finite_runs(np.zeros(3, bool)) == []


def test_pipeline_outliers_gaps_filter_beats_raw():
    rng = np.random.default_rng(6)
    truth = _walk(T=500)
    x = truth + rng.normal(0, 0.01, truth.shape)
    bad = rng.random(truth.shape[:-1]) < 0.02
    x[bad] += 0.4
    x[rng.random(truth.shape[:-1]) < 0.03] = np.nan
    filled, _ = fill_gaps(hampel(x), max_gap=20)
    y = butterworth(filled, FPS)
    both = ~np.isnan(y[..., 0]) & ~np.isnan(x[..., 0])
    err_raw = np.linalg.norm(x - truth, axis=-1)[both].mean()
    err = np.linalg.norm(y - truth, axis=-1)[both].mean()
    assert err < 0.3 * err_raw
    assert np.isnan(y).mean() < 0.01  # the gaps were bridged
