"""Damaged raw files: the reader resynchronises on the record structure, damaged stretches
keep their slots (so every later frame keeps its time), and what was skipped is reported."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.firmware.sim.arbiter import MotionSource
from bpms.io.rawfile import RECORD_SIZE, new_header, read_header, read_raw, write_raw


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """3,705 frames of simulated motion (independent truth: the motion model's frames)."""
    motion = MotionSource.simulated(duration_s=80.0, seed=21)
    n = 3705
    frames = [motion.frame(j) for j in range(n)]
    times = 1.7e9 + np.arange(n) * 0.02
    path = tmp_path_factory.mktemp("raw") / "intact.bpmsraw"
    write_raw(path, times, b"".join(frames), new_header(source="test"))
    return path, frames, times


def damage(src, dst, edit) -> None:
    _, offset = read_header(src)
    data = bytearray(src.read_bytes())
    edit(data, offset)
    dst.write_bytes(bytes(data))


def check_all_but(rec, frames, times, lost: set[int]) -> None:
    assert len(rec) == len(frames)  # every slot kept
    for k in range(len(frames)):
        if k not in lost:
            assert rec.frame_bytes(k) == frames[k], k
            # a cut through the end marker also takes the low byte of the next record's time
            assert rec.times[k] == pytest.approx(times[k], abs=1e-4)


@pytest.mark.parametrize("where", [8 + 100, 3, 8 + 338])  # in a frame, in a time, at a marker
def test_three_bytes_deleted_mid_file_lose_at_most_the_damaged_record(recording, tmp_path,
                                                                       where):
    src, frames, times = recording
    dst = tmp_path / "cut.bpmsraw"
    victim = 1000

    def cut(data, offset):
        at = offset + victim * RECORD_SIZE + where
        del data[at : at + 3]

    damage(src, dst, cut)
    rec = read_raw(dst)
    check_all_but(rec, frames, times, {victim})
    assert rec.damaged.tolist() == [victim] and rec.skipped_bytes == RECORD_SIZE - 3
    assert rec.decode().errors[victim].all()  # the placeholder says: no data here
    assert times[victim - 1] < rec.times[victim] < times[victim + 1]
    assert any("1 damaged record(s) (345 bytes)" in p for p in rec.problems)
    # frame 600 after the damage is still at 12.0 s (position × 0.02 s), not earlier
    assert rec.frame_bytes(victim + 600) == frames[victim + 600]


def test_twenty_damaged_records_keep_every_later_frame_in_place(recording, tmp_path):
    src, frames, times = recording
    dst = tmp_path / "twenty.bpmsraw"
    victims = list(range(100, 2100, 100))

    def smash(data, offset):
        for v in victims:
            at = offset + v * RECORD_SIZE + 8
            data[at : at + 2] = b"XX"  # the start marker gone, no shift

    damage(src, dst, smash)
    rec = read_raw(dst)
    check_all_but(rec, frames, times, set(victims))
    assert rec.damaged.tolist() == victims


def test_inserted_garbage_and_a_run_of_lost_records(recording, tmp_path):
    src, frames, _times = recording
    dst = tmp_path / "mixed.bpmsraw"

    def edit(data, offset):
        at = offset + 3000 * RECORD_SIZE
        del data[at : at + 5 * RECORD_SIZE]  # records 3000-3004 lost whole (no trace left)
        at = offset + 2000 * RECORD_SIZE + 50
        data[at:at] = b"$#garbage#$" * 7  # bytes inserted inside record 2000

    damage(src, dst, edit)
    rec = read_raw(dst)
    # record 2000 is damaged (one slot); records whose bytes are missing altogether cannot
    # be seen in the stream: later frames shift by 5 there, and only there.
    assert rec.damaged.tolist() == [2000]
    assert len(rec) == len(frames) - 5
    for k in (0, 1999, 2001, 2999):
        assert rec.frame_bytes(k) == frames[k]
    assert rec.frame_bytes(3000) == frames[3005]


def test_garbage_at_the_end_and_an_empty_data_part(recording, tmp_path):
    src, frames, _times = recording
    dst = tmp_path / "tail.bpmsraw"
    damage(src, dst, lambda data, offset: data.extend(b"\xff" * (2 * RECORD_SIZE + 10)))
    rec = read_raw(dst)
    assert len(rec) == len(frames) + 2 and rec.damaged.tolist() == [3705, 3706]
    only = tmp_path / "header.bpmsraw"
    damage(src, only, lambda data, offset: data.__delitem__(slice(offset, None)))
    assert len(read_raw(only)) == 0
