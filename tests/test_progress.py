"""Progress lines: in place on a terminal; in a log or a pipe one plain line every 10 % or 5 s
(and the last), never a carriage return."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

from bpms.progress import ProgressLine, report

ROOT = Path(__file__).resolve().parents[1]


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_a_pipe_gets_a_line_every_ten_percent_and_the_last():
    out = io.StringIO()
    line = ProgressLine(1000, out, clock=Clock())  # the clock never moves: percent alone
    for done in range(0, 1001, 7):  # 143 updates, the last 994
        line.update(done, f"job {done}")
    line.update(1000, "job 1000")
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue()
    # 0 %, then each crossing of a further 10 %, then the final line
    assert lines[0] == "job 0" and lines[-1] == "job 1000"
    percents = [int(x.split()[1]) // 100 for x in lines]
    assert percents == list(range(11)), lines  # 0, 105, 203, ... 903, 1000


def test_a_pipe_gets_a_line_every_five_seconds_when_the_work_is_slow():
    out, clock = io.StringIO(), Clock()
    line = ProgressLine(10_000, out, clock=clock)
    shown = []
    for done in range(0, 100):  # 1 % in all, one update a second
        clock.t = float(done)
        if line.update(done, str(done)):
            shown.append(done)
    assert shown == list(range(0, 100, 5))


def test_a_terminal_sees_every_update_in_place():
    out = Terminal()
    line = ProgressLine(10, out, clock=Clock())
    for done in range(11):
        line.update(done, f"{done}/10")
    text = out.getvalue()
    assert text.count("\r") == 11 and text.endswith("\r10/10\n") and text.count("\n") == 1


def test_report_keeps_one_line_per_label_and_starts_again_for_the_next_job():
    out = io.StringIO()
    for _ in range(2):  # two jobs of the same label one after the other
        for done in range(0, 50_001, 1000):
            report("filtering", done, 50_000, out)
    lines = out.getvalue().splitlines()
    assert lines.count("filtering: 100% (50000/50000 frames)") == 2
    assert lines.count("filtering:   0% (0/50000 frames)") == 2
    assert len(lines) == 2 * 11


def test_a_long_export_writes_plain_progress_lines_to_a_pipe(tmp_path):
    """A recording above 30,000 frames (10 min): the command's stderr is a pipe, so its
    progress is a few plain lines, not one line full of carriage returns."""
    from bpms.firmware.sim.session import simulate

    raw = simulate(620.0, seed=2, noise=False).save_raw(tmp_path / "Raw_long.bpmsraw")
    done = subprocess.run([sys.executable, "-m", "bpms", "export", "matlab", str(raw), "-o",
                           str(tmp_path / "long")], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    assert "\r" not in done.stderr
    progress = [ln for ln in done.stderr.splitlines() if "% (" in ln]
    assert any(ln.endswith("(31000/31000 frames)") for ln in progress), progress
    assert 3 <= len(progress) <= 30, progress
