"""The one writer of numeric text rows (bpms.io.text_rows) against Python's own % formatting:
the same text, byte for byte, and so the same numbers read back, on hand-chosen tricky values
and on random values of every magnitude, in blocks of one row to thousands (the live filtered
file writes a few rows at a time, a recording thousands)."""

from __future__ import annotations

import io

import numpy as np
import pytest

from bpms.io.filtered_file.reader import read_filtered
from bpms.io.filtered_file.writer import FilteredWriter
from bpms.io.text_rows import RowFormat

#: Values chosen to break a formatter: signed zeros, non-finite values, the extremes of the
#: double range, decimal ties and near-ties of the 10th significant digit, carries into a new
#: digit (9.9999999995 → 10), the borders of positional and exponent notation (1e-4, 1e10),
#: values just below those borders, and what a filtered file holds (angles, times, flags).
TRICKY = [
    0.0, -0.0, np.nan, -np.nan, np.inf, -np.inf, 1e-300, -1e-300, 5e-324, 2.2250738585072014e-308,
    1e20, -1e20, 1.7976931348623157e308, 0.1, 0.2, 0.3, 1 / 3, 2 / 3, 3.14159265358979,
    -3.14159265358979, 2.718281828459045, 0.5, 1.5, 2.5, -0.5, 0.125, 0.0625, 1.25,
    9.9999999995, 9.99999999949, 9.9999999996, 99999.999995, 0.99999999995, 1.0000000005,
    1.00000000005, 1.0000000015, 1.2345678905, 1.2345678915, 123456.78905, 0.00012345678905,
    1e-4, 9.99999999995e-5, 0.0001 * (1 - 2 ** -52), 1e-5, 1.5e-5, 1.23456789e-5, 1e-13,
    9.99999999999e-14, 1e-14, 1e9, 999999999.5, 1e10, 9999999999.4, 9999999999.5, 1e7,
    9999999.9999, 123456789012.0, 2.0 ** 52, 2.0 ** 53, 2.0 ** 52 - 0.5, 4503599627370495.5,
    1700000000.0000005, 1700000000.1234565, 1700000000.123456, 0.02 * 3, 0.02 * 180_000,
    1.0, 2.0, 9.0, 10.0, 100.0, 180.0, -180.0, np.pi / 2, -np.pi, np.degrees(1.0),
]
FORMATS = ["%.10g", "%.6f", "%.0f", "%d", "%.5f", "%.8f", "%.1f", "%.3g", "%g", "%.12g",
           "%.15g", "%.2f", "%.13f", "%.16f"]


def python_rows(data: np.ndarray, specs: list[str], seps: list[str]) -> str:
    out = []
    for row in data.tolist():
        cells = [spec % v for spec, v in zip(specs, row, strict=True)]
        out.append(cells[0] + "".join(s + c for s, c in zip(seps, cells[1:], strict=True)))
    return "".join(line + "\n" for line in out)


def finite_for(spec: str, values: np.ndarray) -> np.ndarray:
    return values[np.isfinite(values)] if spec == "%d" else values  # "%d" % nan raises


@pytest.mark.parametrize("spec", FORMATS)
@pytest.mark.parametrize("rows", [1, 3, 2000])  # a live batch to a recording's block
def test_tricky_values_are_written_as_python_writes_them(spec, rows):
    values = finite_for(spec, np.array(TRICKY))
    data = np.resize(values, (rows, len(values)))
    fmt = RowFormat([spec] * data.shape[1], [","] * (data.shape[1] - 1))
    assert fmt.text(data) == python_rows(data, [spec] * data.shape[1],
                                         [","] * (data.shape[1] - 1))


def test_values_read_back_as_ten_significant_digits():
    """What the filtered file promises (docs/filtered-file.md): each value reads back as
    Python's own float(format(v, '.10g'))."""
    values = np.array(TRICKY)
    data = np.resize(values, (100, len(values)))
    text = RowFormat(["%.10g"] * len(values), [","] * (len(values) - 1)).text(data)
    got = np.array([[float(c) for c in line.split(",")] for line in text.splitlines()])
    want = np.array([[float(format(v, ".10g")) for v in row] for row in data.tolist()])
    np.testing.assert_array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))


@pytest.mark.parametrize("spec", ["%.10g", "%.6f", "%.0f", "%d", "%.5f", "%.8f", "%g"])
def test_random_values_of_every_magnitude(spec):
    rng = np.random.default_rng(24)
    n = 12_000
    pools = [
        rng.normal(size=n) * 1.5,  # angles, rad
        rng.normal(size=n) * 10.0 ** rng.integers(-15, 17, n),  # every decade
        rng.integers(0, 2 ** 62, n, dtype=np.uint64).view(np.float64),  # any bit pattern
        np.round(rng.normal(size=n) * 1e4) / 10.0 ** rng.integers(0, 7, n),  # short decimals
        (rng.integers(0, 2 ** 30, n) + 0.5) / 10.0 ** rng.integers(0, 8, n),  # ties
        1.7e9 + rng.random(n) * 1e6,  # host times
    ]
    for pool in pools:
        pool = finite_for(spec, pool)
        pool = pool[: len(pool) // 6 * 6].reshape(-1, 6)
        fmt = RowFormat([spec] * 6, [","] * 5)
        assert fmt.text(pool) == python_rows(pool, [spec] * 6, [","] * 5)


def test_mixed_columns_separators_and_templates():
    rng = np.random.default_rng(5)
    specs = ["%.10g", "%.6f", "%d"] + ["%.10g"] * 20 + ["%.0f"] * 8
    data = np.column_stack([np.arange(400) * 0.02, 1.7e9 + np.arange(400) * 0.02,
                            rng.integers(0, 2, 400), rng.normal(size=(400, 20)),
                            rng.integers(0, 2, (400, 8))])
    data[7, 5] = np.nan
    data[9, 25] = np.nan  # a nan flag: not a 0/1 tail any more
    for rows in (data[:10], data):
        fmt = RowFormat(specs, [","] * (len(specs) - 1))
        assert fmt.text(rows) == python_rows(rows, specs, [","] * (len(specs) - 1))
    template = "%.6f\t%.8f,%.8f,%.8f,%.8f\t%.8f,%.8f,%.8f,%.8f"
    quats = rng.normal(size=(3000, 9))
    assert RowFormat.parse(template, " ", 9).text(quats) == "".join(
        (template % tuple(r)) + "\n" for r in quats.tolist())
    assert RowFormat.parse("%.5f", " ", 3).text(quats[:, :3]) == python_rows(
        quats[:, :3], ["%.5f"] * 3, [" "] * 2)
    assert RowFormat.parse("%.1f", ",", 1).text(np.arange(3.0)) == "0.0\n1.0\n2.0\n"
    assert RowFormat(["%.10g"], []).text(np.zeros((0, 1))) == ""
    with pytest.raises(ValueError, match="unsupported number format"):
        RowFormat(["%5.2e"], [])
    with pytest.raises(ValueError, match="single ASCII"):
        RowFormat(["%d", "%d"], [", "])


def test_filtered_file_reads_back_what_python_formatting_gives(tmp_path):
    """A filtered file written in one block and live-sized blocks of ten rows: the values read
    back are float(format(v, '.10g')), the host times float('%.6f' % t), the flags 0/1."""
    rng = np.random.default_rng(9)
    n = 3000
    euler = rng.normal(size=(n, 18, 3))
    euler[::37] *= 1e-5  # exponent notation
    euler[5, 3, 1] = np.nan
    host = 1.7e9 + np.arange(n) * 0.02 + rng.random(n) * 1e-3
    flags = (rng.random((n, 18)) < 0.1).astype(float)
    t = np.arange(n) * 0.02
    for name, step in (("block.csv", n), ("live.csv", 10)):
        path = tmp_path / name
        with FilteredWriter(path, groups=["euler", "mag_disturbed"]) as w:
            for lo in range(0, n, step):
                w.write_block(t[lo:lo + step], euler[lo:lo + step], host_time=host[lo:lo + step],
                              mag_disturbed=flags[lo:lo + step])
        back = read_filtered(path)
        want = np.array([float(format(v, ".10g")) for v in euler.ravel()]).reshape(euler.shape)
        np.testing.assert_array_equal(back.euler, want)
        np.testing.assert_array_equal(back.host_time, [float(f"{h:.6f}") for h in host])
        np.testing.assert_array_equal(back.groups["mag_disturbed"], flags)
    assert (tmp_path / "block.csv").read_bytes() == (tmp_path / "live.csv").read_bytes()


def test_a_text_stream_receives_text():
    out = io.StringIO()
    with FilteredWriter(out) as w:
        w.write_block(np.arange(3) * 0.02, np.zeros((3, 18, 3)))
    assert out.getvalue().splitlines()[-1].startswith("0.04,nan,0,0,0,")


@pytest.mark.parametrize("precision", [1, 6, 10, 15, 17])
def test_decimal_exponent_table_is_exact(precision):
    """The %g path's table of decimal exponents per binary exponent, computed in floating
    point, equals the one computed with exact fractions: X the largest with 10**X ≤ 2**e."""
    from fractions import Fraction

    from bpms.io.text_rows import _general_scales

    scales, exps = _general_scales(precision)
    for b in range(1, 2047):
        e = b - 1022
        bound = Fraction(2) ** e
        x = 0
        while Fraction(10) ** (x + 1) <= bound:
            x += 1
        while Fraction(10) ** x > bound:
            x -= 1
        assert exps[b] == x, b
        power = precision - 1 - x
        usable = x - 1 >= -13 and x <= min(precision, 7) and 0 <= power <= 21
        assert (scales[b] == 10.0 ** power) if usable else np.isnan(scales[b]), b
    assert np.isnan(scales[[0, 2047]]).all()
