"""The one owner of a recording's time column (bpms.io.timebase), against times worked out by
hand: stream time is frame index × dt (SPEC §1: the filter's fixed 20 ms), never host time."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.io.timebase import frame_at, stream_time, stream_time_of, stream_times


def test_stream_times_of_a_block_and_of_one_live_frame():
    np.testing.assert_allclose(stream_times(3, 4, 0.02), [0.06, 0.08, 0.10, 0.12], atol=1e-15)
    np.testing.assert_allclose(stream_times(0, 3, 0.01), [0.0, 0.01, 0.02], atol=1e-15)
    one = stream_times(150, 1, 0.02)
    assert one.shape == (1,) and one[0] == pytest.approx(3.0, abs=1e-12)
    assert stream_times(5, 0, 0.02).shape == (0,)
    # a block and the same frames one at a time give the same numbers
    block = stream_times(1000, 5, 0.02)
    singles = [stream_times(1000 + k, 1, 0.02)[0] for k in range(5)]
    np.testing.assert_allclose(block, singles, rtol=0, atol=1e-12)
    np.testing.assert_allclose(block, [20.0, 20.02, 20.04, 20.06, 20.08], atol=1e-12)


def test_stream_time_of_indices_and_one_index():
    np.testing.assert_allclose(stream_time_of(np.array([0, 1, 50, -3]), 0.02),
                               [0.0, 0.02, 1.0, 0.0], atol=1e-15)
    assert stream_time(50) == pytest.approx(1.0, abs=1e-15)  # default dt: 20 ms
    assert stream_time(7, 0.1) == pytest.approx(0.7, abs=1e-15)
    assert stream_time(-2) == 0.0
    assert stream_time(0) == 0.0


def test_frame_at_the_nearest_frame():
    assert frame_at(12.5) == 625
    assert frame_at(0.0) == 0
    assert frame_at(0.029) == 1 and frame_at(0.031) == 2  # nearest, not truncated
    assert frame_at(1.0, 0.1) == 10
    assert frame_at(-0.04) == -2
