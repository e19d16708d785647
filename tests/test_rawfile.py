"""Native raw recording format: round trip, O(1) layout, torn and damaged files."""

from __future__ import annotations

import os

import numpy as np
import pytest

from bpms.io.frames import FRAME_DTYPE, FRAME_SIZE, decode_frames, encode_frames
from bpms.io.rawfile import (
    RECORD_SIZE,
    RawFileError,
    RawWriter,
    RecordingError,
    new_header,
    read_header,
    read_raw,
    write_raw,
)


def frames_and_times(n: int, seed: int = 0) -> tuple[bytes, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    raw = rng.integers(-600, 600, (n, 18, 9))
    return encode_frames(raw), 1.7e9 + np.arange(n) * 0.02, raw


def test_round_trip_and_header(tmp_path):
    frames, times, raw = frames_and_times(200)
    header = new_header(calibration=np.ones((18, 16)), options={"filter": {"kp_yaw": 1.2}},
                        notes="subject S01, suited 4.3 psi", source="test")
    path = tmp_path / "Raw_test_1.bpmsraw"
    with RawWriter(path, header) as writer:
        for k in range(200):
            writer.write(times[k], frames[k * FRAME_SIZE:(k + 1) * FRAME_SIZE])
    rec = read_raw(path)
    assert len(rec) == 200 and rec.problems == []
    np.testing.assert_array_equal(rec.times, times)
    np.testing.assert_array_equal(rec.decode().raw, raw)
    assert rec.header["notes"] == "subject S01, suited 4.3 psi"
    assert rec.header["calibration"] == np.ones((18, 16)).tolist()
    assert rec.header["format_version"] == 2


def test_records_are_fixed_size_and_reachable_directly(tmp_path):
    frames, times, raw = frames_and_times(50)
    path = tmp_path / "r.bpmsraw"
    write_raw(path, times, frames, new_header())
    _, offset = read_header(path)
    assert offset % 16 == 0
    assert (os.path.getsize(path) - offset) == 50 * RECORD_SIZE
    with path.open("rb") as f:
        f.seek(offset + 37 * RECORD_SIZE + 8)
        frame = f.read(FRAME_SIZE)
    np.testing.assert_array_equal(decode_frames(frame).raw[0], raw[37])


def test_torn_last_record_is_ignored_with_a_warning(tmp_path):
    frames, times, _ = frames_and_times(10)
    path = tmp_path / "r.bpmsraw"
    write_raw(path, times, frames, new_header())
    with path.open("ab") as f:
        f.write(b"\x00" * 100)  # a record cut off by a crash
    rec = read_raw(path)
    assert len(rec) == 10
    assert "incomplete" in rec.problems[0]


def test_damaged_record_keeps_its_slot_and_is_counted(tmp_path):
    frames, times, _ = frames_and_times(10)
    path = tmp_path / "r.bpmsraw"
    write_raw(path, times, frames, new_header())
    _, offset = read_header(path)
    data = bytearray(path.read_bytes())
    data[offset + 3 * RECORD_SIZE + 8] = ord("X")  # frame 3 loses its start marker
    path.write_bytes(bytes(data))
    rec = read_raw(path)
    assert len(rec) == 10 and "1 damaged record" in rec.problems[0]  # the slot is kept
    assert rec.damaged.tolist() == [3] and rec.decode().errors[3].all()
    expected = np.frombuffer(frames, dtype=FRAME_DTYPE)
    keep = [k for k in range(10) if k != 3]
    assert rec.frames[keep].tobytes() == expected[keep].tobytes()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "not a BPMS raw recording"),
        (b"hello world, this is text", "not a BPMS raw recording"),
        (b"BPMSRAW\0\x09\x00\x10\x00\x00\x00", "newer than this software"),
        (b"BPMSRAW\0\x01\x00\xff\x00\x00\x00{", "cut short"),
        (b"BPMSRAW\0\x01\x00\x03\x00\x00\x00{{{", "header is damaged"),
    ],
)
def test_foreign_or_broken_files_give_clear_errors(tmp_path, content, message):
    path = tmp_path / "x.bpmsraw"
    path.write_bytes(content)
    with pytest.raises(RawFileError, match=message):
        read_raw(path)


def test_missing_file(tmp_path):
    with pytest.raises(RawFileError, match="cannot be read"):
        read_raw(tmp_path / "missing.bpmsraw")


def test_never_overwrites_and_unwritable_folder(tmp_path):
    path = tmp_path / "r.bpmsraw"
    path.write_bytes(b"precious")
    with pytest.raises(RecordingError, match="cannot create"):
        RawWriter(path, new_header())
    assert path.read_bytes() == b"precious"
    with pytest.raises(RecordingError):
        RawWriter(tmp_path / "no" / "such" / "dir" / "r.bpmsraw", new_header())


def test_flushed_records_are_on_disk_before_close(tmp_path):
    frames, times, _ = frames_and_times(5)
    path = tmp_path / "r.bpmsraw"
    writer = RawWriter(path, new_header(), flush_interval_s=0.0)
    for k in range(5):
        writer.write(times[k], frames[k * FRAME_SIZE:(k + 1) * FRAME_SIZE])
    assert len(read_raw(path)) == 5  # read by another handle while still open
    writer.close()
