"""Progress lines: in place on a terminal; in a log or a pipe one plain line every 10 % or 5 s
(and the last), never a carriage return."""

from __future__ import annotations

import io

from bpms.progress import ProgressLine, report


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


def test_the_commands_progress_is_plain_lines_in_a_pipe(capsys):
    """What the analysis commands call per chunk of a recording above 30,000 frames: with
    stderr captured (not a terminal) it writes a few plain lines, never a carriage return."""
    from bpms.progress import stderr_progress

    for done in range(0, 186_001, 15_000):  # an hour at 50 Hz, in the door's 5-minute chunks
        stderr_progress("filtering trial.bpmsraw", min(done, 186_000), 186_000)
    stderr_progress("filtering trial.bpmsraw", 186_000, 186_000)
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert lines[-1] == "filtering trial.bpmsraw: 100% (186000/186000 frames)"
    assert 8 <= len(lines) <= 13, lines  # every 10 % (a chunk is 8 %), not every chunk
    stderr_progress("short", 10, 20_000)  # 6.7 minutes: no progress at all
    assert capsys.readouterr().err == ""
