"""``bpms monitor [PORT_OR_URL]``: connect to the suit and print one status line per second.

Without a port, the suit is discovered (every candidate serial port is sent 0x02 and must
answer ``BPMS``); when nothing answers, monitor says so and exits 2: only ``--sim`` starts
the simulated suit, and then every line says SIMULATED. The battery is read once, the stream
started (its stale first frame dropped), then every second: elapsed time, frame rate (Hz,
over the last second), frames, resyncs, discarded bytes, error bits and the battery voltage,
followed by the link state and its reason whenever the link is not streaming. The link is
watched like ``bpms record`` watches it: a silent suit is probed and restarted after a
power-cycle, a dropped port or TCP connection is reopened. Ctrl-C (or ``--seconds``) stops
the stream, closes the port and exits 0.
"""

from __future__ import annotations

import argparse
import math
import threading
import time
from typing import TYPE_CHECKING

import numpy as np

from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, number, stop_on_signals
from bpms.commands.sim import add_sim_options, build_arbiter
from bpms.firmware.sim.server import local_server
from bpms.io.events import SourceStatus
from bpms.io.frames import decode_frames
from bpms.io.link import DEFAULT_BAUD, LinkError, discover_suit, list_candidate_ports
from bpms.io.options import SerialOptions, UdpOptions

if TYPE_CHECKING:
    from collections.abc import Callable

    from bpms.pipeline.sources import SuitFrameSource, UdpFrameSource


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    defaults = SerialOptions()
    p = sub.add_parser("monitor", help="connect to the suit and print its status every second")
    p.add_argument("port", nargs="?", metavar="PORT_OR_URL",
                   help="serial port or pyserial URL (default: discover the suit)")
    p.add_argument("--seconds", type=number(float, 0, LONGEST_S, above=True),
                   default=None, metavar="N",
                   help="stop after N seconds (default: until Ctrl-C)")
    p.add_argument("--baud", type=number(int, 1, 10_000_000),
                   default=defaults.baud or DEFAULT_BAUD,
                   help=f"baud rate (nominal over Bluetooth; default {defaults.baud})")
    p.add_argument("--timeout", type=number(float, 0, LONGEST_S, above=True),
                   default=defaults.discovery_timeout_s,
                   metavar="S", help="wait for a reply this long, s "
                                     f"(default {defaults.discovery_timeout_s:g})")
    p.add_argument("--listen", metavar="HOST:PORT", nargs="?", const=UdpOptions().listen,
                   default=None,
                   help="monitor a UDP stream (bpms record --udp, the GUI's UDP server) "
                        f"instead of the suit; default address {UdpOptions().listen} "
                        "(all interfaces). The shared key, if any, comes from the "
                        "BPMS_UDP_KEY environment variable")
    p.add_argument("--sim", action="store_true",
                   help="monitor the simulated suit (every status line says SIMULATED)")
    add_sim_options(p)
    return p


def count_error_bits(frames: list[bytes]) -> int:
    """Sensor error flags set in whole frames, as the resynchronising reader hands them over
    (markers in place), read by the one frame decoder (:func:`bpms.io.frames.decode_frames`)."""
    if not frames:
        return 0
    return int(np.count_nonzero(decode_frames(b"".join(frames)).errors))


def run(args: argparse.Namespace) -> int:
    from bpms.pipeline.sources import SuitFrameSource

    if args.listen is not None:
        return _monitor_udp(args)
    server = None
    port = args.port
    if args.sim:
        server = local_server(build_arbiter(args)).start()
        port = server.address
    elif port is None:
        candidates = list_candidate_ports()
        port = discover_suit(candidates, timeout_s=args.timeout, baud=args.baud)
        if port is None:
            raise CliError(f"no suit answered on {len(candidates)} candidate port(s) (is it "
                           "paired, switched on, charged? --sim monitors the simulated suit)")
    stop_on_signals()
    serial = SerialOptions(baud=args.baud, discovery_timeout_s=args.timeout)
    source = SuitFrameSource(port, serial, simulated=server is not None)
    try:
        try:
            source.connect()
        except LinkError as exc:
            raise CliError(str(exc)) from None
        status = source.status()
        volts = f"{status.battery_v:.2f} V" if status.battery_v is not None else "unknown"
        what = "the SIMULATED suit" if source.simulated else "the suit"
        print(f"connected to {what} on {port}; battery {volts}", flush=True)
        _status_loop(source, args.seconds)
    except KeyboardInterrupt:
        pass
    finally:
        source.close()  # stops the stream (best effort)
        if server is not None:
            server.stop()
    return 0


def status_line(elapsed: float, rate: float, frames: int, error_bits: int,
                status: SourceStatus) -> str:
    """One status line; the link state and reason follow while it is not streaming."""
    battery = f"{status.battery_v:.2f}" if status.battery_v is not None else "-"
    line = (f"t {elapsed:6.1f} s  rate {rate:5.1f} Hz  frames {frames:7d}  "
            f"resyncs {status.resyncs:4d}  discarded {status.discarded_bytes:6d} B  "
            f"error bits {error_bits:5d}  battery {battery} V")
    if status.state != "streaming":
        line += f"  {status.state.upper()}" + (f": {status.reason}" if status.reason else "")
    if status.simulated:
        line += "  SIMULATED"
    return line


class _Reader(threading.Thread):
    """Reads the source and counts, so that a read blocked in a probe or a reconnection
    (up to ``--timeout`` s each) never holds back the status line."""

    def __init__(self, source: SuitFrameSource | UdpFrameSource) -> None:
        super().__init__(name="bpms-monitor-reader", daemon=True)
        self.source = source
        self.lock = threading.Lock()
        self.frames = self.error_bits = 0
        self.failure: BaseException | None = None
        self._stop = threading.Event()

    def run(self) -> None:
        try:
            while not self._stop.is_set():
                got = [e.frame for e in self.source.read(0.05)]
                bits = count_error_bits(got)
                with self.lock:
                    self.frames += len(got)
                    self.error_bits += bits
        except BaseException as exc:  # shown by the main thread, which then stops
            self.failure = exc

    def counts(self) -> tuple[int, int]:
        with self.lock:
            return self.frames, self.error_bits

    def stop(self) -> None:
        self._stop.set()


def _status_loop(source: SuitFrameSource | UdpFrameSource, seconds: float | None,
                 line: Callable[[float, float, int, int, SourceStatus], str] = status_line
                 ) -> None:
    """One line per second from the main thread, whatever the reader waits for; ``line``
    makes it of elapsed time, rate, frames, error bits and the source's status."""
    reader = _Reader(source)
    reader.start()
    t0 = time.monotonic()
    next_line = t0 + 1.0
    shown = 0
    window_t0 = t0
    try:
        while reader.failure is None:
            end = t0 + seconds if seconds is not None else math.inf
            time.sleep(max(0.0, min(next_line, end) - time.monotonic()))
            now = time.monotonic()
            if now >= next_line:
                frames, error_bits = reader.counts()
                rate = (frames - shown) / (now - window_t0)
                print(line(now - t0, rate, frames, error_bits, source.status()), flush=True)
                shown, window_t0 = frames, now
                next_line += 1.0
                if next_line < now:  # fell behind (suspended): no burst of lines
                    next_line = now + 1.0
            if now >= end:
                return
        raise reader.failure
    finally:
        reader.stop()


def udp_status_line(elapsed: float, rate: float, frames: int, status: SourceStatus) -> str:
    """One status line of a UDP stream: counters, then the state and the warnings (another
    sender on this port or on this session, a sender that took over)."""
    c = status.counters
    line = (f"t {elapsed:6.1f} s  rate {rate:5.1f} Hz  frames {frames:7d}  lost {c['lost']}  "
            f"duplicated {c['duplicated']}  reordered {c['reordered']}  "
            f"malformed {c['malformed']}  foreign {c['foreign']}  "
            f"unauthenticated {c['unauthenticated']}  replayed {c['replayed']}  "
            f"implausible {c['implausible']}  conflicts {c['conflicts']}  stale {c['stale']}  "
            f"switches {c['takeovers']}  {status.state}")
    if status.warning:
        line += f"  WARNING: {status.warning}"
    return line


def _monitor_udp(args: argparse.Namespace) -> int:
    from bpms.io.udp.addresses import UdpConfigError
    from bpms.pipeline.sources import UdpFrameSource

    try:
        from bpms.io.defaults import default_options
        from bpms.io.udp.auth import shared_key

        udp = default_options(announce=False).udp
        source = UdpFrameSource(args.listen, key=shared_key(udp.key_file),
                                takeover_after_s=udp.takeover_after_s)
    except (UdpConfigError, OSError, ValueError) as exc:
        raise CliError(str(exc)) from None
    stop_on_signals()
    print(f"listening for UDP on {source.udp.listening}", flush=True)
    try:
        _status_loop(source, args.seconds, lambda elapsed, rate, frames, _bits, status:
                     udp_status_line(elapsed, rate, frames, status))
    except KeyboardInterrupt:
        pass
    finally:
        source.close()
    return 0
