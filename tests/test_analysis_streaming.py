"""Streaming reductions (issue 18.1): range of motion and the walked path computed chunk by
chunk give the numbers of the whole-array computation, whatever the chunk boundaries."""

from __future__ import annotations

import itertools

import numpy as np

from bpms.analysis.rom import RomAccumulator
from bpms.analysis.track import TrackAccumulator, walked_path


def _walk(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    accel = {side: 1.0 + 0.2 * rng.random(n) for side in ("right", "left")}
    for k in range(40, n, 27):  # strikes, alternating, some closer than the minimum interval
        side = "right" if (k // 27) % 2 else "left"
        accel[side][k] = 2.5 + rng.random()
    accel["right"][[999, 1000]] = [3.9, 3.9]  # a plateau across a chunk boundary
    positions = rng.normal(0, 0.3, (n, 21, 3))
    positions[5:9] = np.nan
    return t, accel, positions


def test_track_in_chunks_equals_the_whole(tmp_path):
    t, accel, pos = _walk()
    whole = walked_path(t, accel, pos, 2.0, 0.4, 7.0)
    assert len(whole.times) > 50
    for bounds in ([1000, 1001, 2999], [1, 2, 3, 500, 1999], list(range(0, 3000, 7))):
        acc = TrackAccumulator(2.0, 0.4, 7.0)
        edges = [0, *[b for b in bounds if b > 0], len(t)]
        for lo, hi in itertools.pairwise(edges):
            acc.add(t[lo:hi], {s: a[lo:hi] for s, a in accel.items()}, pos[lo:hi])
        got = acc.track()
        np.testing.assert_array_equal(got.times, whole.times)
        assert got.sides == whole.sides
        np.testing.assert_array_equal(got.peaks, whole.peaks)
        np.testing.assert_allclose(got.positions, whole.positions, rtol=0, atol=1e-12)


def test_rom_in_chunks_equals_min_max_over_the_window():
    rng = np.random.default_rng(3)
    t = np.arange(2000) * 0.02
    angles = rng.normal(0, 0.5, (2000, 28))
    angles[:30] = np.nan  # before the first Reset Zero
    acc = RomAccumulator("x", 5.0, 30.0)
    for lo in range(0, 2000, 333):
        acc.add(t[lo:lo + 333], angles[lo:lo + 333])
    table = acc.table()
    mask = (t >= 5.0) & (t <= 30.0)
    np.testing.assert_allclose(table.minimum, np.degrees(angles[mask].min(axis=0)))
    np.testing.assert_allclose(table.maximum, np.degrees(angles[mask].max(axis=0)))
    assert (table.t0, table.t1) == (5.0, 30.0)
