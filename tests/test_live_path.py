"""The live path's hand-offs (issue 18.4): a bounded processing queue with a C-level put and
get, the raw logger writing in batches, filtered rows written in batches and also when the
source goes quiet — with the same rows as the batch filter."""

from __future__ import annotations

import queue
import threading

import numpy as np
import pytest
from waiting import wait_until

from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.events import FrameEvent, SourceStatus
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.frames import FRAME_SIZE
from bpms.io.rawfile import read_raw
from bpms.pipeline.filtered_log import FILTERED_BATCH
from bpms.pipeline.handoff import Handoff
from bpms.pipeline.session import LiveSession


def test_handoff_is_bounded_and_a_waiting_producer_gets_room():
    handoff: Handoff[int] = Handoff(2)
    handoff.put_nowait(1)
    handoff.put_nowait(2)
    with pytest.raises(queue.Full):
        handoff.put_nowait(3)
    with pytest.raises(queue.Full):
        handoff.put_wait(3, 0.05)  # nobody takes anything: no room within the time given
    done = threading.Event()
    producer = threading.Thread(target=lambda: (handoff.put_wait(3, 20.0), done.set()))
    producer.start()
    assert handoff.get(5.0) == 1  # room for the waiting producer
    assert done.wait(20.0)
    producer.join(5.0)
    assert [handoff.get(5.0), handoff.get(5.0)] == [2, 3]
    with pytest.raises(queue.Empty):
        handoff.get_nowait()
    for k in range(3):  # an end marker goes in whatever the size
        handoff.put(k)
    assert handoff.qsize() == 3


class BurstThenQuiet:
    """A live source that delivers ``frames`` in one read, then stays quiet (reads time out,
    as a suit that stopped sending)."""

    def __init__(self, frames: bytes, start: float = 1.7e9) -> None:
        self._frames = [frames[k:k + FRAME_SIZE] for k in range(0, len(frames), FRAME_SIZE)]
        self._start = start
        self._closed = threading.Event()

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        if self._frames:
            frames, self._frames = self._frames, []
            return [FrameEvent(self._start + 0.02 * k, f, k, k == 0)
                    for k, f in enumerate(frames)]
        self._closed.wait(timeout)
        return []

    def status(self) -> SourceStatus:
        return SourceStatus("burst", "streaming")

    def close(self) -> None:
        self._closed.set()


@pytest.mark.parametrize("n", [3, 2 * FILTERED_BATCH + 3])
def test_rows_reach_the_filtered_file_when_the_source_goes_quiet(tmp_path, n):
    rec = simulate(duration_s=n / 50 + 1.0, seed=5)
    frames = rec.frames[:n * FRAME_SIZE]
    session = LiveSession(BurstThenQuiet(frames), recording_dir=tmp_path)
    status = session.start_logging(raw=True, filtered=True, name="quiet")
    session.start()
    try:
        # still logging, no frame coming: the rows waiting for a full batch are written
        assert wait_until(lambda: status.filtered_rows == n and status.raw_records == n)
    finally:
        session.stop()
    filtered = read_filtered(status.filtered_path)
    assert len(filtered.t) == n and not filtered.hole.any()
    reference = BodyPoseProcessor().process(rec.raw[:n], rec.errors[:n])
    np.testing.assert_allclose(filtered.euler, reference.euler_output, atol=1e-8)
    np.testing.assert_allclose(filtered.joint_angles, reference.joint_angles, atol=1e-8,
                               equal_nan=True)
    raw = read_raw(status.raw_path)
    assert raw.frames.tobytes() == frames
    np.testing.assert_array_equal(raw.times, 1.7e9 + 0.02 * np.arange(n))
