"""Bounds every reader checks before it parses (docs/raw-format.md, docs/configuration.md).

A file is input from anyone: a header that claims 4 GB, a 200 MB header or 200,000 nested
``[`` must give a one-line refusal, not a ``MemoryError`` or a ``RecursionError`` traceback.
So, before parsing:

- a recording's header (raw JSON header, filtered ``#`` lines) is at most
  :data:`MAX_HEADER_BYTES` (16 MiB; a real one is a few kB);
- a configuration file (``options.toml``, ``Calib.cfg``, ``Calib.json``) is at most
  :data:`MAX_CONFIG_BYTES` (1 MiB; a real one is under 30 kB);
- JSON nests at most :data:`MAX_JSON_DEPTH` levels (a real header nests 4).

The depth is measured without parsing: strings are blanked out, then the brackets are
counted in one vectorised pass, so a 16 MiB text costs a few tens of ms.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

MAX_HEADER_BYTES = 16 * 1024 * 1024
MAX_CONFIG_BYTES = 1024 * 1024
MAX_JSON_DEPTH = 64

_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")


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
    never shallower, than it is."""
    brackets = _NOT_BRACKET.sub("", _STRING.sub('""', text))
    if not brackets:
        return 0
    codes = np.frombuffer(brackets.encode("ascii"), np.uint8)
    step = np.isin(codes, (0x5B, 0x7B)).astype(np.int32) - np.isin(codes, (0x5D, 0x7D))
    return int(np.cumsum(step).max(initial=0))


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
    with path.open("rb") as f:
        data = f.read(MAX_CONFIG_BYTES + 1)
    check_size(max(len(data), _size(path)), MAX_CONFIG_BYTES, what)
    return data


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0
