"""Bounds every reader checks before it parses (docs/raw-format.md, docs/configuration.md).

A file is input from anyone: a header that claims 4 GB, a 200 MB header or 200,000 nested
``[`` must give a one-line refusal, not a ``MemoryError`` or a ``RecursionError`` traceback.
So, before parsing:

- a recording's header (raw JSON header, filtered ``#`` lines) is at most
  :data:`MAX_HEADER_BYTES` (16 MiB; a real one is a few kB);
- a configuration file (``options.toml``, ``Calib.cfg``, ``Calib.json``) is at most
  :data:`MAX_CONFIG_BYTES` (1 MiB; a real one is under 30 kB);
- JSON nests at most :data:`MAX_JSON_DEPTH` levels (a real header nests 4).

The depth is measured without parsing, in time linear in the length and memory bounded
whatever the text (:func:`json_depth`): a 16 MiB text costs a fraction of a second.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from bpms.io.paths import require_regular_input

MAX_HEADER_BYTES = 16 * 1024 * 1024
MAX_CONFIG_BYTES = 1024 * 1024
MAX_JSON_DEPTH = 64


class BoundError(ValueError):
    """Input beyond a reader's bound (too big, nested too deeply); one-line message."""


def _mib(n: int) -> str:
    return f"{n / (1024 * 1024):g} MiB"


def check_size(size: int, limit: int, what: str) -> None:
    """Raise :class:`BoundError` when ``size`` bytes exceed ``limit``."""
    if size > limit:
        raise BoundError(f"{what} is {size:,} bytes, more than the {_mib(limit)} this "
                         "software reads")


def json_depth(text: str) -> int:
    """The deepest nesting of ``[``/``{`` in JSON ``text`` (brackets inside strings do not
    count). An unterminated string counts its brackets: a damaged text can only read deeper,
    never shallower, than it is.

    Linear in the length and bounded in memory, whatever the text (issue 43: a regular
    expression over runs of ``\\"`` was quadratic): one pass over blocks of :data:`_BLOCK`
    bytes, each in a few vectorised steps. A ``"`` opens or closes a string unless an odd run
    of ``\\`` stands before it; a backslash outside a string is invalid JSON, which the
    parser stops at, so reading it as an escape there changes no depth the parser reaches."""
    data = text.encode("utf-8", errors="surrogatepass")
    scan = _Scan()
    for start in range(0, len(data), _BLOCK):
        scan.block(np.frombuffer(data, np.uint8, min(_BLOCK, len(data) - start), start))
    return scan.result()


#: Bytes scanned per block by :func:`json_depth` (a few tens of MB of arrays per block).
_BLOCK = 1 << 20


class _Scan:
    """The state of :func:`json_depth` carried from one block to the next."""

    def __init__(self) -> None:
        self.backslashes = 0  # the run of backslashes that ended the previous block
        self.in_string = False  # after an opening quote
        self.depth = 0  # the nesting outside strings at the end of the previous block
        self.deepest = 0
        # Since the last opening quote, should its string never end: the depth there, the
        # bracket sum since and the highest prefix of that sum.
        self.open_depth = self.open_sum = self.open_high = 0

    def _real_quotes(self, codes: np.ndarray) -> np.ndarray:
        """Offsets of the quotes that open or close a string."""
        quotes = np.flatnonzero(codes == 0x22)
        backslash = codes == 0x5C
        if not backslash.any():  # no escape here: only the previous block's run can escape
            carried, self.backslashes = self.backslashes, 0
            if carried % 2 and quotes.size and quotes[0] == 0:
                return quotes[1:]
            return quotes
        # per byte: the offset of the last byte at or before it that is not a backslash
        last = np.maximum.accumulate(np.where(backslash, np.int32(-1),
                                              np.arange(codes.size, dtype=np.int32)))
        before = last[np.maximum(quotes - 1, 0)]  # for quotes at offset 0: ignored below
        run = np.where(before >= 0, quotes - 1 - before, quotes + self.backslashes)
        run[quotes == 0] = self.backslashes
        end = int(last[-1])
        self.backslashes = codes.size - 1 - end if end >= 0 else self.backslashes + codes.size
        return quotes[run % 2 == 0]

    def block(self, codes: np.ndarray) -> None:
        quotes = self._real_quotes(codes)
        step = ((codes == 0x5B) | (codes == 0x7B)).view(np.int8) \
            - ((codes == 0x5D) | (codes == 0x7D)).view(np.int8)
        if quotes.size:
            toggles = np.zeros(codes.size, np.int8)
            toggles[quotes] = 1
            inside = np.bitwise_xor.accumulate(toggles)
            if self.in_string:
                inside ^= 1
            outside = step * (1 - inside)
        else:
            outside = step if not self.in_string else None
        start_depth = self.depth
        if outside is not None and outside.any():
            levels = np.cumsum(outside, dtype=np.int64)
            self.deepest = max(self.deepest, start_depth + int(levels.max()))
            self.depth = start_depth + int(levels[-1])
        in_string = self.in_string ^ bool(quotes.size % 2)
        if quotes.size and in_string:  # a new opening quote: its string may never end
            last = int(quotes[-1])
            self.open_depth = start_depth + int(np.sum(outside[:last], dtype=np.int64))
            self.open_sum = self.open_high = 0
            tail = step[last + 1:]
        else:
            tail = step if in_string else step[:0]
        if tail.size:
            sums = self.open_sum + np.cumsum(tail, dtype=np.int64)
            self.open_high = max(self.open_high, int(sums.max()))
            self.open_sum = int(sums[-1])
        self.in_string = in_string

    def result(self) -> int:
        if self.in_string:  # an unterminated string: its brackets count
            return max(self.deepest, self.open_depth + self.open_high)
        return self.deepest


def loads_json(text: str, what: str, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """``json.loads(text)`` after the size and depth checks. Raises :class:`BoundError`
    (too big or nested too deeply) or ``json.JSONDecodeError`` (a ValueError)."""
    check_size(len(text), MAX_HEADER_BYTES, what)
    depth = json_depth(text)
    if depth > max_depth:
        raise BoundError(f"{what} nests {depth} levels deep, more than the {max_depth} this "
                         "software reads")
    try:
        return json.loads(text)
    except RecursionError:  # cannot happen below the depth bound; kept as a last guard
        raise BoundError(f"{what} is nested too deeply") from None


def read_config_bytes(path: str | Path, what: str = "the file") -> bytes:
    """The bytes of a configuration file after the size check (never more than the bound is
    read). Raises OSError (missing, unreadable, a directory) or :class:`BoundError`."""
    path = Path(path)
    require_regular_input(path)  # a named pipe or a device would block or never end
    with path.open("rb") as f:
        data = f.read(MAX_CONFIG_BYTES + 1)
    check_size(max(len(data), _size(path)), MAX_CONFIG_BYTES, what)
    return data


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0
