"""The header and configuration bounds (bpms/io/bounded.py, issue 43.4): the JSON depth check
is linear in the text's length whatever the text, and counts what a parser would reach.

The expected depths are hand-built (or json.dumps of a known nesting), never taken from the
code under test; the cost is checked on structure (the blocks scanned), with a hostile 16 MiB
header that the former regular expression (quadratic on runs of ``\\"``: 90 s for 128 kB)
would not finish in hours."""

from __future__ import annotations

import json

import pytest

from bpms.io import bounded
from bpms.io.bounded import BoundError, json_depth, loads_json

pytestmark = pytest.mark.timeout(60)


@pytest.mark.parametrize(("text", "depth"), [
    ("", 0),
    ("{}", 1),
    ('{"a": [1, {"b": []}]}', 4),
    ('["[[[[", "]]]]"]', 1),  # brackets in strings do not count
    ('["\\"[[[", 2]', 1),  # an escaped quote does not end the string
    ('["\\\\", [[2]]]', 3),  # an escaped backslash does not escape the quote after it
    ('["\\\\\\"[[", 1]', 1),  # three backslashes: the quote is escaped
    ('[1, "abc [[[[', 5),  # an unterminated string counts its brackets
    ("[" * 200_000, 200_000),
])
def test_hand_built_depths(text, depth):
    assert json_depth(text) == depth


@pytest.mark.parametrize("block", [1, 2, 3, 7])
def test_depth_is_the_same_across_block_boundaries(monkeypatch, block):
    """Escapes, quotes and brackets that straddle the scanner's blocks."""
    nesting = [[["a\\", '"[', {"k]": ['\\"{', [["\\\\"]]]}]]]
    monkeypatch.setattr(bounded, "_BLOCK", block)
    assert json_depth(json.dumps(nesting)) == 7
    assert json_depth('[1, "ab\\\\\\"[[') == 3


def _reference_depth(text: str) -> int:
    """The depth read one character at a time, as the docstring states it: a quote after an
    even run of backslashes opens or closes a string; brackets count outside strings, and
    after the opening quote of a string that never ends."""
    inside, backslashes, depth, deepest = False, 0, 0, 0
    opened_at = tail = tail_high = 0
    for ch in text:
        if ch == '"' and backslashes % 2 == 0:
            inside = not inside
            if inside:
                opened_at, tail, tail_high = depth, 0, 0
        elif ch in "[{]}":
            step = 1 if ch in "[{" else -1
            if inside:
                tail += step
                tail_high = max(tail_high, tail)
            else:
                depth += step
                deepest = max(deepest, depth)
        backslashes = backslashes + 1 if ch == "\\" else 0
    return max(deepest, opened_at + tail_high) if inside else deepest


@pytest.mark.parametrize("block", [1, 3, 16, 1 << 20])
def test_random_texts_read_as_the_reference_reads_them(monkeypatch, block):
    import random

    monkeypatch.setattr(bounded, "_BLOCK", block)
    rng = random.Random(block)
    for _ in range(400):
        text = "".join(rng.choice('[]{}"\\ab,:') for _ in range(rng.randrange(60)))
        assert json_depth(text) == _reference_depth(text), repr(text)


def _blocks_scanned(monkeypatch, text: str) -> list[int]:
    sizes: list[int] = []
    real = bounded._Scan.block

    def counted(self, codes):
        sizes.append(codes.size)
        return real(self, codes)

    monkeypatch.setattr(bounded._Scan, "block", counted)
    json_depth(text)
    return sizes


@pytest.mark.parametrize("body", ['\\"', '"[', "\\\\"])
def test_a_16_mib_hostile_header_is_scanned_once_in_bounded_blocks(monkeypatch, body):
    """Every byte is scanned once, in blocks of at most _BLOCK bytes (linear time, bounded
    memory): the former check was quadratic on runs of ``\\"``."""
    text = '{"notes": "' + body * (8 * 1024 * 1024)
    sizes = _blocks_scanned(monkeypatch, text)
    assert sum(sizes) == len(text)
    assert max(sizes) <= bounded._BLOCK <= 1 << 20


def test_a_16_mib_hostile_header_is_refused_in_one_line():
    text = '{"notes": "' + '\\"' * (8 * 1024 * 1024 - 8)
    with pytest.raises(json.JSONDecodeError):  # read to its end: unterminated, refused
        loads_json(text, "the header")
    with pytest.raises(BoundError, match="nests 2097153 levels"):
        loads_json('{"a": ' + '"[' * (4 * 1024 * 1024) + "}", "the header")  # 1 + one per 2 pairs
    assert loads_json('{"notes": "' + '\\"' * (8 * 1024 * 1024 - 8) + '"}', "the header") \
        == {"notes": '"' * (8 * 1024 * 1024 - 8)}
