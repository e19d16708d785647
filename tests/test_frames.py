"""Frame codec (SPEC §2): encode/decode round trips, error words, marker checks."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bpms.io.frames import (
    FRAME_SIZE,
    IMU_NAMES,
    N_IMUS,
    FrameError,
    decode_frame,
    decode_frames,
    describe_errors,
    encode_frame,
    encode_frames,
    error_words_to_flags,
    flags_to_error_words,
    is_frame,
)

raw_frames = arrays(np.int16, st.tuples(st.integers(1, 5), st.just(18), st.just(9)))
error_flags = arrays(bool, (18, 3))


def test_layout_matches_spec():
    raw = np.zeros((18, 9), dtype=np.int16)
    raw[0, 0] = 0x0102  # IMU 0 ax, big-endian at offset 2
    raw[3, 8] = -2  # IMU 3 = cluster 1 slot 0, gz at 2 + 56 + 16
    errors = np.zeros((18, 3), dtype=bool)
    errors[4, 1] = True  # IMU 4 = cluster 1 slot 1, mag → bit 3*1+1 = 4
    frame = encode_frame(raw, errors)
    assert len(frame) == FRAME_SIZE == 340
    assert frame[:2] == b"$#" and frame[-2:] == b"#$"
    assert frame[2:4] == b"\x01\x02"
    assert frame[2 + 56 + 16 : 2 + 56 + 18] == b"\xff\xfe"
    assert frame[2 + 56 + 54 : 2 + 56 + 56] == (1 << 4).to_bytes(2, "big")
    assert len(IMU_NAMES) == N_IMUS


@given(raw_frames)
def test_round_trip(raw):
    rng = np.random.default_rng(int(raw.sum()) & 0xFFFF)
    errors = rng.random((len(raw), 18, 3)) < 0.1
    decoded = decode_frames(encode_frames(raw, errors))
    np.testing.assert_array_equal(decoded.raw, raw)
    np.testing.assert_array_equal(decoded.errors, errors)
    assert decoded.raw.dtype == np.int16 and decoded.raw.shape == raw.shape


@given(error_flags)
def test_error_word_bits(flags):
    words = flags_to_error_words(flags)
    assert words.shape == (6,)
    for cluster in range(6):
        for slot in range(3):
            for sensor in range(3):
                bit = bool(words[cluster] >> (3 * slot + sensor) & 1)
                assert bit == flags[3 * cluster + slot, sensor]
    assert (words >> 9 == 0).all()
    np.testing.assert_array_equal(error_words_to_flags(words), flags)


def test_encode_saturates_to_int16():
    raw = np.zeros((18, 9))
    raw[0, 0], raw[0, 1] = 40000, -40000
    decoded = decode_frame(encode_frame(raw))
    assert decoded.raw[0, 0, 0] == 32767 and decoded.raw[0, 0, 1] == -32768


def test_decode_rejects_bad_input():
    good = encode_frame(np.zeros((18, 9)))
    with pytest.raises(FrameError, match="whole number"):
        decode_frames(good[:-1])
    with pytest.raises(FrameError, match="markers"):
        decode_frames(good + b"X" + good[1:])
    assert is_frame(good) and not is_frame(good[:-1]) and not is_frame(b"x" + good[1:])


def _hand_built_frame(first: int) -> tuple[bytes, np.ndarray, np.ndarray]:
    """A frame packed by hand as SPEC §2 lays it out (not by the encoder): counts first,
    first + 1, ... (wrapping in int16); each cluster's error word has bit 3·slot + sensor of
    its flags and bits 9-15 all set (not flags: they must be ignored)."""
    counts = (np.arange(first, first + 162) + 32768) % 65536 - 32768
    raw = counts.reshape(18, 9)
    errors = np.zeros((18, 3), bool)
    body = b""
    for cluster in range(6):
        slot, sensor = cluster % 3, (cluster * 2) % 3
        errors[3 * cluster + slot, sensor] = True
        word = (1 << (3 * slot + sensor)) | 0xFE00
        body += struct.pack(">27hH", *raw[3 * cluster:3 * cluster + 3].ravel(), word)
    return b"$#" + body + b"#$", raw, errors


def test_decode_reads_hand_built_frames_from_any_buffer():
    frames = [_hand_built_frame(first) for first in (-32768, 0, 32700)]
    wire = b"".join(f for f, _, _ in frames)
    for buf in (wire, bytearray(wire), memoryview(wire), np.frombuffer(wire, np.uint8)):
        decoded = decode_frames(buf)
        np.testing.assert_array_equal(decoded.raw, [r for _, r, _ in frames])
        np.testing.assert_array_equal(decoded.errors, [e for _, _, e in frames])
        assert decoded.raw.dtype == np.int16 and decoded.raw.flags.c_contiguous
    live = decode_frames(frames[1][0])  # one frame, as live
    np.testing.assert_array_equal(live.raw[0], frames[1][1])
    np.testing.assert_array_equal(live.errors[0], frames[1][2])
    empty = decode_frames(b"")
    assert empty.raw.shape == (0, 18, 9) and empty.errors.shape == (0, 18, 3)


def test_describe_errors_names_the_sensor():
    flags = np.zeros((18, 3), dtype=bool)
    flags[17, 2] = True
    assert describe_errors(flags) == ["IMU 17 (Head) gyro"]
