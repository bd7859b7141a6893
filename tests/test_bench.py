"""rmpl bench's memory figure: the long-sequence lift is measured in its own process."""

from __future__ import annotations

import numpy as np

from rmpl.bench import long_sequence_memory, peak_memory_mb


def test_long_sequence_memory_is_the_child_peak():
    big = np.ones((160, 1000, 1000))  # 1.28 GB in this process: must not leak into the figure
    big[::7] = 2.0
    parent = peak_memory_mb()
    assert parent > 1200
    mb, seconds = long_sequence_memory(200)
    assert 0 < mb < parent - 500 and seconds > 0
    del big


def test_temporal_track_speed_and_memory_come_from_a_child():
    from rmpl.bench import temporal_track

    fps, mb = temporal_track(200)
    assert fps > 0 and mb > 0
    assert mb != peak_memory_mb()  # the child's own peak, not this process's
