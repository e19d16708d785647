"""The hostile-input corpus (tools/hostile_corpus.py, issue 26.7) through every command that
reads a recording or a configuration: 0 tracebacks, no exit 0 with wrong output, no pickle
that runs code. The commands run in this interpreter (one corpus, built once); a few run as
real processes too (the nested and the 200 MB header).

The corpus expects the one reader of each format (issue 25): frame counts equal to
``read_raw``'s, and exit 2 for a recording with no valid frame. The analysis commands still
read ``.bpmsraw`` through a second reader that never resynchronises; exactly the pairs that
fail for that reason are marked ``xfail(strict=True)``, so each turns into a failure the day
issue 25 lands, and its mark must then go."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.timeout(300)


def _load_tool():
    spec = importlib.util.spec_from_file_location("hostile_corpus",
                                                  REPO / "tools" / "hostile_corpus.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


tool = _load_tool()

ISSUE_25 = tool.ISSUE_25
XFAIL = pytest.mark.xfail(strict=True, reason="issue 25: one reader per format")


def _params():
    out = []
    for command, case in tool.pairs():
        marks = [XFAIL] if (command, case.name) in ISSUE_25 else []
        out.append(pytest.param(command, case.name, marks=marks, id=f"{command}-{case.name}"))
    return out


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    return tool.Corpus(tmp_path_factory.mktemp("corpus"))


@pytest.mark.parametrize(("command", "case"), _params())
def test_command_on_hostile_input(corpus, command, case):
    verdict = corpus.check(command, tool.BY_NAME[case])
    assert not verdict.traceback, f"traceback: {verdict.outcome.traceback}"
    assert verdict.problems == [], verdict.outcome.stderr[-2000:]


def test_the_corpus_expectations_agree_with_read_raw(corpus):
    """What each recording case is built to hold is what the one reader reads from it (the
    constructed expectation is independent of the reader; both must agree)."""
    from bpms.io.rawfile import RawFileError
    from bpms.io.recordings import open_recording

    for case in tool.RECORDING_CASES:
        try:
            rec = open_recording(corpus.path(case))
        except (RawFileError, OSError):
            assert case.frames is None, case.name
            continue
        valid = len(rec) - len(rec.damaged)
        if case.frames is None:
            assert valid == 0, case.name  # no valid frame: to be refused
        else:
            assert len(rec) == case.frames, case.name
            if case.name not in ("absurd_times",):
                intact = [corpus.times[k] for k in range(len(rec)) if k not in set(rec.damaged)]
                got = [rec.times[k] for k in range(len(rec)) if k not in set(rec.damaged)]
                assert got == pytest.approx(intact[:len(got)], abs=1e-3), case.name


def test_every_damage_class_and_command_is_covered():
    classes = {c.damage for c in tool.CASES}
    for required in ("truncation", "random bytes", "inserted bytes", "deleted bytes",
                     "pickle __reduce__", "directory", "empty file", "absurd calibration",
                     "absurd options", "nested header", "200 MB header"):
        assert required in classes
    commands = {cmd for cmd, _ in tool.pairs()}
    assert {"filter", "export-matlab", "rom", "track", "drift", "convert", "batch", "extract",
            "replay", "config"} <= commands


def test_a_200_mb_header_is_refused_unread(corpus):
    """Memory stays flat: the header's length is checked before a byte of it is read."""
    path = str(corpus.path(tool.BY_NAME["huge_header"]))
    tracemalloc.start()
    try:
        outcome = tool.run_cli(["filter", path, "-o", str(corpus.folder / "h.csv")])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert outcome.code == 2 and "more than the 16 MiB" in outcome.stderr
    assert peak < 20e6, f"{peak / 1e6:.0f} MB allocated"


@pytest.mark.parametrize("command", ["filter", "replay", "convert"])
def test_the_nested_header_in_a_real_process(corpus, command):
    """200,000 nested '[' used to end in a RecursionError traceback (10 commands)."""
    path = str(corpus.path(tool.BY_NAME["nested_header"]))
    args = {"filter": ["filter", path], "replay": ["replay", path, "--udp", "127.0.0.1:9"],
            "convert": ["convert", path, "-o", str(corpus.folder / "nested")]}[command]
    run = subprocess.run([sys.executable, "-m", "bpms", *args], cwd=REPO, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        f"bpms {command}: {path}: the header nests 200000 levels deep, more than the 64 this "
        "software reads"]
