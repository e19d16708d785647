"""Live latency and CPU at 50 Hz over a pseudo-terminal: the pipeline beside a minimal relay,
and both beside the tree before the one-implementation work (bench/reference.py).

Run: ``.venv/bin/python bench/live.py [--minutes 0.5] [--untuned] [--reference auto|PATH|none]``
(Linux/macOS: a pty).

The simulated suit streams in real time (50 Hz) on a pty, read by the project's serial source
(:class:`bpms.pipeline.sources.SuitFrameSource`). Measured one after the other in this run:

- **relay**: the same source read by one thread and handed to a second thread through a queue,
  nothing else (the floor any live pipeline pays on this machine);
- **pipeline**: :class:`bpms.pipeline.session.LiveSession` with raw and filtered recording on
  (warm-up and frozen heap, :mod:`bpms.pipeline.steady`);
- with ``--untuned``, also the pipeline with warm-up and gc freezing switched off;
- **reference**: the relay and the pipeline of the tree at
  :data:`reference.BEFORE_ONE_IMPLEMENTATION` (a ``git worktree`` in the temporary folder)
  (``--reference-minutes`` each, default: as long as ``--minutes``).

Every run, of either tree, is a fresh child process (a process that already ran sessions would
carry their leftovers into the next: a larger heap for the collector, warm dispatchers), and
with ``--rounds`` the runs take turns.

Printed for each: frame → pose latency (host took the frame in → sample ready) p50, p99,
p99.9 and max in ms, the worst of the first 10 frames, the longest garbage-collection pause
(``gc.callbacks``, from the first frame on), the number of full (generation 2) collections,
and CPU time per frame (ms, whole process, from the first frame to the end: the simulated suit
runs in the same process). The **recorder's** CPU per frame is the pipeline's minus the relay's
of the same tree (what recording adds on top of reading the suit), printed beside the
reference's.
Aims (issue 24.5): over 10 minutes, frame → pose p99.9 and the recorder's CPU per frame each
≤ 1.2× the reference's (issue 18.4 before it: p99.9 ≤ 5 ms, no gc pause over 5 ms). Figures
only.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _tree_from_argv() -> Path:
    """``--tree PATH`` (child runs of another tree) goes first on sys.path, before bpms loads."""
    if "--tree" in sys.argv:
        return Path(sys.argv[sys.argv.index("--tree") + 1]).resolve()
    return ROOT


sys.path.insert(0, str(_tree_from_argv()))


class GcWatch:
    """Garbage collections (``gc.callbacks``): (start, ``time.perf_counter()`` s; duration,
    s; generation). ``since``: only collections from then on count (the first frame)."""

    def __init__(self) -> None:
        self.pauses: list[tuple[float, float, int]] = []
        self.since = 0.0
        self._t0 = 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._t0 = time.perf_counter()
        else:
            self.pauses.append((self._t0, time.perf_counter() - self._t0, info["generation"]))

    def counted(self) -> list[tuple[float, int]]:
        return [(d, g) for t, d, g in self.pauses if t >= self.since]

    def __enter__(self) -> GcWatch:
        gc.callbacks.append(self)
        return self

    def __exit__(self, *exc: object) -> None:
        gc.callbacks.remove(self)


class Run:
    """One measured run: latencies s, gc pauses (s, generation), CPU s per frame."""

    def __init__(self, latencies: np.ndarray, pauses: list[tuple[float, int]],
                 cpu_per_frame: float) -> None:
        self.latencies = latencies
        self.pauses = pauses
        self.cpu = cpu_per_frame

    def to_json(self) -> str:
        return json.dumps({"latencies": self.latencies.tolist(), "pauses": self.pauses,
                           "cpu": self.cpu})

    @classmethod
    def from_json(cls, text: str) -> Run:
        d = json.loads(text)
        return cls(np.array(d["latencies"]), [tuple(p) for p in d["pauses"]], d["cpu"])

    @staticmethod
    def join(runs: list[Run]) -> Run:
        """Runs of the same thing one after the other as one (CPU weighted by frames)."""
        frames = [max(len(r.latencies), 1) for r in runs]
        cpu = sum(r.cpu * n for r, n in zip(runs, frames, strict=True)) / sum(frames)
        return Run(np.concatenate([r.latencies for r in runs]),
                   [p for r in runs for p in r.pauses], cpu)


def _suit():
    from bpms.firmware.sim.arbiter import Arbiter, MotionSource
    from bpms.firmware.sim.server import PtyServer

    return PtyServer(Arbiter(MotionSource.simulated(seed=1), realtime=True)).start()


def relay(seconds: float) -> Run:
    """The minimal relay: read the suit in one thread, hand each frame to another."""
    from bpms.io.options import SerialOptions
    from bpms.pipeline.sources import SuitFrameSource

    server = _suit()
    source = SuitFrameSource(server.path, SerialOptions())
    source.connect()
    handoff: queue.Queue = queue.Queue()
    latencies: list[float] = []
    stop = threading.Event()
    first = threading.Event()

    def reader() -> None:
        while not stop.is_set():
            for event in source.read(0.1):
                handoff.put(event)

    def taker() -> None:
        while not stop.is_set():
            try:
                event = handoff.get(timeout=0.1)
            except queue.Empty:
                continue
            if not latencies:
                watch.since = event.arrival
                first.set()
            latencies.append(time.perf_counter() - event.arrival)

    threads = [threading.Thread(target=f, daemon=True) for f in (reader, taker)]
    watch = GcWatch()
    with watch:
        for t in threads:
            t.start()
        first.wait(30.0)
        cpu0, n0 = time.process_time(), len(latencies)
        time.sleep(seconds)
        cpu, n = time.process_time() - cpu0, len(latencies) - n0
        stop.set()
        for t in threads:
            t.join(2)
    source.close()
    server.stop()
    return Run(np.array(latencies), watch.counted(), cpu / max(n, 1))


def _prewarm_reference() -> None:
    """A tree without a warm-up of its own (the reference) loads its kernels here, so its CPU
    figure is the steady state's, not the first call's."""
    from bpms.filter.processor import BodyPoseProcessor

    proc = BodyPoseProcessor()
    raw = np.zeros((4, 18, 9), np.int16)
    raw[..., 2] = 256
    result = proc.process(raw)
    for _ in range(3):
        result = proc.step(raw[0])
    _ = result.joint_angles, result.joint_positions, result.segment_quaternions


def pipeline(seconds: float, tuned: bool = True) -> Run:
    """The LiveSession with raw and filtered recording on."""
    import bpms.pipeline.session as session_module
    from bpms.io.options import SerialOptions
    from bpms.pipeline.session import LiveSession
    from bpms.pipeline.sources import SuitFrameSource

    own_warm_up = hasattr(session_module, "prepare_live_path")
    if not own_warm_up:
        _prewarm_reference()
    original = getattr(session_module, "prepare_live_path", None)
    if not tuned and own_warm_up:
        session_module.prepare_live_path = lambda processor: 0.0
    server = _suit()
    try:
        with tempfile.TemporaryDirectory(prefix="bpms-live-") as tmp:
            session = LiveSession(SuitFrameSource(server.path, SerialOptions()),
                                  recording_dir=tmp)
            sub = session.subscribe(maxlen=10_000)
            session.source.connect()
            session.start_logging(raw=True, filtered=True, name="bench")
            # (latency s, host time s) of every sample; the samples themselves are let go, as
            # a display does, so that collections do not scan minutes of them
            seen: list[tuple[float, float]] = []
            with GcWatch() as watch:
                session.start()
                first = sub.get(60.0)
                cpu0 = time.process_time()
                end = time.monotonic() + seconds
                while first is not None and time.monotonic() < end:
                    time.sleep(min(0.5, max(end - time.monotonic(), 0.0)))
                    seen += [(s.latency_s, s.host_time) for s in sub.drain()]
                cpu, t1 = time.process_time() - cpu0, time.time()
                session.stop()
            if first is not None:
                seen = [(first.latency_s, first.host_time), *seen,
                        *((s.latency_s, s.host_time) for s in sub.drain())]
                # the warm-up's collection happens before the first frame
                watch.since = time.perf_counter() - (time.time() - first.host_time)
    finally:
        if original is not None:
            session_module.prepare_live_path = original
        server.stop()
    lat = np.array([latency for latency, _ in seen])
    n = sum(1 for _, host in seen[1:] if host <= t1)
    return Run(lat, watch.counted(), cpu / max(n, 1))


def in_child(tree: str, what: str, seconds: float) -> Run | str:
    """One run (``relay``, ``pipeline`` or ``untuned``) of ``tree``'s bpms in a fresh child
    process, or why it failed. Both trees are measured this way: a process that has already
    run sessions holds their leftovers (a larger heap for the collector to scan, numba's
    dispatchers warm), which a fresh one does not."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as out:
        path = out.name
    env = {**os.environ, "PYTHONPATH": tree}
    done = subprocess.run([sys.executable, __file__, "--tree", tree, "--child", what,
                           "--minutes", str(seconds / 60), "--out", path],
                          env=env, cwd=tree, capture_output=True, text=True)
    if done.returncode:
        return f"{what} of {tree} failed: {done.stderr.strip().splitlines()[-1:]}"
    run = Run.from_json(Path(path).read_text())
    os.unlink(path)
    return run


def report(name: str, run: Run) -> None:
    ms = run.latencies * 1e3
    longest = max((p for p, _ in run.pauses), default=0.0) * 1e3
    full = sum(1 for _, g in run.pauses if g == 2)
    if not len(ms):
        print(f"{name:<20} no frames")
        return
    p50, p99, p999 = np.percentile(ms, [50, 99, 99.9])
    print(f"{name:<20}{len(ms):8d}{p50:8.2f}{p99:8.2f}{p999:9.2f}{ms.max():8.2f}"
          f"{ms[:10].max():10.2f}{longest:10.2f}{full:7d}{run.cpu * 1e3:10.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=0.5, help="length of each run")
    parser.add_argument("--untuned", action="store_true",
                        help="also run the pipeline without warm-up and gc freezing (first)")
    parser.add_argument("--reference", default="auto",
                        help="the reference tree: auto (a worktree of the commit before "
                             "the one-implementation work), a folder, or none")
    parser.add_argument("--reference-minutes", type=float, default=None,
                        help="length of each reference run (default: --minutes)")
    parser.add_argument("--rounds", type=int, default=1,
                        help="split each run into this many turns, taking turns with the "
                             "reference")
    parser.add_argument("--tree", help=argparse.SUPPRESS)
    parser.add_argument("--child", choices=("relay", "pipeline", "untuned"),
                        help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    seconds = args.minutes * 60.0
    if args.child:
        run = (relay(seconds) if args.child == "relay"
               else pipeline(seconds, tuned=args.child == "pipeline"))
        Path(args.out).write_text(run.to_json())
        return
    ref_minutes = args.reference_minutes or args.minutes
    ref: tuple[Run, Run] | str | None = None
    tree = None
    if args.reference != "none":
        tree = args.reference
        if tree == "auto":
            sys.path.insert(0, str(Path(__file__).parent))
            from reference import reference_tree

            try:
                tree = str(reference_tree())
            except RuntimeError as exc:
                tree, ref = None, f"reference not measured: {exc}"
    # This tree and the reference take turns (``--rounds``), so that load from elsewhere on the
    # machine falls on both alike; every run is a fresh child process, for both trees.
    plan = [("relay", "relay", str(ROOT), seconds), ("pipeline", "pipeline", str(ROOT), seconds)]
    if args.untuned:
        plan.insert(1, ("pipeline untuned", "untuned", str(ROOT), seconds))
    if tree is not None:
        plan += [("reference relay", "relay", tree, ref_minutes * 60.0),
                 ("reference pipeline", "pipeline", tree, ref_minutes * 60.0)]
    parts: dict[str, list[Run]] = {}
    for _ in range(args.rounds):
        for name, what, where, length in plan:
            got = in_child(where, what, length / args.rounds)
            if isinstance(got, str):
                if not name.startswith("reference"):
                    raise SystemExit(got)
                ref = got
                plan = [step for step in plan if not step[0].startswith("reference")]
                continue
            parts.setdefault(name, []).append(got)
    runs = [(name, Run.join(found)) for name, found in parts.items()]
    if "reference pipeline" in parts:
        ref = (dict(runs)["reference relay"], dict(runs)["reference pipeline"])
    print(f"\nframe → pose latency at 50 Hz over a pty, {args.minutes:g} min per run "
          f"(reference: {ref_minutes:g} min) (ms)")
    print(f"{'':<20}{'frames':>8}{'p50':>8}{'p99':>8}{'p99.9':>9}{'max':>8}{'first 10':>10}"
          f"{'gc max':>10}{'gen2':>7}{'CPU/frame':>10}")
    for name, run in runs:
        report(name, run)
    by_name = dict(runs)
    recorder = by_name["pipeline"].cpu - by_name["relay"].cpu
    print(f"\nrecorder CPU per frame (pipeline − relay of the same tree): "
          f"{recorder * 1e3:.3f} ms", end="")
    if isinstance(ref, tuple):
        ref_recorder = ref[1].cpu - ref[0].cpu
        p999 = np.percentile(by_name["pipeline"].latencies, 99.9)
        ref_p999 = np.percentile(ref[1].latencies, 99.9)
        print(f"; reference: {ref_recorder * 1e3:.3f} ms; ratio {recorder / ref_recorder:.2f} "
              f"(aim ≤ 1.2)")
        print(f"frame → pose p99.9: {p999 * 1e3:.2f} ms; reference: {ref_p999 * 1e3:.2f} ms; "
              f"ratio {p999 / ref_p999:.2f} (aim ≤ 1.2)")
    else:
        print(f"; {ref}" if ref else "")
    print(f"load average: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
