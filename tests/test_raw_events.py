"""Raw format version 2 (docs/raw-format.md): event records between the frame records, read by
the one reader; damage costs only what it hits and every frame keeps its slot; version 1
files read as before; the reader streams in flat memory. The expected values are built here
from the layout as documented (struct, zlib), not taken from the reader."""

from __future__ import annotations

import struct
import tracemalloc
import zlib

import numpy as np
import pytest

from bpms.firmware.sim.arbiter import MotionSource
from bpms.io.raw_reader import LOOKAHEAD, RawFile, RawFrames
from bpms.io.rawfile import (
    RECORD_SIZE,
    RawWriter,
    new_header,
    read_header,
    read_raw,
    write_raw,
)
from bpms.io.session_events import SessionEvent

N = 1200


@pytest.fixture(scope="module")
def frames():
    motion = MotionSource.simulated(duration_s=30.0, seed=4)
    return [motion.frame(j) for j in range(N)]


def _times(n=N):
    return 1.7e9 + np.arange(n) * 0.02


def _event_bytes(event: SessionEvent, t: float) -> bytes:
    """An event record made from docs/raw-format.md's table."""
    payload = event.to_json()
    head = struct.pack("<d", t) + b"$E" + struct.pack("<I", len(payload)) + payload
    return head + struct.pack("<I", zlib.crc32(head)) + b"E$"


EVENTS = [SessionEvent("marker", 100, data={"text": "start of squat"}),
          SessionEvent("reset_zero", 400, data={"source": "manual", "window": 25}),
          SessionEvent("alignment", 700, data={"on": False})]


def _file(tmp_path, frames, events=EVENTS, name="e.bpmsraw"):
    path = tmp_path / name
    write_raw(path, _times(), b"".join(frames), new_header(source="test"), events)
    return path


def test_the_event_record_is_the_documented_bytes(tmp_path, frames):
    path = _file(tmp_path, frames)
    _, offset = read_header(path)
    data = path.read_bytes()
    # the marker event goes just before frame 100's record
    at = offset + 100 * RECORD_SIZE
    want = _event_bytes(EVENTS[0], _times()[100])
    assert data[at:at + len(want)] == want
    assert data[at + len(want):at + len(want) + RECORD_SIZE][8:10] == b"$#"
    rec = read_raw(path)
    assert len(rec) == N and rec.problems == []
    assert rec.frames.tobytes() == b"".join(frames)
    assert [(slot, e.kind) for slot, e in rec.events] == [(100, "marker"), (400, "reset_zero"),
                                                          (700, "alignment")]
    assert rec.header["session_events"] is True


def _damaged(tmp_path, src, edit, name="d.bpmsraw"):
    data = bytearray(src.read_bytes())
    edit(data)
    out = tmp_path / name
    out.write_bytes(bytes(data))
    return out


def _check_slots(rec, frames, lost: set[int]):
    assert len(rec) == N  # every slot kept
    for k in range(N):
        if k not in lost:
            assert rec.frame_bytes(k) == frames[k], k
    assert set(rec.damaged.tolist()) == lost


def test_a_damaged_event_record_loses_only_itself(tmp_path, frames):
    src = _file(tmp_path, frames)
    event_at = bytes(src.read_bytes()).find(b"$E") - 8  # the first event (marker at 100)

    def flip(data):
        data[event_at + 20] ^= 0xFF  # a byte of its JSON: the CRC fails

    rec = read_raw(_damaged(tmp_path, src, flip))
    _check_slots(rec, frames, set())
    # its place between the frames is known, its kind is not (the flip hit "kind")
    assert [(slot, e.kind, e.data.get("kind")) for slot, e in rec.events] == [
        (100, "lost", "unknown"), (400, "reset_zero", None), (700, "alignment", None)]
    assert any("1 damaged event record(s) lost (unknown at frame 100)" in p
               for p in rec.problems)

    def cut(data):
        del data[event_at + 30:event_at + 33]  # bytes lost inside it

    rec = read_raw(_damaged(tmp_path, src, cut, "cut.bpmsraw"))
    _check_slots(rec, frames, set())
    assert [(slot, e.kind, e.data.get("kind")) for slot, e in rec.events] == [
        (100, "lost", "marker"), (400, "reset_zero", None), (700, "alignment", None)]


def test_damage_beside_events_costs_only_the_damaged_frames(tmp_path, frames):
    src = _file(tmp_path, frames)
    data = bytes(src.read_bytes())
    second = data.find(b"$E", data.find(b"$E") + 2) - 8  # the Reset Zero before frame 400
    size = 2 * len(_event_bytes(EVENTS[1], 0.0))  # (it changes numbers: written twice)

    def edit(data):
        del data[second + size + 100:second + size + 103]  # frame 400, right after it
        data[second - RECORD_SIZE + 8] = 0  # frame 399 loses its start marker
        data[second:second] = b"\x00garbage"  # inserted between frame 399 and the event

    rec = read_raw(_damaged(tmp_path, src, edit))
    _check_slots(rec, frames, {399, 400})
    assert [slot for slot, _ in rec.events] == [100, 400, 700]
    np.testing.assert_allclose(rec.times[401:], _times()[401:])  # no time shift after it


def test_an_event_at_the_end_and_a_torn_last_event(tmp_path, frames):
    end = SessionEvent("logging", -1, data={"action": "stop"})
    path = tmp_path / "end.bpmsraw"
    write_raw(path, _times(), b"".join(frames), new_header(), [EVENTS[0]])
    path.write_bytes(path.read_bytes() + _event_bytes(end, 1.8e9))  # 60 bytes: < a frame
    rec = read_raw(path)
    assert len(rec) == N and rec.problems == []
    assert rec.events[-1] == (N, SessionEvent("logging", -1, 1.8e9, {"action": "stop"}))
    torn = tmp_path / "torn.bpmsraw"
    torn.write_bytes(path.read_bytes()[:-20])
    rec = read_raw(torn)
    assert len(rec) == N and len(rec.events) == 1
    assert any("incomplete" in p for p in rec.problems)


def test_version_1_files_read_as_before(tmp_path, frames):
    """A version-1 file: frame records only; its bytes that happen to look like an event are
    damage, not events."""
    path = tmp_path / "v1.bpmsraw"
    write_raw(path, _times(), b"".join(frames), new_header(), [])
    data = bytearray(path.read_bytes())
    data[8:10] = struct.pack("<H", 1)
    _, offset = read_header(path)
    fake = _event_bytes(SessionEvent("marker", 5), 0.0)
    at = offset + 600 * RECORD_SIZE
    data[at:at] = fake  # a v1 reader resynchronises over these bytes
    path.write_bytes(bytes(data))
    rec = read_raw(path)
    assert RawFile(path).version == 1 and rec.events == []
    # bytes inserted between two intact records: skipped, no slot (every frame in place)
    assert len(rec) == N and len(rec.damaged) == 0
    assert rec.frames.tobytes() == b"".join(frames)
    assert any("inserted" in p for p in rec.problems)


def test_an_event_written_late_still_applies_at_its_frame(tmp_path, frames):
    """The live writer puts an event after the frames processed when it happened: up to
    LOOKAHEAD frames later it is still given to the chunk holding its frame."""
    path = tmp_path / "late.bpmsraw"
    with RawWriter(path, new_header(extra={"session_events": True})) as writer:
        for k, frame in enumerate(frames):
            writer.write(_times()[k], frame)
            if k == 1100:  # about 1,000 frames after the frame it names
                writer.write_event(SessionEvent("reset_zero", 90, data={"source": "manual"}))
    chunks = list(RawFile(path).chunks(chunk_frames=100, lookahead=LOOKAHEAD))
    placed = [(c.start, slot) for c in chunks for slot, _ in c.events]
    assert placed == [(0, 90)]
    # with a lookahead too short, it is applied at the first frame not yet given out
    f = RawFile(path)
    placed = [slot for c in f.chunks(chunk_frames=100, lookahead=200) for slot, _ in c.events]
    assert placed == [900] and any("after their frame" in p for p in f.problems)


def test_the_frames_a_writer_reports_on_disk_count_only_frames(tmp_path, frames):
    path = tmp_path / "w.bpmsraw"
    with RawWriter(path, new_header()) as writer:
        for k in range(50):
            writer.write(_times()[k], frames[k])
            if k % 10 == 0:
                writer.write_event(SessionEvent("note", k, data={"text": "x" * 500}))
        writer.flush()
        assert writer.records_on_disk() == 50 and writer.events == 5


def test_replay_reads_slots_from_disk_equal_to_read_raw(tmp_path, frames):
    src = _file(tmp_path, frames)
    damaged = _damaged(tmp_path, src, lambda d: d.__delitem__(slice(-2000, -1995)))
    whole = read_raw(damaged)
    slots = RawFrames(damaged)
    assert len(slots) == len(whole)
    assert [(s, e.to_json()) for s, e in slots.events] == [(s, e.to_json())
                                                           for s, e in whole.events]
    assert slots.damaged.tolist() == whole.damaged.tolist()
    for lo, hi in ((0, 7), (7, 300), (1190, 1200), (250, 260), (0, N)):  # in order, back
        times, data = slots.read(lo, hi)
        assert data == whole.frames[lo:hi].tobytes()
        np.testing.assert_array_equal(times, whole.times[lo:hi])


def _peak_reading(path) -> tuple[int, int]:
    tracemalloc.start()
    try:
        n = sum(len(c) for c in RawFile(path).chunks())
        return n, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_long_recording_streams_in_flat_memory(tmp_path, frames):
    """50,000 and 150,000 frames (17 and 52 MB): the reader holds the same few MB for both."""
    records = np.empty(N, dtype=[("time", "<f8"), ("frame", "V340")])
    records["frame"] = np.frombuffer(b"".join(frames), dtype="V340")
    peaks = []
    for n_frames in (50_400, 151_200):
        path = tmp_path / f"long{n_frames}.bpmsraw"
        with RawWriter(path, new_header()) as writer:
            for k in range(n_frames // N):
                records["time"] = 1.7e9 + (k * N + np.arange(N)) * 0.02
                writer._file.write(records.tobytes())  # (N records at once: the test's speed)
                writer.records += N
        n, peak = _peak_reading(path)
        assert n == n_frames
        peaks.append(peak)
    assert peaks[1] < 1.1 * peaks[0] + 1e6, peaks  # flat: not with the length
    assert peaks[1] < 0.5 * path.stat().st_size, peaks
