"""The parser accepts a frame only when its end marker sits exactly at offset 338: a candidate
whose "#$" sits one byte early or late is garbage, whatever the chunking. Deterministic
companion of the property tests in test_parser.py (the planted-fault script relies on it)."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.io.frames import END, FRAME_SIZE, START, encode_frame
from bpms.io.parser import FrameParser


def good_frame(seed: int) -> bytes:
    rng = np.random.default_rng(seed)
    raw = rng.integers(-300, 300, size=(18, 9)).astype(np.int16)
    frame = encode_frame(raw)
    assert b"$#" not in frame[2:] and b"#$" not in frame[:-2]  # no chance markers inside
    return frame


def parse_all(stream: bytes, chunk: int | None) -> list[bytes]:
    parser = FrameParser()
    if chunk is None:
        return parser.feed(stream)
    out: list[bytes] = []
    for pos in range(0, len(stream), chunk):
        out += parser.feed(stream[pos:pos + chunk])
    return out


@pytest.mark.parametrize("shift", [-1, +1])
@pytest.mark.parametrize("chunk", [None, 1, 7, 340])
def test_end_marker_one_byte_off_is_rejected(shift, chunk):
    a, b = good_frame(1), good_frame(2)
    body = a[2:-2]
    # a 339- or 341-byte "frame": its end marker one byte early or late
    bad = START + (body[:-1] if shift < 0 else body + b"\x00") + END
    assert len(bad) == FRAME_SIZE + shift
    assert parse_all(bad + b, chunk) == [b]
    assert parse_all(a + bad + b, chunk) == [a, b]
