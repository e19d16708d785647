"""Numeric rows as text: the one writer of CSV and other delimited number tables (the
filtered file, ``bpms extract``, the MATLAB CSV, OpenSim and BVH motion rows).

:class:`RowFormat` writes the rows of a float64 array exactly as Python's ``%`` operator
writes each value (``"%.10g" % v``, ``"%.6f" % v``, ``"%d" % v``): the same text, byte for
byte, so a file reads back to the same numbers whichever way it was written. It does so a
block at a time with numpy instead of one value at a time:

- A value becomes its sign, integer part ``I`` and fraction digits ``F`` by exact float
  arithmetic. Powers of ten up to 1e22 are exact doubles and a product by one of them is
  correctly rounded, so ``rint(|v| * 10**k)`` is the correctly rounded decimal except when the
  product lands exactly on ``.5``; those ties are detected and left to Python.
- ``I`` and ``F`` become ASCII eight digits at a time in 64-bit integers (multiplications and
  shifts, one digit per byte); byte masks blank the leading zeros of ``I`` and, for ``%g``,
  the trailing zeros of ``F``. Every value fills a fixed cell of 32-bit words, blank bytes (0)
  where a shorter value has no character, and the blanks are dropped from the whole block at
  the end.
- The values that way does not cover (ties, infinities, numbers beyond 2**52, ``%g`` of
  numbers below 1e-13 or from 1e5 up) are written by Python's ``%`` one value at a time, in
  their cells, so the text is always what ``%`` writes. Every block, the live filtered file's
  few rows as a whole recording's, takes this one way.

Conversions: ``%.Pg`` (vectorised for P ≤ 10), ``%.Nf`` (N ≤ 13), ``%d``/``%i``; one
single-character separator between fields, ``\\n`` after each row.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np

_WORD = np.dtype("<u4")  # one cell word: 4 ASCII bytes, the first in the lowest byte
_U = np.uint64
_P10 = np.array([float(10 ** k) for k in range(23)])  # exact doubles
_MAX_EXACT = 2.0 ** 52  # below this a double holds every half-integer: ties are exact
_G_MAX_PRECISION = 10  # %g: I < 10**P and F × 10**k < 10**13 stay exact
_F_MAX_DECIMALS = 13  # %f: the fraction digits the vectorised path writes
#: Values formatted together (rows × columns): the work arrays stay in the processor's cache.
_CHUNK_VALUES = 1 << 16
_SPEC = re.compile(r"%(?:\.(\d+))?([gfdi])")
_BYTES_7F = _U(0x7F7F7F7F7F7F7F7F)
_BYTES_80 = _U(0x8080808080808080)
_ZERO_CHARS = _U(0x3030303030303030)
_NAN_WORD = _WORD.type(int.from_bytes(b"\0nan", "little"))  # after the separator
_SWAR_10K = _U(109_951_163)
_SWAR_LANES_32 = _U((10_000 << 32) - 1)
_SWAR_LANES_16 = _U((100 << 16) - 1)
_SWAR_LANES_8 = _U((10 << 8) - 1)


@dataclass(frozen=True)
class _Spec:
    kind: str  # "g", "f" or "d"
    precision: int
    text: str  # the conversion, for Python's %


def _parse_spec(text: str) -> _Spec:
    match = _SPEC.fullmatch(text)
    if match is None:
        raise ValueError(f"unsupported number format {text!r} (use %.Ng, %.Nf or %d)")
    digits, kind = match.groups()
    kind = "d" if kind == "i" else kind
    if kind == "d" and digits is not None:
        raise ValueError(f"unsupported number format {text!r} (use %d)")
    precision = 6 if digits is None and kind != "d" else int(digits or 0)
    if kind == "g":
        precision = max(precision, 1)
    return _Spec(kind, precision, text)


class RowFormat:
    """The text layout of a table's rows: one conversion per column (``specs``) and the
    single-character separator before each column after the first (``separators``)."""

    def __init__(self, specs: Sequence[str], separators: Sequence[str]) -> None:
        if not specs:
            raise ValueError("a row format needs at least one column")
        if len(separators) != len(specs) - 1:
            raise ValueError("one separator between each two columns")
        if any(len(s.encode("ascii")) != 1 for s in separators):
            raise ValueError("separators must be single ASCII characters")
        self.specs = [_parse_spec(s) for s in specs]
        self.separators = list(separators)
        seps = np.array([ord("\n")] + [ord(s) for s in separators], dtype=_WORD)
        by_spec: dict[_Spec, list[int]] = {}
        for col, spec in enumerate(self.specs):
            by_spec.setdefault(spec, []).append(col)
        self._groups = [_Group(spec, np.array(cols), seps[cols])
                        for spec, cols in by_spec.items()]

    @classmethod
    def parse(cls, fmt: str | Sequence[str], delimiter: str, columns: int) -> RowFormat:
        """As ``numpy.savetxt`` reads ``fmt``: one conversion for every column, one per
        column, or a whole row (``"%.6f\\t%.8f,%.8f"``: ``delimiter`` is then not used)."""
        if not isinstance(fmt, str):
            return cls(list(fmt), [delimiter] * (len(fmt) - 1))
        if _SPEC.fullmatch(fmt):
            return cls([fmt] * columns, [delimiter] * (columns - 1))
        texts = _SPEC.split(fmt)[0::3]  # split() yields text, precision, kind, text, ...
        if texts[0] or texts[-1]:
            raise ValueError(f"row format {fmt!r}: text before the first or after the last "
                             "conversion is not supported")
        return cls([m.group(0) for m in _SPEC.finditer(fmt)], texts[1:-1])

    @property
    def columns(self) -> int:
        return len(self.specs)

    def text(self, data: np.ndarray) -> str:
        """The rows of ``data[N, columns]``, each ending in ``\\n`` ("" for no rows)."""
        return self.ascii(data).decode("ascii")

    def ascii(self, data: np.ndarray) -> bytes:
        """:meth:`text` as ASCII bytes (for a file opened in binary mode)."""
        data = np.asarray(data, dtype=np.float64)
        if data.ndim == 1:  # as numpy.savetxt: one value per row
            data = data.reshape(-1, 1)
        n, ncols = data.shape
        if ncols != self.columns:
            raise ValueError(f"{ncols} columns for a row format of {self.columns}")
        if n == 0:
            return b""
        step = max(1, _CHUNK_VALUES // ncols)
        chunks = [self._chunk_bytes(data[lo:lo + step], first=lo == 0)
                  for lo in range(0, n, step)]
        chunks.append(b"\n")
        return b"".join(chunks)

    def _chunk_bytes(self, data: np.ndarray, first: bool) -> bytes:
        """The chunk's rows, each row starting with the newline that ends the one before
        (none before the very first)."""
        n = len(data)
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            cells = [group.cells(data) for group in self._groups]
        widths = np.zeros(self.columns, dtype=np.intp)
        for group, (words, _, _) in zip(self._groups, cells, strict=True):
            widths[group.cols] = len(words)
        offsets = np.concatenate([[0], np.cumsum(widths)])
        buf = np.zeros((n, int(offsets[-1])), dtype=_WORD)
        for group, (words, slow, texts) in zip(self._groups, cells, strict=True):
            group.place(buf, offsets, words, slow, texts)
        if first:
            buf.view(np.uint8)[0, 0] = 0  # no newline before the first row
        return buf.tobytes().translate(None, b"\0")


class _Group:
    """The columns of a row format that share one conversion."""

    def __init__(self, spec: _Spec, cols: np.ndarray, seps: np.ndarray) -> None:
        self.spec = spec
        self.cols = cols
        self.seps = seps
        # runs of consecutive columns: (first in the group, end in the group, first column)
        breaks = np.flatnonzero(np.diff(cols) != 1) + 1
        starts = np.concatenate([[0], breaks])
        ends = np.concatenate([breaks, [len(cols)]])
        self.runs = [(int(s), int(e), int(cols[s])) for s, e in zip(starts, ends, strict=True)]

    def cells(self, data: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, list[bytes]]:
        """(the words of every value, [n × c] flat; the values Python writes; their texts)."""
        values = data[:, self.cols]
        x = values.ravel()
        words, fast = _words(x, self.spec)
        slow = np.flatnonzero(~fast)
        texts = [(self.spec.text % v).encode("ascii") for v in x[slow].tolist()]
        if texts:  # room for the longest of them after the separator
            need = -(-(max(len(t) for t in texts) + 1) // 4)
            words += [np.zeros(len(x), _WORD)] * max(0, need - len(words))
        return words, slow, texts

    def place(self, buf: np.ndarray, offsets: np.ndarray, words: list[np.ndarray],
              slow: np.ndarray, texts: list[bytes]) -> None:
        n, c, w = len(buf), len(self.cols), len(words)
        for start, end, col in self.runs:
            view = buf[:, offsets[col]:offsets[col] + (end - start) * w]
            view = view.reshape(n, end - start, w)
            for k, word in enumerate(words):
                view[:, :, k] = word.reshape(n, c)[:, start:end]
            view[:, :, 0] |= self.seps[start:end]
        if texts:
            room = 4 * w
            row, at = np.divmod(slow, c)
            first = (row * buf.shape[1] + offsets[self.cols[at]]) * 4
            chars = buf.view(np.uint8).reshape(-1)
            cells = np.frombuffer(b"".join(t.rjust(len(t) + 1, b"\0").ljust(room, b"\0")
                                           for t in texts), np.uint8).reshape(-1, room)
            cells = cells.copy()
            cells[:, 0] = self.seps[at]
            chars[first[:, None] + np.arange(room)] = cells


# -- digits in 64-bit words ----------------------------------------------------------------
def _swar8(u: np.ndarray) -> np.ndarray:
    """``u`` (uint64, < 1e8) → its 8 digits (values 0..9), one per byte, the most
    significant in the lowest byte (the first character of the text)."""
    hi = (u * _SWAR_10K) >> _U(40)  # u // 10_000, exact below 1e8
    v = (u << _U(32)) - hi * _SWAR_LANES_32  # hi | (u - 10_000 hi) << 32: two 4-digit lanes
    h = ((v * _U(5243)) >> _U(19)) & _U(0x0000007F0000007F)  # // 100 in each lane
    v = (v << _U(16)) - h * _SWAR_LANES_16  # h | (v - 100 h) << 16: four 2-digit lanes
    h = ((v * _U(103)) >> _U(10)) & _U(0x000F000F000F000F)  # // 10 in each lane
    return (v << _U(8)) - h * _SWAR_LANES_8  # h | (v - 10 h) << 8: one digit a byte


def _nonzero_bytes(t: np.ndarray) -> np.ndarray:
    """0xFF in each byte of ``t`` (bytes < 0x80) that is not 0, else 0x00."""
    return (((t + _BYTES_7F) & _BYTES_80) >> _U(7)) * _U(0xFF)


def _smear_up(t: np.ndarray) -> np.ndarray:
    """Byte k becomes the OR of bytes 0..k (a digit seen at or before k)."""
    t = t | (t << _U(8))
    t |= t << _U(16)
    t |= t << _U(32)
    return t


def _smear_down(t: np.ndarray) -> np.ndarray:
    """Byte k becomes the OR of bytes k..7 (a digit seen at or after k)."""
    t = t | (t >> _U(8))
    t |= t >> _U(16)
    t |= t >> _U(32)
    return t


def _halves(words: np.ndarray) -> list[np.ndarray]:
    """uint64 words → their two 32-bit halves, first characters first."""
    pairs = words.astype("<u8", copy=False).view(_WORD).reshape(-1, 2)
    return [pairs[:, 0], pairs[:, 1]]


# -- the words of one group's values ------------------------------------------------------------
def _words(x: np.ndarray, spec: _Spec) -> tuple[list[np.ndarray], np.ndarray]:
    """The cell words of the values ``x`` (byte 0 of the first left for the separator), and
    which values they hold (the others: Python)."""
    if spec.kind == "d" or (spec.kind == "f" and spec.precision == 0):
        small = _small_integers(x, spec)
        if small is not None:
            return [small], np.ones(len(x), bool)
    nan = np.isnan(x) if spec.kind != "d" else None
    if spec.kind == "g" and spec.precision <= _G_MAX_PRECISION:
        assert nan is not None
        return _general_words(x, spec.precision, nan)
    if spec.kind == "f" and spec.precision <= _F_MAX_DECIMALS:
        fast, neg, int_part, frac13 = _fixed_parts(x, spec.precision)
    elif spec.kind == "d":
        a = np.abs(x)
        fast = a < _MAX_EXACT
        int_part = np.floor(a)
        neg = (x < 0) & (int_part > 0) & fast  # "%d" % -0.5 is "0"
        frac13 = None
    else:  # more digits than the vectorised path holds: Python writes every value
        return [np.zeros(len(x), _WORD)], np.zeros(len(x), bool)
    words = _integer_words(int_part, fast, neg, nan)
    if frac13 is not None:
        fraction = _fixed_fraction_words(frac13, spec.precision)
        if nan is not None:
            for word in fraction:
                word[nan] = 0
        words += [w for w in fraction if w.any()]  # a word no value needs is left out
    return words, fast if nan is None else fast | nan


def _small_integers(x: np.ndarray, spec: _Spec) -> np.ndarray | None:
    """Flags and counts 0..9 (and nan for %.0f): one word each; None if others occur."""
    digit = (x >= 0) & (x <= 9) & (x == np.floor(x))
    nan = None
    if spec.kind == "f":
        digit &= ~np.signbit(x)  # "%.0f" % -0.0 is "-0"
        nan = np.isnan(x)
        digit |= nan
    if not digit.all():
        return None
    word = (np.nan_to_num(x).astype(_WORD) + _WORD.type(ord("0"))) << _WORD.type(8)
    if nan is not None and nan.any():
        word[nan] = _NAN_WORD
    return word


@cache
def _top_digits() -> np.ndarray:
    """d0 d1 of the ten digits, from m // 1e8 (0..99; 128 entries), at bytes 2 and 3."""
    top = np.arange(128, dtype=np.uint64) % np.uint64(100)
    return ((top // np.uint64(10)) << np.uint64(16)) | ((top % np.uint64(10)) << np.uint64(24))


@cache
def _zero_points() -> np.ndarray:
    """For X = -4..0 (index X + 4): "0.000", "0.00", "0.0", "0." from byte 2 on, or nothing
    (X ≥ 0: the point goes after the integer digits)."""
    out = np.zeros(5, np.uint64)
    for k, text in enumerate([b"0.000", b"0.00", b"0.0", b"0."]):
        out[k] = int.from_bytes(b"\0\0" + text, "little")
    return out


@cache
def _general_scales(precision: int) -> tuple[np.ndarray, np.ndarray]:
    """Per biased binary exponent b of a double (its bits 52..62): 10**(P-1-X) and X, for X
    the largest decimal exponent with 10**X ≤ 2**(b-1022) (a value with that b has exponent
    X or X-1). NaN where the vectorised path does not go (zero, subnormal, |v| < 1e-13,
    |v| ≥ 1e7 or beyond 10**P, infinity, nan).

    X = ⌊(b − 1022) · log10 2⌋ in floating point is exact: 2**e is a power of ten only at
    e = 0, and over this range e · log10 2 is never closer than 1e-5 to an integer, far beyond
    the product's rounding (tests/test_text_rows.py checks every b with exact fractions)."""
    b = np.arange(2048)
    exps = np.floor((b - 1022) * np.log10(2.0)).astype(np.int64)
    exps[[0, 2047]] = 0
    power = precision - 1 - exps
    ok = ((exps - 1 >= -13) & (exps <= min(precision, 7)) & (power >= 0) & (power <= 21)
          & (b >= 1) & (b <= 2046))
    scales = np.where(ok, 10.0 ** np.clip(power, 0, 21), np.nan)
    return scales, exps


_POINT = _U(ord(".") << 16)
_DIGITS_LO = _U(0x3030303030300000)  # '0' added to bytes 2..7 (d0..d5)
_DIGITS_HI = _U(0x30303030)  # and to bytes 0..3 of the second word (d6..d9)
_E_MINUS = int.from_bytes(b"e-", "little")
_MINUS_HEAD = _U(ord("-") << 8)


def _general_words(x: np.ndarray, precision: int,
                   nan: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """``%.Pg``: m = the P significant digits, rint(|x| × 10**(P-1-X)), written as its digits
    d0..d9 with the point placed by X: "d0..dX.dX+1.." (0 ≤ X ≤ 4), "0.0d0.." (-4 ≤ X < 0),
    "d0.d1..e-XX" (-13 ≤ X < -4); trailing zeros after the point, and a bare point, blank.
    A cell is 16 bytes (separator, sign, up to 14 characters) and a fifth word when a value
    needs it: the 15th character of "0.000d0..d9", or "e-XX"."""
    a = np.abs(x)
    low, high = 10.0 ** (precision - 1), 10.0 ** precision
    scales, exps = _general_scales(precision)
    b = a.view(np.int64) >> 52
    scale = scales.take(b)
    p = a * scale
    down = p < low  # the decimal exponent is one lower
    scale *= 1.0 + 9.0 * down
    p = a * scale
    m = np.rint(p)
    fast = (m >= low) & (np.abs(p - m) != 0.5)  # nan, inf: scale and m are nan
    x_exp = exps.take(b) - down
    carry = m >= high  # 9.9999999996 → 10: one more integer digit
    if carry.any():
        m[carry] = low
        x_exp[carry] += 1
    fast &= x_exp <= min(4, precision - 1)  # from 1e5 on: Python (the point would leave
    # the first word)
    zero = a == 0
    if zero.any():
        m[zero] = 0.0
        x_exp[zero] = 0
        fast |= zero
    expo = x_exp < -4
    x_exp *= ~expo  # exponent notation: the point after the first digit
    # the ten digits from byte 2 on (bytes 0, 1: separator and sign): d0 d1 from m // 1e8,
    # d2..d9 from the rest
    if precision < 10:
        m *= _P10[10 - precision]
    top = np.floor(m / 1e8)  # exact: m < 2**53, and 1e8 is exact
    low8 = _swar8((m - top * 1e8).astype(_U))
    digits_lo = _top_digits().take(top.astype(np.intp) & 127) | (low8 << _U(32))
    digits_hi = low8 >> _U(32)  # d6..d9
    split = (np.maximum(x_exp + 1, 0) << 3).astype(_U)  # integer digits, bits
    int_mask = ((_U(1) << split) - _U(1)) << _U(16)
    text_lo = digits_lo + _DIGITS_LO
    text_hi = digits_hi + _DIGITS_HI
    zeros = np.flatnonzero(digits_hi < _U(1 << 24))  # d9 is 0: trailing zeros to blank
    if len(zeros):
        low, high_ = digits_lo[zeros], digits_hi[zeros]
        text_hi[zeros] &= _nonzero_bytes(_smear_down(high_))
        keep = _nonzero_bytes(_smear_down(low | ((high_ > 0).astype(_U) << _U(56))))
        text_lo[zeros] &= keep | int_mask[zeros]
    # open the gap for "." (one byte) or "0.000" (1 - X bytes) before the fraction digits
    gap = ((1 - np.minimum(x_exp, 0)) << 3).astype(_U)
    kept = text_lo & int_mask
    moved = text_lo ^ kept
    point = x_exp >= 0  # a digit after the point unless d9 was 0 and they all were
    if len(zeros):
        point[zeros] &= (moved[zeros] | text_hi[zeros]) > 0
    prefix = (point.astype(_U) * _POINT) << split
    prefix |= _zero_points().take(np.minimum(x_exp, 0) + 4, mode="clip")
    spill = (text_hi >> (_U(64) - gap)).astype(_WORD)  # the 15th character of "0.000d0.."
    text_hi = (text_hi << gap) | (moved >> (_U(64) - gap))
    text_lo = kept | (moved << gap) | prefix | np.signbit(x) * _MINUS_HEAD
    words = [*_halves(text_lo), *_halves(text_hi), spill]
    expo &= fast
    if expo.any():
        at = np.flatnonzero(expo)
        power = -exps[b[at]] + down[at] - carry[at]  # -X, 5..13
        tens = power // 10
        spill[at] |= (_E_MINUS | ((tens + ord("0")) << 16)
                      | ((power - tens * 10 + ord("0")) << 24)).astype(_WORD)
    if nan.any():
        for word in words[1:]:
            word[nan] = 0
        words[0][nan] = _NAN_WORD
    return [w for k, w in enumerate(words) if k == 0 or w.any()], fast | nan


def _fixed_parts(x: np.ndarray, decimals: int) -> tuple:
    """``%.Nf``: m = rint(|x| × 10**N), I = m // 10**N, F = the rest, shifted to 13
    places."""
    a = np.abs(x)
    p = a * _P10[decimals]
    m = np.rint(p)
    fast = (p < _MAX_EXACT) & (np.abs(p - m) != 0.5)
    int_part = np.floor(m / _P10[decimals])
    frac13 = ((m - int_part * _P10[decimals]) * _P10[13 - decimals]) if decimals else None
    return fast, np.signbit(x) & fast, int_part, frac13


def _integer_words(int_part: np.ndarray, fast: np.ndarray, neg: np.ndarray,
                   nan: np.ndarray | None) -> list[np.ndarray]:
    """The separator's byte, the sign and the integer digits (leading zeros blank, the units digit
    always written), right-aligned in 8-digit words; "nan" for nan. Values not ``fast`` get
    anything (Python overwrites them)."""
    largest = float(np.max(int_part, initial=0.0, where=fast))
    digits = len(str(int(largest)))
    u = int_part.astype(_U)
    head = neg.astype(_U) * _MINUS_HEAD
    if digits <= 2:  # one word: separator, sign, two digits
        tens = (u * _U(103)) >> _U(10)
        ones = u - tens * _U(10)
        word = head | (((tens + _U(ord("0"))) * (tens > 0)) << _U(16))
        word |= (ones + _U(ord("0"))) << _U(24)
        if nan is not None and nan.any():
            word[nan] = _NAN_WORD
        return [word.astype(_WORD)]
    groups = -(-(digits + 2) // 8)  # 8-digit words; the first keeps 2 bytes for sep, sign
    chunks = []
    rest = u
    for k in range(groups - 1, 0, -1):
        top = rest // _U(10 ** (8 * k))
        chunks.append(top)
        rest = rest - top * _U(10 ** (8 * k))
    chunks.append(rest)
    words = []
    seen = np.zeros(len(u), _U)
    for k, chunk in enumerate(chunks):
        d = _swar8(chunk)
        t = _smear_up(d | seen)
        if k == len(chunks) - 1:
            t |= _U(1) << _U(56)  # the units digit
        word = (d + _ZERO_CHARS) & _nonzero_bytes(t)
        seen = seen | (chunk > 0).astype(_U)
        words.append(word)
    words[0] |= head
    if nan is not None and nan.any():
        for word in words:
            word[nan] = 0
        words[0][nan] = _NAN_WORD
    return [half for word in words for half in _halves(word)]


def _fraction_digits(frac13: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 13 fraction digits: f1..f5 in bytes 3..7 of the first word, f6..f13 in the
    second (digit values)."""
    u = frac13.astype(_U)
    hi = u // _U(100_000_000)
    return _swar8(hi), _swar8(u - hi * _U(100_000_000))


_FIRST_ZEROS = _U(0x3030303030000000)  # '0' added to bytes 3..7 (f1..f5)


def _fixed_fraction_words(frac13: np.ndarray, decimals: int) -> list[np.ndarray]:
    """%.Nf: the point and exactly N fraction digits."""
    a_digits, b_digits = _fraction_digits(frac13)
    a_keep = bytes([0, 0, 0xFF] + [0xFF if k < decimals else 0 for k in range(5)])
    b_keep = bytes([0xFF if 5 + k < decimals else 0 for k in range(8)])
    first = ((a_digits + _FIRST_ZEROS) | _POINT) & _U(int.from_bytes(a_keep, "little"))
    words = _halves(first)
    if decimals > 5:
        words += _halves((b_digits + _ZERO_CHARS) & _U(int.from_bytes(b_keep, "little")))
    return words
