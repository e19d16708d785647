"""The hostile-input corpus (tools/hostile_corpus.py, issue 26.7) through every command that
reads a recording or a configuration: 0 tracebacks, no exit 0 with wrong output, no pickle
that runs code. The commands run in this interpreter (one corpus, built once); a few run as
real processes too (the nested and the 200 MB header).

The corpus expects the one reader of each format (issue 25): frame counts equal to
``read_raw``'s, and exit 2 for a recording with no valid frame; every door reads ``.bpmsraw``
through it (bpms/io/raw_reader.py)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
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

def _params():
    return [pytest.param(command, case.name, id=f"{command}-{case.name}")
            for command, case in tool.pairs()]


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
        if case.name.startswith("v2_"):
            continue  # below, one by one
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


V2_CASES = [c.name for c in tool.RECORDING_CASES if c.name.startswith("v2_")]


@pytest.mark.parametrize("case", V2_CASES)
def test_a_version_2_recording_keeps_every_frame_slot_whatever_the_damage(corpus, case):
    """The frame slots are the frame records the live session wrote (counted from the
    documented layout, tools/corpus_events.py), damage or not; the frames damaged are at
    most those whose records the damage touched; every event kind the code writes is in the
    intact file."""
    from bpms.io.rawfile import read_raw

    rec = read_raw(corpus.path(tool.BY_NAME[case]))
    assert len(rec) == tool.N_SLOTS, rec.problems
    assert set(rec.damaged) <= corpus.touched[case], rec.problems
    if case == "v2_intact":
        from bpms.io.session_events import KINDS

        assert rec.problems == []
        assert {e.kind for _, e in rec.events} == set(KINDS)


def test_a_damaged_reset_zero_record_leaves_the_joint_angles(corpus, tmp_path):
    """One bit flipped in every Reset Zero record of a live recording: the frames are intact,
    so every row keeps its joint angles (issue 43.1: none did)."""
    from bpms.io.filtered_file.reader import read_filtered

    out = tmp_path / "j.csv"
    outcome = tool.run_cli(["filter", str(corpus.path(tool.BY_NAME["v2_reset_zero_bits"])),
                            "-o", str(out), "--joints"], 60)
    assert outcome.code == 0 and not outcome.traceback, outcome.stderr[-2000:]
    joints = read_filtered(out).joint_angles
    assert joints is not None and np.isfinite(joints).all(axis=1).mean() > 0.9


def test_every_damage_class_and_command_is_covered():
    classes = {c.damage for c in tool.CASES}
    for required in ("truncation", "random bytes", "inserted bytes", "deleted bytes",
                     "damaged events", "v2 random bytes",
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
