"""Getting the compiled filters ready: the notice, its progress lines, and when it happens."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

from bpms.filter import warmup
from bpms.filter.warmup import Progress, ensure_kernels, kernels_ready

ROOT = Path(__file__).resolve().parents[1]


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _show(stream, steps: int = 3) -> str:
    progress = Progress(steps, stream, notice_after_s=0.0)
    progress._timer.join(5)  # the notice is due at once
    progress.compile_started()  # and something compiles
    for k in range(steps):
        progress.step(f"step {k}")
        progress.advance()
    progress.close()
    return stream.getvalue()


def test_progress_rewrites_one_line_on_a_terminal():
    text = _show(Terminal())
    assert text.count("\n") == 1 and text.endswith("\n")  # one line, ended once
    assert text.count("\r") >= 4 and "3/3 done in" in text.split("\r")[-1]


def test_progress_writes_plain_lines_elsewhere():
    text = _show(io.StringIO())
    assert "\r" not in text
    lines = text.splitlines()
    assert len(lines) >= 4 and lines[-1].endswith(" s") and "3/3 done in" in lines[-1]
    assert all(line.startswith("bpms: compiling the filters") for line in lines)


def test_nothing_is_said_when_it_is_quick():
    stream = io.StringIO()
    progress = Progress(2, stream, notice_after_s=60.0)
    progress.step("a")
    progress.advance()
    progress.close()
    assert stream.getvalue() == ""


def test_nothing_is_said_when_nothing_compiles():
    """Loading cached kernels on a busy machine may take longer than the notice's delay: it
    is not compiling, and says nothing (issue 43.7)."""
    stream = io.StringIO()
    progress = Progress(2, stream, notice_after_s=0.0)
    progress._timer.join(5)
    progress.step("a")
    progress.advance()
    progress.close()
    assert stream.getvalue() == ""


FRESH_THEN_CACHED = """
import io, sys
from bpms.filter import warmup
warmup.PARTS["vqf"] = ("hinge",)  # the quickest part alone (about 2 s to compile)
stream = io.StringIO()
warmup.ensure_kernels("vqf", stream=stream, notice_after_s=0.0)
print(repr(stream.getvalue()))
"""


def test_the_notice_appears_when_compiling_and_not_when_loading_the_cache(tmp_path):
    env = {**__import__("os").environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    said = []
    for _ in range(2):  # a fresh numba cache: compiles; then the same cache: loads
        done = subprocess.run([sys.executable, "-c", FRESH_THEN_CACHED], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        said.append(done.stdout.strip().splitlines()[-1])
    assert "compiling the filters for this machine" in said[0] and "1/1 done in" in said[0]
    assert said[1] == "''"


def test_kernels_are_ready_once_and_a_live_session_loads_them_before_any_frame(monkeypatch):
    from bpms.pipeline.session import LiveSession

    monkeypatch.setattr(warmup, "_ready", set())  # as in a fresh process
    assert not kernels_ready("mahony")

    class Silent:  # a frame source that never delivers a frame
        def read(self, timeout: float = 0.1) -> list:
            return []

        def status(self):  # pragma: no cover - never asked here
            raise NotImplementedError

        def close(self) -> None:
            pass

    session = LiveSession(Silent())  # built, not started: not one frame has been offered
    assert session.processor is not None
    assert kernels_ready("mahony")
    assert not kernels_ready("observer")  # only the kernels this session needs
    assert ensure_kernels("mahony") == 0.0  # once per process


def test_bpms_warmup_command_says_the_filters_are_ready():
    done = subprocess.run([sys.executable, "-m", "bpms", "warmup", "--filter", "mahony"],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith("bpms warmup: the filters (mahony)")
    assert "\r" not in done.stderr


LIVE_PATH_COMPILES = """
import sys
from numba.core import event
from bpms.filter.warmup import ensure_kernels
from bpms.filter.processor import BodyPoseProcessor
from bpms.pipeline.steady import warm_up

# what 'bpms warmup' (one process per core) and a live session (this process) do first
with event.install_recorder("numba:compile") as compiled_here:
    ensure_kernels(sys.argv[1], processes=int(sys.argv[2]))
processor = BodyPoseProcessor()
processor.select_filter(sys.argv[1])
with event.install_recorder("numba:compile") as compiles:
    warm_up(processor)  # every call of the live path: batch, wire frames, Reset Zero, joints
modules = {e.data["dispatcher"].py_func.__module__ for _, e in compiled_here.buffer}
modules = {name for name in modules if name.startswith("bpms.")} or {"none"}
print(",".join(sorted(modules)), len(compiles.buffer))
"""


def test_after_the_warm_up_nothing_on_the_live_path_compiles(tmp_path):
    # a fresh numba cache, as on a machine that never ran BPMS Suite: whatever the warm-up
    # leaves out is compiled while a live session waits for its first frame. Mahony's parts
    # are shared out over two processes: this one compiles the filter, a child the
    # disturbance indicators and the hinge constraint, which this one then only loads.
    env = {**__import__("os").environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    for algorithm, processes in (("mahony", 2), ("adaptive", 1)):
        done = subprocess.run([sys.executable, "-c", LIVE_PATH_COMPILES, algorithm,
                               str(processes)], cwd=ROOT, env=env, capture_output=True,
                              text=True, timeout=900)
        assert done.returncode == 0, done.stderr[-3000:]
        compiled_here, live_compiles = done.stdout.split()[-2:]
        assert live_compiles == "0", (algorithm, done.stdout)
        if processes == 2:
            assert compiled_here.split(",") == ["bpms.filter.guard", "bpms.filter.mahony"]
