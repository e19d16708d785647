"""Hostile-input corpus: damaged recordings and absurd configurations through every command
that reads one (issue 26.7), run in one interpreter.

    python tools/hostile_corpus.py                 # build in a temporary folder, run, print
    python tools/hostile_corpus.py --keep DIR      # build into DIR and keep it
    python tools/hostile_corpus.py --only filter   # one command

The corpus (tools/corpus_cases.py builds it) holds, beside an intact 6 s recording of the
simulated suit (the control): truncations, random bytes, inserted and deleted bytes, lost
record markers, a header nested 200,000 levels deep, a 200 MB header, a header of escaped
quotes, empty files, directories, a named pipe, absurd headers, legacy pickles whose
``__reduce__`` would run code or whose times are 400-digit integers, absurd calibration and
options files, and format-version-2 recordings with every event kind a live session writes
(tools/corpus_events.py), damaged in their events and frames (issue 43.6).

Every case knows what a correct command does with it, from how it was built (not from the
code under test): a *refused* input gives exit 2 with a one-line ``bpms CMD: ...`` message;
an input that still holds frames gives exactly that many frames (3 deleted bytes cost one
frame and keep its slot, docs/raw-format.md), each at its time index × 0.02 s; an absurd
configuration gives a warning naming the bad value and the factory fallback. Commands that
print no frame count (rom, track, drift) must give the same output as for the recording
``bpms.io.rawfile.read_raw`` reads from the damaged file, written back intact. A traceback
is always a failure; so is a command still running after :data:`HANG_S` (an alarm ends it),
exit 0 with wrong output or without an output it was asked for, and a pickle that ran code.
The closing table (tools/corpus_table.py) counts the runs by damage class and what went
wrong.

Commands run in this process through :func:`bpms.cli.main` (stdout and stderr captured), so
the whole corpus costs seconds, not a process start per case. tests/test_hostile_corpus.py
runs every (command, case) pair; bench/hostile_input.py prints the totals.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shutil
import socket
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for _where in (REPO, Path(__file__).resolve().parent):
    if str(_where) not in sys.path:
        sys.path.insert(0, str(_where))

from corpus_cases import (  # noqa: E402  (tools/ is not a package)
    BY_NAME,
    CASES,
    CONFIG_CASES,
    MARKER,
    N_SLOTS,  # noqa: F401  (tests/test_hostile_corpus.py reads it here)
    RECORDING_CASES,
    Case,
    CorpusFiles,
)
from corpus_table import table  # noqa: E402

R = "recording"


#: Commands that read a recording; "export-bvh" is ``bpms export bvh`` and so on.
RECORDING_COMMANDS = ("filter", "export-matlab", "export-bvh", "export-opensim", "rom",
                      "track", "drift", "convert", "extract", "batch", "replay")
#: Commands given each configuration case: (command, takes calibration, takes options).
CONFIG_COMMANDS = {
    "filter": (True, True), "export-matlab": (True, True), "rom": (True, True),
    "track": (True, True), "drift": (True, True), "convert": (True, True),
    "extract": (True, False), "batch": (False, True), "replay": (False, True),
    "config": (True, True), "record": (True, True), "calibrate": (True, False),
}
#: ``bpms record --sim`` runs a live session for a second: one configuration per damage class.
RECORD_CASES = ("calib_gravity_tiny", "calib_random", "calib_empty", "calib_directory",
                "options_gain_huge", "options_nested", "options_huge")
#: (command, case) pairs with nothing to check: ``bpms config`` shows the Calib.cfg in force and
#: does not read the ellipsoid companion (Calib.json), which the filter reads.
PAIRS_NOT_APPLICABLE: frozenset[tuple[str, str]] = frozenset(
    {("config", "calib_json_nested"), ("config", "calib_json_quotes")})


#: Pairs that failed while the analysis commands read ``.bpmsraw`` through a second reader
#: (fixed 348-byte steps: no resynchronisation, damaged records dropped instead of kept, no
#: error for a recording without a valid frame). Since issue 25 every door reads through the
#: one reader (bpms/io/raw_reader.py) and they pass; they stay listed because ``batch`` (one
#: case per damage class otherwise) runs each of them.
_DOOR = ("filter", "export-matlab", "export-bvh", "export-opensim", "rom", "extract", "batch")
_NO_FRAME = ("export-matlab", "export-bvh", "export-opensim", "track", "convert", "extract",
             "replay")
ONE_READER_PAIRS: frozenset[tuple[str, str]] = frozenset(
    {(cmd, "deleted_3_bytes") for cmd in (*_DOOR, "convert")}
    | {(cmd, case) for case in ("inserted_5_bytes", "markers_lost_5") for cmd in _DOOR}
    | {(cmd, case) for case in ("markers_lost_all", "random_body") for cmd in _NO_FRAME})


#: Commands that cost a second or more per run (batch draws its summary figure): given one
#: case per damage class and kind only.
REPRESENTATIVES_ONLY = frozenset({"batch"})


def _representatives(cases: tuple[Case, ...]) -> set[str]:
    seen: dict[tuple[str, str], str] = {}
    for c in cases:
        seen.setdefault((c.kind, c.damage), c.name)
    return set(seen.values())


def pairs() -> list[tuple[str, Case]]:
    """Every (command, case) pair the corpus runs."""
    few = _representatives(CASES)
    out = [(cmd, c) for c in RECORDING_CASES for cmd in RECORDING_COMMANDS]
    for c in CONFIG_CASES:
        for cmd, (cal, opt) in CONFIG_COMMANDS.items():
            if cmd == "record" and c.name not in RECORD_CASES:
                continue
            if (c.kind == "calibration" and cal) or (c.kind == "options" and opt):
                out.append((cmd, c))
    return [(cmd, c) for cmd, c in out if (cmd, c.name) not in PAIRS_NOT_APPLICABLE
            and (cmd not in REPRESENTATIVES_ONLY or c.name in few
                 or (cmd, c.name) in ONE_READER_PAIRS)]



# --------------------------------------------------------------------------- running


class Corpus(CorpusFiles):
    """The corpus built in ``folder`` (:class:`CorpusFiles`); :meth:`run` / :meth:`check` a
    command on one of its cases."""

    def __init__(self, folder: str | Path) -> None:
        super().__init__(folder)
        self._repaired: dict[str, Path] = {}
        self._baseline: dict[str, Outcome] = {}
    def recording_for(self, case: Case) -> Path:
        return self.path(case) if case.kind == R else self.intact

    def repaired(self, case: Case) -> Path:
        """What ``read_raw`` reads from the damaged file, written back as an intact file of
        the same name (so that outputs naming the recording compare equal)."""
        if case.name not in self._repaired:
            from bpms.io.rawfile import write_raw
            from bpms.io.recordings import open_recording

            rec = open_recording(self.path(case))  # read_raw, or the legacy reader
            where = self.folder / "repaired" / case.name
            where.mkdir(parents=True, exist_ok=True)
            path = where / (self.path(case).stem + ".bpmsraw")
            write_raw(path, rec.times, rec.frames.tobytes(), rec.header,
                      [event.at(slot) for slot, event in rec.events])  # the events it read
            self._repaired[case.name] = path
        return self._repaired[case.name]

    def run(self, command: str, case: Case, *, recording: Path | None = None,
            tag: str = "") -> Outcome:
        """Run ``command`` on ``case`` in this process."""
        rec = recording or self.recording_for(case)
        out = self.out_dir / f"{command}-{case.name}{tag}"
        if out.exists():
            shutil.rmtree(out)
        out.mkdir(parents=True)
        calib = str(self.path(case)) if case.kind == "calibration" else None
        opts = str(self.path(case)) if case.kind == "options" else None
        sock = None
        if command == "replay":
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
            sock.bind(("127.0.0.1", 0))
        try:
            argv = _argv(command, rec, out, calib, opts, sock)
            outcome = run_cli(argv, HANG_S)
            outcome.out_dir = out
            if sock is not None:
                outcome.datagrams = _drain(sock)
        finally:
            if sock is not None:
                sock.close()
        outcome.code_ran = (self.path(case).parent / MARKER).exists()
        return outcome

    def baseline(self, command: str, case: Case | None = None) -> Outcome:
        """``command`` on the intact recording ``case`` was made from (the version-2 one for
        a version-2 case), with no configuration given."""
        control = BY_NAME["v2_intact" if case is not None and case.name.startswith("v2_")
                          else "intact"]
        key = f"{command} {control.name}"
        if key not in self._baseline:
            self._baseline[key] = self.run(command, control, tag="-baseline")
        return self._baseline[key]

    def check(self, command: str, case: Case) -> Verdict:
        """Run ``command`` on ``case`` and judge the outcome."""
        outcome = self.run(command, case)
        verdict = Verdict(command, case, outcome)
        if outcome.hang:
            verdict.problems.append(f"still running after {HANG_S:g} s (a hang)")
            return verdict
        if outcome.traceback:
            verdict.traceback = outcome.traceback.strip().splitlines()[-1]
            return verdict
        problems = verdict.problems
        if outcome.code_ran:
            problems.append("the pickle ran code (its marker file exists)")
        expected_code = 0 if case.frames is not None else 2
        if case.frames is not None and command in ("drift", "config", "record"):
            expected_code = self.baseline(command, case).code
        if command == "drift" and case.name.startswith("v2_") and case.name != "v2_intact":
            # damaged sensor data may leave no still end pose: as for what read_raw reads
            expected_code = self.run(command, case, recording=self.repaired(case),
                                     tag="-repaired").code
        if command == "calibrate" and case.name == "calib_directory":
            expected_code = 2  # --existing must name a file: refused in one line
        if command == "batch" and case.frames is None:
            if not (outcome.code == 2 or re.search(r"^0 processed, 1 skipped", outcome.stdout,
                                                   re.MULTILINE)):
                problems.append(f"batch: exit {outcome.code} and not reported skipped")
            return verdict
        if outcome.code != expected_code:
            problems.append(f"exit {outcome.code}, expected {expected_code}"
                            + _last(outcome.stderr))
            return verdict
        if expected_code == 2:
            last = outcome.stderr.strip().splitlines()[-1:] or [""]
            name = command.split("-")[0]
            if not last[0].startswith(f"bpms {name}: "):
                problems.append(f"the error is not one 'bpms {name}: ...' line: {last[0]!r}")
            return verdict
        for text in case.warns:
            if not any(text in line and "warning" in line.lower()
                       for line in (outcome.stderr + outcome.stdout).splitlines()):
                problems.append(f"no warning mentioning {text!r}")
        if outcome.code == 0:
            problems += _missing_outputs(command, outcome)
        if command not in ("config", "record", "calibrate") and case.frames is not None:
            problems += _frames_problems(command, outcome, case.frames, self)
            # Without damaged events, damage costs the same as what read_raw reads written
            # back intact; what a door does in place of a lost event is issue 43.1's.
            if command in ("rom", "track", "drift") and case.kind == R \
                    and not case.events_damaged:
                problems += self._same_as_repaired(command, case, outcome)
        return verdict

    def _same_as_repaired(self, command: str, case: Case, outcome: Outcome) -> list[str]:
        other = self.run(command, case, recording=self.repaired(case), tag="-repaired")
        if other.code != outcome.code:
            return [f"exit {outcome.code}, but {other.code} for what read_raw reads"]
        mine = _outputs_text(outcome)
        theirs = _outputs_text(other)
        if mine != theirs:
            return ["its output differs from the output for what read_raw reads"]
        return []


@dataclass
class Outcome:
    code: int
    stdout: str
    stderr: str
    traceback: str = ""
    seconds: float = 0.0
    out_dir: Path | None = None
    datagrams: list[bytes] = field(default_factory=list)
    code_ran: bool = False
    hang: bool = False


@dataclass
class Verdict:
    command: str
    case: Case
    outcome: Outcome
    traceback: str = ""
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.traceback and not self.problems

    def __str__(self) -> str:
        what = (self.traceback and f"TRACEBACK {self.traceback}") or "; ".join(self.problems)
        return f"{self.command} {self.case.name}: {what or 'ok'}"


#: A command still running after this long is a hang (ended by an alarm where there is one).
HANG_S = 60.0


class _Hang(BaseException):
    """Raised by the alarm in a command that runs too long (not an Exception: the command's
    own handlers do not catch it)."""


@contextlib.contextmanager
def _deadline(seconds: float | None):
    """Interrupt the main thread after ``seconds`` with :class:`_Hang` (Unix main thread;
    elsewhere, no deadline: pytest's timeout is the last guard)."""
    import signal
    import threading

    usable = (seconds and hasattr(signal, "setitimer")
              and threading.current_thread() is threading.main_thread())
    if not usable:
        yield
        return

    def alarm(signum, frame):
        raise _Hang

    before = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before)


def run_cli(argv: list[str], deadline_s: float | None = None) -> Outcome:
    """``bpms ARGV`` in this process: exit code, output, any uncaught exception, and whether
    it was still running after ``deadline_s``."""
    from bpms.cli import main

    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    tb = ""
    hang = False
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            with _deadline(deadline_s):
                code = main(argv)
        except _Hang:
            code, hang = -1, True
        except SystemExit as exc:  # argparse
            code = exc.code if isinstance(exc.code, int) else 2
        except Exception:  # a traceback: what the user would have seen
            code = 1
            tb = traceback.format_exc()
    stderr = err.getvalue()
    if not tb and "Traceback (most recent call last)" in stderr:
        tb = stderr[stderr.index("Traceback (most recent call last)"):]
    return Outcome(code, out.getvalue(), stderr, tb, time.perf_counter() - t0, hang=hang)


def _argv(command: str, rec: Path, out: Path, calib: str | None, opts: str | None,
          sock: socket.socket | None) -> list[str]:
    name, _, fmt = command.partition("-")
    extra = [*(["--calibration", calib] if calib else []), *(["--options", opts] if opts else [])]
    if name == "filter":
        return ["filter", str(rec), "-o", str(out / "f.csv"), "--force", *extra]
    if name == "export":
        target = {"matlab": "m.csv", "bvh": "m.bvh", "opensim": "os"}[fmt]
        return ["export", fmt, str(rec), "-o", str(out / target), "--force", *extra]
    if name == "rom":
        return ["rom", str(rec), "-o", str(out), "--no-figures", *extra]
    if name == "track":
        return ["track", str(rec), "-o", str(out / "t.csv"), "--no-figure", *extra]
    if name == "drift":
        return ["drift", str(rec), "-o", str(out / "d.csv"), *extra]
    if name == "convert":
        return ["convert", str(rec), "-o", str(out / "cv"), "--force", *extra]
    if name == "extract":
        cal = ["--calibrated", "--calibration", calib] if calib else []
        return ["extract", "raw", str(rec), "--imu", "all", "-o", str(out / "x.csv"),
                "--force", *cal]
    if name == "batch":
        return ["batch", str(rec.parent), "-o", str(out / "b"), "--workers", "1",
                *(["--options", opts] if opts else [])]
    if name == "replay":
        assert sock is not None
        host, port = sock.getsockname()
        return ["replay", str(rec), "--speed", "0", "--udp", f"{host}:{port}",
                *(["--options", opts] if opts else [])]
    if name == "config":
        return ["config", "show", *extra]
    if name == "calibrate":  # a gyro calibration of the simulated suit merged into the file
        return ["calibrate", "--sim", "--sim-speed", "0", "--sensor", "gyro", "--gyro-samples",
                "50", "--yes", "--existing", str(calib), "-o", str(out / "Calib.cfg")]
    if name == "record":
        return ["record", "--sim", "--seconds", "1", "-o", str(out), "--name", "corpus", *extra]
    raise ValueError(f"unknown command {command!r}")


def _drain(sock: socket.socket) -> list[bytes]:
    sock.settimeout(0.0)
    out = []
    while True:
        try:
            out.append(sock.recv(65535))
        except (BlockingIOError, TimeoutError):
            return out


#: What each command writes (under its output folder): a command that exits 0 without it
#: has handed back less than was asked.
_OUTPUTS = {
    "filter": ("f.csv",), "export-matlab": ("m.csv",), "export-bvh": ("m.bvh",),
    "export-opensim": ("os*.sto",), "track": ("t.csv",), "drift": ("d.csv",),
    "convert": ("cv.*",), "extract": ("x.csv",), "rom": ("rom*.csv",), "batch": ("b/*",),
}


def _missing_outputs(command: str, outcome: Outcome) -> list[str]:
    """Exit 0: every output the command was asked for exists and holds something."""
    if outcome.out_dir is None:
        return []
    missing = []
    for pattern in _OUTPUTS.get(command, ()):
        found = [p for p in outcome.out_dir.glob(pattern) if p.is_file() or p.is_dir()]
        if not found or all(p.is_file() and p.stat().st_size == 0 for p in found):
            missing.append(pattern)
    return [f"exit 0 without its output {', '.join(missing)}"] if missing else []


def _last(text: str) -> str:
    lines = text.strip().splitlines()
    return f" ({lines[-1][:160]})" if lines else ""


_COUNTS = {
    "filter": re.compile(r": (\d+) frames filtered"),
    "export": re.compile(r"bpms export: (\d+) frames in"),
    "convert": re.compile(r"\((\d+) frames, "),
    "extract": re.compile(r": (\d+) rows × "),
    "batch": re.compile(r"\]\s.*: (\d+) frames, "),
    "replay": re.compile(r"replaying (\d+) frames"),
}


def _frames_problems(command: str, outcome: Outcome, frames: int, corpus: Corpus) -> list[str]:
    """The frame count the command reports (and, for filter, the time of every row)."""
    name = command.split("-")[0]
    pattern = _COUNTS.get(name)
    problems = []
    if pattern is not None:
        found = pattern.findall(outcome.stdout + outcome.stderr)
        if not found:
            problems.append("no frame count in its output")
        elif int(found[-1]) != frames:
            problems.append(f"{found[-1]} frames, expected {frames}")
    if name == "filter" and outcome.out_dir is not None:
        times = _csv_times(outcome.out_dir / "f.csv")
        expected = [round(k * 0.02, 6) for k in range(frames)]
        if times != expected[:len(times)] or len(times) != frames:
            problems.append(f"{len(times)} rows whose times are not k × 0.02 s "
                            f"for k = 0..{frames - 1}")
    if name == "replay":
        raw = [g for g in outcome.datagrams if len(g) > 5 and g[5] == 1]
        if len(raw) != frames:
            problems.append(f"{len(raw)} RAW_FRAME datagrams, expected {frames}")
    return problems


def _csv_times(path: Path) -> list[float]:
    """The time column of a filtered CSV, read with nothing but the text (docs/filtered-file.md):
    '#' lines are the header, then the column names, then one row per frame."""
    if not path.exists():
        return []
    rows = [line for line in path.read_text().splitlines() if line and not line.startswith("#")]
    return [round(float(line.split(",", 1)[0]), 6) for line in rows[1:]]


def _outputs_text(outcome: Outcome) -> str:
    """Output files and stdout with paths and durations taken out (for comparison)."""
    parts = []
    assert outcome.out_dir is not None
    for path in sorted(outcome.out_dir.rglob("*")):
        if path.is_file() and path.suffix in (".csv", ".md", ".sto", ".bvh"):
            parts.append(f"{path.relative_to(outcome.out_dir)}\n{path.read_text()}")
    text = "\n".join(parts) + "\n" + outcome.stdout
    text = re.sub(r"/\S+", "PATH", text)
    # the provenance names the recording: a legacy .txt is repaired into a .bpmsraw
    text = re.sub(r"(recording[=: ]+[^;\n]+?)\.(txt|bpmsraw)\b", r"\1.RAW", text)
    return re.sub(r"\d+\.\d+ s\b", "T s", text)


# --------------------------------------------------------------------------- the table


@dataclass
class Totals:
    tried: int = 0
    tracebacks: int = 0
    wrong: int = 0
    failures: list[str] = field(default_factory=list)
    verdicts: list[Verdict] = field(default_factory=list)


def run_all(corpus: Corpus, commands: tuple[str, ...] | None = None) -> Totals:
    """Every pair (or those of ``commands``); failures are counted and listed."""
    totals = Totals()
    for command, case in pairs():
        if commands and command.split("-")[0] not in commands and command not in commands:
            continue
        verdict = corpus.check(command, case)
        totals.verdicts.append(verdict)
        totals.tried += 1
        if verdict.ok:
            continue
        if verdict.traceback:
            totals.tracebacks += 1
        else:
            totals.wrong += 1
        totals.failures.append(str(verdict))
    return totals


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", metavar="DIR", help="build the corpus into DIR and keep it")
    parser.add_argument("--only", action="append", metavar="COMMAND", help="only this command")
    args = parser.parse_args(argv)
    with contextlib.ExitStack() as stack:
        folder = Path(args.keep) if args.keep else Path(stack.enter_context(
            tempfile.TemporaryDirectory(prefix="bpms-corpus-")))
        if args.keep and (folder / "cases").is_dir():
            shutil.rmtree(folder)  # an earlier corpus: built anew
        elif args.keep and folder.exists() and any(folder.iterdir()):
            parser.error(f"{folder} is not empty (and not an earlier corpus)")
        t0 = time.perf_counter()
        corpus = Corpus(folder)
        totals = run_all(corpus, tuple(args.only or ()))
        print(f"bad inputs tried {totals.tried}, tracebacks {totals.tracebacks}, wrong outputs "
              f"{totals.wrong} ({time.perf_counter() - t0:.1f} s)")
        for line in totals.failures:
            print("  " + line)
        print()
        print(table(totals.verdicts))
    return 1 if totals.tracebacks or totals.wrong else 0


if __name__ == "__main__":
    sys.exit(main())
