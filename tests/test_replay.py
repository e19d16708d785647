"""Replay of a raw recording: pacing, pause, step, seek with pre-roll, as fast as possible."""

from __future__ import annotations

import time

import numpy as np
import pytest

from bpms.io.frames import FRAME_SIZE, decode_frames, encode_frames
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.replay import ReplaySource


@pytest.fixture
def recording(tmp_path):
    n = 1000
    raw = np.zeros((n, 18, 9), dtype=np.int16)
    raw[:, 0, 0] = np.arange(n)  # frame number in IMU 0's ax
    path = tmp_path / "r.bpmsraw"
    write_raw(path, 1.7e9 + np.arange(n) * 0.02, encode_frames(raw), new_header())
    return read_raw(path)


def frame_numbers(events):
    return [int(decode_frames(e.frame).raw[0, 0, 0]) for e in events]


def read_for(source, seconds):
    events, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        events += source.read(timeout=0.05)
    return events


def test_as_fast_as_possible_delivers_everything_in_order(recording):
    source = ReplaySource(recording, speed=None)
    events = []
    while not source.ended:
        events += source.read()
    assert frame_numbers(events) == list(range(1000))
    assert events[0].discontinuity and not any(e.discontinuity for e in events[1:])
    assert source.read(timeout=0.01) == []


def test_paced_at_speed(recording):
    source = ReplaySource(recording, speed=8.0)
    events = read_for(source, 0.5)  # 8 × 50 Hz × 0.5 s = 200 frames
    assert 170 <= len(events) <= 230
    assert frame_numbers(events) == list(range(len(events)))


def test_pause_step_and_play(recording):
    source = ReplaySource(recording, speed=4.0, autoplay=False)
    assert read_for(source, 0.2) == []
    source.step()
    source.step(2)
    assert frame_numbers(source.read()) == [0, 1, 2]
    source.play()
    assert frame_numbers(read_for(source, 0.2))[0] == 3
    source.pause()
    source.read(timeout=0.05)
    assert read_for(source, 0.2) == []


def test_seek_marks_a_discontinuity_with_preroll(recording):
    source = ReplaySource(recording, speed=None, preroll_s=2.0)
    source.read()
    source.seek(seconds=10.0)
    events = source.read()
    assert frame_numbers(events[:1]) == [500]
    assert events[0].discontinuity and len(events[0].preroll) == 100 * FRAME_SIZE
    assert frame_numbers([type(events[0])(0.0, events[0].preroll[-FRAME_SIZE:])]) == [499]
    source.seek(5000)
    assert source.ended and source.read(timeout=0.01) == []
    source.seek(0)
    assert source.read()[0].preroll == b""
