"""Docs that run: every fenced Python block in README.md and docs/ is run here, or its first
line says why not (``# not run: REASON``, visible in the page).

- The blocks of the pages run as they stand, with the files the page names (a sample
  recording copied under the name the page uses, the shipped Calib.cfg and options); a block
  that cannot run as it stands says so on its first line (``# not run: REASON``). A preamble
  is for names no page can define (none now).
- The UDP reader of docs/udp.md runs as a script, exactly as it stands, against
  ``bpms replay``; what it prints is checked against the recording and the Python API. A
  change of the UDP format (a new version number) fails here until the page is updated.
- The LSL inlet of docs/lsl.md runs as a script against ``bpms replay --lsl``.
"""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from deadlines import scaled
from waiting import wait_until

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "docs" / "samples"
ARM = SAMPLES / "Raw_simulated_arm_raise.bpmsraw"
WALK = SAMPLES / "Raw_simulated_walk.bpmsraw"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)
NOT_RUN = re.compile(r"\A# not run: \S")


def python_blocks() -> list[tuple[str, str]]:
    """(page, code) of every fenced Python block, pages relative to the repository."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return [(str(page.relative_to(ROOT)), m.group(1)) for page in pages
            for m in BLOCK.finditer(page.read_text(encoding="utf-8"))]


@dataclass(frozen=True)
class Run:
    """How a block runs: in ``folder`` ("repo": the source tree; "tmp": a fresh folder with
    ``files`` copied in), after ``preamble``; ``raises``: the exception its last line is
    meant to raise; ``subprocess``: in a process of its own (it changes global state)."""

    folder: str = "tmp"
    files: tuple[tuple[str, Path], ...] = ()
    preamble: str = ""
    raises: str | None = None
    subprocess: bool = False


TRIAL = (("Raw_trial_001.bpmsraw", ARM),)
#: (page, a line of the block) → how it runs. The UDP reader and the LSL inlet have tests of
#: their own (below).
RUNS: dict[tuple[str, str], Run] = {
    ("README.md", 'result = process_file("docs/samples/'): Run("repo"),
    ("docs/analysis.md", "events = gyro_heel_strikes("): Run("repo"),
    ("docs/opening-recordings.md", 'opened = open_for_processing("Raw_trial_001.bpmsraw")'):
        Run(files=TRIAL),
    ("docs/filter.md", 'proc = BodyPoseProcessor(calibration="Calib.cfg"'): Run(
        files=(*TRIAL, ("Calib.cfg", ROOT / "calib" / "Calib.cfg"),
               ("options.toml", ROOT / "calib" / "options.toml")),
        raises="OptionRangeError"),
    ("docs/filters.md", "proc.select_filter(\"vqf\")"): Run(),
    ("docs/analysis.md", "rom.groupby([\"joint\", \"condition\"])"): Run(),
    ("docs/simulated-suit.md", "rec = simulate(seed=1)"): Run(),
    ("docs/simulated-suit.md", "rec = simulate(seed=1, posture="): Run(),
    ("docs/filtered-file.md", "register_column_group(ColumnGroup("): Run(subprocess=True),
}
SCRIPTS = {("docs/udp.md", "# bpms-udp-reader"), ("docs/lsl.md", "# bpms-lsl-inlet")}


def _key(page: str, code: str) -> tuple[str, str] | None:
    for key in (*RUNS, *SCRIPTS):
        if key[0] == page and key[1] in code:
            return key
    return None


def test_every_python_block_runs_here_or_says_why_not():
    unhandled, seen = [], set()
    for page, code in python_blocks():
        if NOT_RUN.match(code):
            continue
        key = _key(page, code)
        if key is None:
            unhandled.append(f"{page}: {code.splitlines()[0]}")
        seen.add(key)
    assert unhandled == [], ("a Python block neither run by this test nor marked "
                             "'# not run: REASON' on its first line")
    assert set(RUNS) | SCRIPTS <= seen, "a block this test runs is no longer in its page"


def _block(key: tuple[str, str]) -> str:
    return next(code for page, code in python_blocks() if _key(page, code) == key)


@pytest.mark.parametrize("key", list(RUNS), ids=[f"{p}:{k[:24]}" for p, k in RUNS])
def test_the_block_runs(key, tmp_path, monkeypatch):
    run = RUNS[key]
    code = _block(key)
    folder = ROOT if run.folder == "repo" else tmp_path
    for name, source in run.files:
        shutil.copy(source, tmp_path / name)
    script = tmp_path / "block.py"
    script.write_text(run.preamble + code, encoding="utf-8")
    if run.subprocess:
        done = subprocess.run([sys.executable, str(script)], cwd=folder, capture_output=True,
                              text=True, timeout=scaled(120))
        assert done.returncode == 0, done.stderr
        return
    monkeypatch.chdir(folder)
    tree = ast.parse(script.read_text(encoding="utf-8"))
    last = [tree.body.pop()] if run.raises else []
    namespace: dict = {"__name__": "docs_block"}
    exec(compile(tree, f"{key[0]} (block)", "exec"), namespace)
    if last:  # the page's last line shows an error on purpose
        with pytest.raises(Exception) as raised:
            exec(compile(ast.Module(last, []), f"{key[0]} (last line)", "exec"), namespace)
        assert type(raised.value).__name__ == run.raises


# -- the UDP reader against bpms replay -------------------------------------------------------

class Lines:
    """A child's stdout read line by line in a thread (never blocks the test)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._thread.start()

    def _read(self, proc: subprocess.Popen) -> None:
        for line in proc.stdout:
            self.lines.append(line.rstrip("\n"))


def test_the_udp_reader_script_reads_bpms_replay(tmp_path):
    script = tmp_path / "bpms_udp_reader.py"
    script.write_text(_block(("docs/udp.md", "# bpms-udp-reader")), encoding="utf-8")
    reader = subprocess.Popen([sys.executable, "-u", str(script), "0"], cwd=tmp_path,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out = Lines(reader)
        assert wait_until(lambda: out.lines, 30), "the reader never said where it listens"
        port = int(re.fullmatch(r"listening on UDP port (\d+)", out.lines[0]).group(1))
        replay = subprocess.run([sys.executable, "-m", "bpms", "replay", str(ARM), "--udp",
                                 f"127.0.0.1:{port}", "--speed", "4"], cwd=ROOT,
                                capture_output=True, text=True, timeout=scaled(120))
        assert replay.returncode == 0, replay.stderr
        from bpms.io.recordings import open_recording

        frames = open_recording(ARM).decode()
        n = len(frames.raw)

        def count(part: str) -> int:
            return sum(part in ln for ln in list(out.lines))

        wait_until(lambda: count(" head q=") >= n - 5 and count(" raw right ") == (n + 49) // 50,
                   30)
    finally:
        reader.terminate()
        reader.wait(scaled(10))
    lines = out.lines
    assert not [ln for ln in lines if ln.startswith("gap or reorder")]
    raw_lines = [ln for ln in lines if " raw right leg " in ln]
    poses = [ln for ln in lines if " head q=" in ln]
    # one raw line a second, the counts exactly the recording's
    assert len(raw_lines) == (n + 49) // 50
    for line in raw_lines:
        t, counts = re.fullmatch(r"t=([\d.]+)s raw right leg accel counts \((.+)\)",
                                 line).groups()
        k = round(float(t) / 0.02)
        assert k % 50 == 0 and tuple(int(c) for c in counts.split(",")) == tuple(
            int(c) for c in frames.raw[k, 0, :3])
    # a pose for every frame after the first Reset Zero, as the Python API computes it
    from bpms.filter.door import process_file

    result = process_file(ARM)
    assert len(poses) >= n - 5
    pattern = (r"t=([\d.]+)s head q=\(.+\) knee_r=(-?[\d.]+) deg "
               r"pelvis height=(-?[\d.]+) m isb")
    worst_knee = worst_height = 0.0
    for line in poses:
        t, knee, height = (float(x) for x in re.fullmatch(pattern, line).groups())
        k = round(t / 0.02)
        worst_knee = max(worst_knee, abs(knee - np.degrees(result.joint_angles[k, 2])))
        worst_height = max(worst_height, abs(height + result.joint_positions[k, 0, 2]))
    assert worst_knee <= 0.06 and worst_height <= 0.0006


# -- the LSL inlet against bpms replay --lsl ---------------------------------------------------

def test_the_lsl_inlet_script_reads_bpms_replay(tmp_path):
    pytest.importorskip("pylsl")
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-docs-{os.getpid()}\n")
    env = {**os.environ, "LSLAPICFG": str(cfg)}
    script = tmp_path / "inlet.py"
    script.write_text(_block(("docs/lsl.md", "# bpms-lsl-inlet")), encoding="utf-8")
    inlet = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    replay = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(WALK), "--lsl",
                               "--loop"], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    try:
        out, err = inlet.communicate(timeout=scaled(90))
    finally:
        replay.terminate()
        replay.wait(scaled(20))
    assert inlet.returncode == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("convention: isb")
    summary = re.fullmatch(r"(\d+) samples over ([\d.]+) s, steps ([\d.]+)-([\d.]+) ms, "
                           r"joint_knee_r_flexion (-?[\d.]+) to (-?[\d.]+) deg", lines[1])
    assert summary, lines
    count, span, low, high, _, knee_max = (float(x) for x in summary.groups())
    assert count == 200 and span == pytest.approx(3.98, abs=0.011)
    assert 19.0 <= low <= high <= 21.0  # the de-jittered 50 Hz clock
    assert knee_max > 5.0  # the walk bends the knee


def test_samples_are_small_labelled_simulated_recordings():
    from bpms.io.recordings import open_recording

    files = sorted(SAMPLES.glob("*.bpmsraw"))
    assert len(files) >= 2 and sum(f.stat().st_size for f in files) < 500_000
    for path in files:
        assert path.name.startswith("Raw_simulated_")
        rec = open_recording(path)
        assert rec.header["notes"].startswith("SIMULATED recording (not a person)")
        assert rec.header.get("simulated") is True and len(rec) > 400
