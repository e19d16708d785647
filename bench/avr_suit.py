"""The firmware in the AVR simulator, figures (run on demand): ``python bench/avr_suit.py
[--seconds S]``.

The suit of ``bpms sim --avr`` (the arbiter and six cluster images on simulated ATmega328P
boards at 16 MHz, docs/firmware.md) streams to a host for S simulated seconds (default 10):

1. **unthrottled**, read by a plain :class:`SuitLink`: the real-time factor while streaming
   (simulated seconds per host second). The reference beside it, measured in the same run:
   the factor of the same suit idle (powered, no host: every board asleep between timer ticks);
2. **real time**, as ``bpms sim --avr`` runs by default, read by the link state machine of
   ``bpms record`` and the GUI (:class:`SuitFrameSource`): the factor reached, the frames per
   host second against the frames per simulated second, and whether the watchdog ever called
   the link silent;
3. **the cycle budget**: each board's awake cycles per 20 ms frame (mean and worst) out of the
   320,000 a 16 MHz ATmega328P has, and the arbiter's busy span (first poll to the frame's
   last byte) against the 20 ms period.

The computer is shared: the load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.firmware.avr_build import build
from bpms.firmware.avr_suit import AvrSuit
from bpms.firmware.sim.arbiter import MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.link import SuitLink
from bpms.io.link_states import LinkState
from bpms.pipeline.sources import SuitFrameSource

BUDGET = 320_000


def factor_between(a: dict, b: dict) -> float:
    return (b["sim_s"] - a["sim_s"]) / max(b["wall_s"] - a["wall_s"], 1e-9)


def idle_factor(images, motion: MotionSource, seconds: float) -> float:
    with AvrSuit(motion, realtime=False, build=images) as suit:
        first = suit.wait_status(lambda s: True, 60)
        last = suit.wait_status(lambda s: s["sim_s"] >= first["sim_s"] + seconds, 600)
    return factor_between(first, last)


def streaming_unthrottled(images, motion: MotionSource, seconds: float) -> tuple[float, dict]:
    suit = AvrSuit(motion, realtime=False, build=images).start()
    server = TcpServer(suit).start()
    link = SuitLink(server.url)
    try:
        link.start()
        first = suit.wait_status(lambda s: bool(s["streams"]), 60)
        frames = 0
        while suit.status["sim_s"] < first["sim_s"] + seconds:
            frames += len(link.read_frames(0.1))
        last = suit.status
        link.stop()
    finally:
        link.close()
        server.stop()
        final = suit.close()
    return factor_between(first, last), final


def real_time_with_the_pipeline(images, motion: MotionSource, seconds: float) -> dict:
    suit = AvrSuit(motion, realtime=True, build=images).start()
    server = TcpServer(suit).start()
    source = SuitFrameSource(server.url)
    try:
        source.connect()
        t0 = time.monotonic()
        start = suit.status
        frames = 0
        while time.monotonic() - t0 < seconds:
            frames += len(source.read(0.1))
        host_s = time.monotonic() - t0
        end = suit.status
        silent = any(new is LinkState.SILENT for _, _, new in source.history)
    finally:
        source.close()
        server.stop()
        final = suit.close()
    stream = final["streams"][-1]
    return {"factor": factor_between(start, end), "frames": frames, "host_s": host_s,
            "per_sim_s": (stream["frames"] - 1) / (stream["last_s"] - stream["start_s"]),
            "silent": silent, "links_lost": source.links_lost, "final": final}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per run")
    args = ap.parse_args()
    images = build()
    motion = MotionSource.simulated(seed=1, duration_s=max(args.seconds + 5, 20))
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"host: {os.cpu_count()} cores, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")

    idle = idle_factor(images, motion, min(args.seconds, 5.0))
    fast, final = streaming_unthrottled(images, motion, args.seconds)
    print(f"real-time factor, unthrottled: streaming {fast:5.2f}   "
          f"(reference, same run: the suit idle {idle:5.2f})")

    rt = real_time_with_the_pipeline(images, motion, args.seconds)
    print(f"real-time factor, real time:   {rt['factor']:5.2f}   frames per host second "
          f"{rt['frames'] / rt['host_s']:5.1f} (per simulated second "
          f"{rt['per_sim_s']:6.2f}); watchdog called it silent: "
          f"{'YES' if rt['silent'] else 'no'}, links lost {rt['links_lost']}")

    period = final["period_us"]
    busy = final["arbiter_busy_us"]
    print(f"period {period['mean']:9.3f} us (min {period['min']:.3f}, max {period['max']:.3f}) "
          f"over {period['n']} frames; late frames {final['late_frames']}")
    print(f"arbiter busy span per frame {busy['mean'] / 1000:5.2f} ms, worst "
          f"{busy['max'] / 1000:5.2f} ms, of 20 ms")
    print(f"cycles per 20 ms frame, of {BUDGET:,}:")
    for board, f in final["cycles_per_frame"].items():
        print(f"  {board:<9} mean {f['mean']:9,.0f} ({f['mean'] / BUDGET:5.1%})   "
              f"worst {f['max']:9,.0f} ({f['max'] / BUDGET:5.1%})")
    wires = final["counters"]
    print(f"wire faults: misrouted {wires['misrouted']}, cut {wires['cut']}, host bytes lost "
          f"{wires['host_bytes_lost']}, USART overruns {sum(wires['overruns'])}, framing "
          f"errors {wires['framing_errors']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
