"""Live equals batch, byte for byte (issue 46.4): the filtered file a live session writes beside
its raw recording and the file ``bpms filter --joints`` writes from that raw recording are the
same bytes, header lines included.

Lines allowed to differ: those that state a clock time (:data:`CLOCK_TIME_LINES`). The filtered
file's header has none today (``host_time_s`` is a column, taken from the raw file's own
arrival times in both), so the whole file must match."""

from __future__ import annotations

import subprocess
import sys

import pytest
from test_live_path import BurstThenQuiet
from waiting import wait_until

from bpms.firmware.sim.session import simulate
from bpms.io.frames import FRAME_SIZE
from bpms.pipeline.session import LiveSession

#: Header keys (``# key: value``) that state a wall-clock time and may differ. None today.
CLOCK_TIME_LINES: tuple[str, ...] = ()


def _comparable(text: bytes) -> bytes:
    keep = [line for line in text.split(b"\n")
            if not any(line.startswith(f"# {key}:".encode()) for key in CLOCK_TIME_LINES)]
    return b"\n".join(keep)


@pytest.mark.parametrize("degrees", [False, True])
def test_live_filtered_file_equals_bpms_filter_of_its_raw_file(tmp_path, degrees,
                                                              deadline_scale):
    n = 130  # two full write batches and a part one
    rec = simulate(duration_s=n / 50 + 1.0, seed=5)
    session = LiveSession(BurstThenQuiet(rec.frames[:n * FRAME_SIZE]), recording_dir=tmp_path)
    status = session.start_logging(raw=True, filtered=True, name="same", degrees=degrees)
    session.start()
    try:
        assert wait_until(lambda: status.filtered_rows == n and status.raw_records == n)
    finally:
        session.stop()
    batch = tmp_path / "batch.csv"
    args = [sys.executable, "-m", "bpms", "filter", str(status.raw_path), "--joints",
            "-o", str(batch)] + (["--degrees"] if degrees else [])
    done = subprocess.run(args, capture_output=True, text=True, timeout=120 * deadline_scale)
    assert done.returncode == 0, done.stderr
    live = status.filtered_path.read_bytes()
    offline = batch.read_bytes()
    live_lines, batch_lines = live.split(b"\n"), offline.split(b"\n")
    header = [line for line in batch_lines if line.startswith(b"#")]
    assert [line for line in live_lines if line.startswith(b"#")] == header
    assert b"# source: " + status.raw_path.name.encode() in header
    assert len(live_lines) == len(batch_lines) == len(header) + 1 + n + 1  # names, rows, ""
    assert _comparable(live) == _comparable(offline)
