"""Writing large numeric tables as text, in chunks, with progress on stderr."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TextIO

import numpy as np

from bpms.analysis.source import stderr_progress

CHUNK_ROWS = 10_000


def write_rows(f: TextIO, data: np.ndarray, fmt: str | Sequence[str], delimiter: str = ",",
               label: str = "writing") -> None:
    """``numpy.savetxt`` of ``data[N, M]`` in chunks of 10,000 rows; a progress line for
    tables above 30,000 rows (10 minutes at 50 Hz); none with an empty ``label``."""
    n = len(data)
    for lo in range(0, n, CHUNK_ROWS):
        hi = min(n, lo + CHUNK_ROWS)
        np.savetxt(f, data[lo:hi], fmt=fmt, delimiter=delimiter)
        if label:
            stderr_progress(label, hi, n)
