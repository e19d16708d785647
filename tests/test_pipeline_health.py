"""Overload is visible (issues 12.7 and 18.5): a live ``socket://`` suit source fed faster than
the filters shows every frame it could not filter in the status, marks each one in the filtered
file at its place, and still records every frame raw."""

from __future__ import annotations

import numpy as np
from waiting import wait_until

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.options import SerialOptions
from bpms.io.rawfile import read_raw
from bpms.pipeline.health import Hole, merge_holes
from bpms.pipeline.session import LiveSession
from bpms.pipeline.sources import SuitFrameSource

SPEED = 160  # frames due 160× as often as a real suit's: 50 Hz × 160 = 8,000 frames/s


class FastArbiter(Arbiter):
    """The simulated suit's arbiter with frame deadlines every 0.02 / SPEED s (real time)."""

    def _deadline(self, k: int) -> float:
        return self._stream_start + k * FRAME_PERIOD_S / SPEED


def test_merge_places_holes_between_processed_frames():
    order, idx, host, later = merge_holes(np.array([3, 4, 9]),
                                          [Hole(5, 0.5), Hole(8, 0.8), Hole(12, 1.2)])
    assert list(order) == [0, 1, -1, -2, 2]  # 3, 4, hole 5, hole 8, 9
    assert list(idx) == [5, 8] and list(host) == [0.5, 0.8] and later == [Hole(12, 1.2)]


def test_live_source_at_8000_fps_shows_and_marks_every_lost_frame(tmp_path):
    arbiter = FastArbiter(MotionSource.simulated(seed=5, duration_s=20.0))
    with TcpServer(arbiter) as server:
        # A short processing queue (8 frames instead of 3,000) so that this machine, however
        # fast, cannot filter every frame of a burst: frames must be lost, and counted.
        session = LiveSession(SuitFrameSource(server.url, SerialOptions()),
                              recording_dir=tmp_path, max_backlog=8)
        session.source.connect()
        rec = session.start_logging(raw=True, filtered=True, name="overload")
        lines = []
        session.start()
        assert wait_until(lambda: session.status().frames >= 8_000, 60)
        status = session.status()
        lines.append(status.health_line())
        session.source.stop_stream()
        assert wait_until(lambda: arbiter.stats.stops == 1, 10)
        assert wait_until(lambda: session.status().processing_backlog == 0, 20)
        session.stop()
    assert wait_until(lambda: not session.running, 30)
    final = session.status()
    raw = read_raw(rec.raw_path)
    assert len(raw) == final.frames  # the raw file holds every frame received
    assert final.not_filtered > 0, "the test must overload the filters"
    assert final.processed + final.not_filtered == final.frames
    assert final.dropped == final.not_filtered + final.display_skipped
    assert "NOT FILTERED" in final.health_line() and "backlog" in lines[0]
    filtered = read_filtered(rec.filtered_path)
    # one row per received frame, in order: the processed ones and a marked row per hole
    assert len(filtered.t) == len(raw)
    assert int(filtered.hole.sum()) == final.not_filtered == final.holes_marked
    np.testing.assert_allclose(filtered.host_time, raw.times, rtol=0, atol=1e-6)
    np.testing.assert_allclose(filtered.t, np.arange(len(raw)) * 0.02, atol=1e-9)
    assert np.isnan(filtered.euler[filtered.hole]).all()
    assert np.isfinite(filtered.euler[~filtered.hole][-100:]).all()



