"""Intact frames whose payloads hold marker bytes by chance (planted here on purpose) all come
out of the streaming parser, whatever the chunking."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.io.parser import FrameParser

FRAME = 340


def frame(k: int, rng: np.random.Generator) -> bytearray:
    body = bytearray(rng.integers(0, 256, FRAME, dtype=np.uint8).tobytes())
    body[0:2], body[338:340] = b"$#", b"#$"
    body[2:6] = k.to_bytes(4, "little")
    for j in range(6, 338):  # no chance markers except the planted ones
        if body[j : j + 2] in (b"$#", b"#$"):
            body[j] = 0
    return body


def planted_stream(n: int, seed: int) -> tuple[list[bytes], bytes]:
    """Frames where frame k's payload holds ``$#`` at offset o and frame k+1 holds ``#$`` at
    offset o - 2, i.e. exactly 338 bytes later: a false candidate overlapping both frames."""
    rng = np.random.default_rng(seed)
    frames = [frame(k, rng) for k in range(n)]
    for k in range(n - 1):
        o = int(rng.integers(8, 330))
        frames[k][o : o + 2] = b"$#"
        frames[k + 1][o - 2 : o] = b"#$"
    out = [bytes(f) for f in frames]
    return out, b"".join(out)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_every_frame_with_planted_markers_comes_out(seed):
    frames, stream = planted_stream(3000, seed)
    rng = np.random.default_rng(seed + 100)
    parser = FrameParser()
    got: list[bytes] = []
    pos = 0
    while pos < len(stream):
        step = int(rng.choice([1, 7, 340, 341, 1000, 4096]))
        got += parser.feed(stream[pos : pos + step])
        pos += step
    got += parser.flush()
    assert got == frames
    assert parser.stats.discarded_bytes == 0 and parser.stats.resyncs == 0


def test_a_frame_cut_short_before_an_intact_one_still_loses_to_it():
    # the case the "later wins" rule exists for must keep working
    rng = np.random.default_rng(9)
    a, b, c = (bytes(frame(k, rng)) for k in range(3))
    cut = a[:200]  # a frame lost its tail: its "$#" + 338 bytes lands in b's payload
    stream = cut + b + c
    # make the false candidate at 0 complete: "#$" 338 bytes after it, inside b
    stream = bytearray(stream)
    stream[338:340] = b"#$"
    parser = FrameParser()
    got = parser.feed(bytes(stream)) + parser.flush()
    assert got[-1] == c and bytes(stream[200:540]) in got
