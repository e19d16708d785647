"""Writing large numeric tables as text, in chunks, with progress on stderr."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from bpms.io.closing import Closing
from bpms.io.text_rows import RowFormat
from bpms.progress import stderr_progress

CHUNK_ROWS = 10_000
COUNT_DIGITS = 12  # room for a count patched in when a file is closed


def write_rows(f: TextIO, data: np.ndarray, fmt: str | Sequence[str], delimiter: str = ",",
               label: str = "writing") -> None:
    """The rows of ``data[N, M]`` as text (:class:`bpms.io.text_rows.RowFormat`: ``fmt`` as
    ``numpy.savetxt`` reads it, the same text) in chunks of 10,000 rows; a progress line for
    tables above 30,000 rows (10 minutes at 50 Hz); none with an empty ``label``."""
    data = np.asarray(data, dtype=np.float64)
    if data.ndim == 1:
        data = data.reshape(-1, 1)
    rows = RowFormat.parse(fmt, delimiter, data.shape[1])
    n = len(data)
    for lo in range(0, n, CHUNK_ROWS):
        hi = min(n, lo + CHUNK_ROWS)
        f.write(rows.text(data[lo:hi]))
        if label:
            stderr_progress(label, hi, n)


class TextWriter(Closing):
    """A text file written block by block (constant memory): UTF-8, ``\\n`` line ends, opened
    here, closed by :meth:`close` or at the end of a ``with`` block."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open(path, "w", encoding="utf-8", newline="\n")  # noqa: SIM115

    def _reserve_count(self, label: str) -> None:
        """Write ``label`` and room for a count (:data:`COUNT_DIGITS`, left-aligned, padded
        with spaces) that :meth:`_patch_count` fills in once the count is known."""
        self._count_label, self._count_at = label, self._file.tell()
        self._file.write(f"{label}{0:<{COUNT_DIGITS}d}")

    def _patch_count(self, n: int) -> None:
        """Write ``n`` into the room :meth:`_reserve_count` left (the file stays open)."""
        self._file.seek(self._count_at)
        self._file.write(f"{self._count_label}{n:<{COUNT_DIGITS}d}")

    def close(self) -> None:
        self._file.close()
