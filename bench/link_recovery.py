"""Link recovery figures (run on demand): ``python bench/link_recovery.py [--repeat N]``.

For each fault, over a real pseudo-terminal and over TCP, with the simulated suit and the link
state machine (:class:`bpms.pipeline.sources.SuitFrameSource`, as ``bpms record``,
``bpms monitor``, the GUI and the calibration tool use it):

- **silence**: the radio carries nothing for 3–4 s, the suit keeps streaming;
- **power-cycle**: the suit is off for 3–4 s, then on and idle (needs a new start);
- **unplugged**: the port disappears for 3–4 s (pty: the device node goes; TCP: the server
  closes the connection and stops listening), then comes back with an idle suit.

The outage lasts 3 s + 0.37 s × run, so the suit returns at different phases of the 1 s
probe / reopen cycle.

Figures per fault: time from the suit's return to the first frame (goal ≤ 2 s; ≤ 1 s for a
plain silence), frames lost (the simulated suit samples nothing while silent or off, so every
motion frame it sent should arrive, except those in flight when a port is unplugged),
duplicates and stale frames (a repeated frame, as a restarted stream's first frame would be).
The reference beside them, measured in the same run: the time from opening a fresh link to
its first frame.
"""

from __future__ import annotations

import argparse
import itertools
import logging
import math
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import PtyServer, TcpServer
from bpms.io.options import SerialOptions
from bpms.pipeline.sources import SuitFrameSource


class Suit:
    def __init__(self, kind: str, folder: Path, motion: MotionSource) -> None:
        self.kind = kind
        self.arbiter = Arbiter(motion)
        self.link = folder / f"rfcomm-{kind}"
        self.server = None
        self.tcp_port = 0
        self.plug()

    @property
    def port(self) -> str:
        return str(self.link) if self.kind == "pty" else f"socket://127.0.0.1:{self.tcp_port}"

    def plug(self) -> None:
        self.arbiter.host_disconnected()
        if self.kind == "pty":
            self.server = PtyServer(self.arbiter).start()
            tmp = self.link.with_suffix(".new")
            os.symlink(self.server.path, tmp)
            os.replace(tmp, self.link)
        else:
            self.server = TcpServer(self.arbiter, port=self.tcp_port).start()
            self.tcp_port = self.server.port

    def unplug(self) -> None:
        if self.kind == "pty":
            self.link.unlink()
        self.server.stop()

    def close(self) -> None:
        self.server.stop()


class Reader(threading.Thread):
    """The acquisition loop: reads the source, keeps (arrival time, frame)."""

    def __init__(self, source: SuitFrameSource) -> None:
        super().__init__(daemon=True)
        self.source = source
        self.got: list[tuple[float, bytes]] = []
        self.stop = threading.Event()

    def run(self) -> None:
        while not self.stop.is_set():
            for e in self.source.read(0.05):
                self.got.append((time.monotonic(), e.frame))


def wait_for(predicate, timeout: float = 20.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.01)
    return False


def run_fault(kind: str, fault: str, motion: MotionSource, folder: Path, off_s: float) -> dict:
    suit = Suit(kind, folder, motion)
    t_open = time.monotonic()
    source = SuitFrameSource(suit.port, SerialOptions(link_lost_after_s=1.0))
    source.connect()
    reader = Reader(source)
    reader.start()
    try:
        wait_for(lambda: len(reader.got) >= 1)
        first = reader.got[0][0] - t_open
        wait_for(lambda: len(reader.got) >= 100)
        if fault == "silence":
            suit.arbiter.silence(off_s)
            t_back = time.monotonic() + off_s
        elif fault == "power-cycle":
            suit.arbiter.silence(off_s)
            suit.arbiter.host_disconnected()
            t_back = time.monotonic() + off_s
        else:
            suit.unplug()
            time.sleep(off_s)
            suit.plug()
            t_back = time.monotonic()
        ok = wait_for(lambda: reader.got[-1][0] > t_back, 15.0)
        flowing = next((t for t, _ in reader.got if t > t_back), math.nan) if ok else math.nan
        wait_for(lambda: reader.got[-1][0] > t_back + 1.0, 5.0)
    finally:
        reader.stop.set()
        reader.join(2)
        source.close()
        suit.close()
    n = suit.arbiter.stats.motion_frames
    index = {motion.frame(j): j for j in range(n)}
    seq = [index.get(f, -1) for _, f in reader.got]
    return {
        "first_frame_s": first,
        "recovery_s": flowing - t_back,
        "lost": n - len(set(seq) - {-1}),
        "duplicates": len(seq) - len(set(seq)),
        "stale": sum(1 for j in seq if j < 0)
        + sum(1 for a, b in itertools.pairwise(seq) if b <= a),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="runs per fault and transport")
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    motion = MotionSource.simulated(duration_s=120.0, seed=17)
    print(f"{'transport':9} {'fault':12} {'recovery s (min/med/max)':>26} {'goal':>6} "
          f"{'lost':>5} {'dup':>4} {'stale':>5}   reference: open→first frame s")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in ("pty", "tcp"):
            for fault in ("silence", "power-cycle", "unplugged"):
                runs = [run_fault(kind, fault, motion, Path(tmp), 3.0 + 0.37 * k)
                        for k in range(args.repeat)]
                rec = [r["recovery_s"] for r in runs]
                goal = 1.0 if fault == "silence" else 2.0
                print(f"{kind:9} {fault:12} {min(rec):8.3f} {statistics.median(rec):8.3f} "
                      f"{max(rec):8.3f} {goal:6.1f} {sum(r['lost'] for r in runs):5d} "
                      f"{sum(r['duplicates'] for r in runs):4d} "
                      f"{sum(r['stale'] for r in runs):5d}   "
                      f"{statistics.median(r['first_frame_s'] for r in runs):.3f}",
                      flush=True)


if __name__ == "__main__":
    main()
