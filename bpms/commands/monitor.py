"""``bpms monitor [PORT_OR_URL]``: connect to the suit and print one status line per second.

Without a port, the suit is discovered (every candidate serial port is sent 0x02 and must
answer ``BPMS``); when nothing answers, the simulated suit is started in-process on a
pseudo-terminal instead. The battery is read once, the stream started (its stale first frame
dropped), then every second: elapsed time, frame rate (Hz, over the last second), frames,
resyncs, discarded bytes, error bits and the battery voltage. Ctrl-C (or ``--seconds``) stops
the stream, closes the port and exits 0.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time

import numpy as np

from bpms.commands import CliError
from bpms.commands.sim import add_sim_options, build_arbiter
from bpms.firmware.sim.server import local_server
from bpms.io.frames import FRAME_DTYPE, error_words_to_flags
from bpms.io.link import DEFAULT_BAUD, LinkError, SuitLink, discover_suit, list_candidate_ports
from bpms.io.options import SerialOptions


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    defaults = SerialOptions()
    p = sub.add_parser("monitor", help="connect to the suit and print its status every second",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("port", nargs="?", metavar="PORT_OR_URL",
                   help="serial port or pyserial URL (default: discover the suit)")
    p.add_argument("--seconds", type=float, default=None, metavar="N",
                   help="stop after N seconds (default: until Ctrl-C)")
    p.add_argument("--baud", type=int, default=defaults.baud or DEFAULT_BAUD,
                   help=f"baud rate (nominal over Bluetooth; default {defaults.baud})")
    p.add_argument("--timeout", type=float, default=defaults.discovery_timeout_s,
                   metavar="S", help="wait for a reply this long, s "
                                     f"(default {defaults.discovery_timeout_s:g})")
    p.add_argument("--no-sim", action="store_true",
                   help="fail instead of starting the simulated suit when none is found")
    add_sim_options(p)
    p.set_defaults(run=run)
    return p


def count_error_bits(frames: list[bytes]) -> int:
    """Set error bits in whole frames (vectorised)."""
    if not frames:
        return 0
    words = np.frombuffer(b"".join(frames), dtype=FRAME_DTYPE)["clusters"]["error"]
    return int(error_words_to_flags(words).sum())


def _sigterm(signum, frame) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    server = None
    port = args.port
    if port is None:
        candidates = list_candidate_ports()
        port = discover_suit(candidates, timeout_s=args.timeout, baud=args.baud)
        if port is None:
            if args.no_sim:
                raise CliError(f"no suit answered on {len(candidates)} candidate port(s)")
            server = local_server(build_arbiter(args)).start()
            port = server.address
            print(f"no suit answered on {len(candidates)} candidate port(s); "
                  f"started the simulated suit on {port}", flush=True)
    signal.signal(signal.SIGTERM, _sigterm)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # even when started in background
    try:
        return _monitor(port, args)
    finally:
        if server is not None:
            server.stop()


def _monitor(port: str, args: argparse.Namespace) -> int:
    try:
        link = SuitLink(port, baud=args.baud, reply_timeout_s=args.timeout)
    except LinkError as exc:
        raise CliError(str(exc)) from None
    try:
        try:
            link.identify()
            volts = link.battery_volts()
            print(f"connected to the suit on {port}; battery {volts:.2f} V", flush=True)
            link.start()
        except LinkError as exc:
            raise CliError(str(exc)) from None
        try:
            _status_loop(link, volts, args.seconds)
        except LinkError as exc:
            raise CliError(f"link lost: {exc}") from None
    except KeyboardInterrupt:
        pass
    finally:
        try:
            if link.streaming:
                link.stop()
        except (LinkError, KeyboardInterrupt) as exc:
            print(f"bpms monitor: warning: {exc or 'interrupted while stopping'}",
                  file=sys.stderr)
        link.close()
    return 0


def _status_loop(link: SuitLink, volts: float, seconds: float | None) -> None:
    t0 = time.monotonic()
    next_line = t0 + 1.0
    frames = error_bits = 0
    window_frames = 0
    window_t0 = t0
    while True:
        got = link.read_frames(0.05)
        frames += len(got)
        window_frames += len(got)
        error_bits += count_error_bits(got)
        now = time.monotonic()
        if now >= next_line:
            st = link.parser.stats
            rate = window_frames / (now - window_t0)
            print(f"t {now - t0:6.1f} s  rate {rate:5.1f} Hz  frames {frames:7d}  "
                  f"resyncs {st.resyncs:4d}  discarded {st.discarded_bytes:6d} B  "
                  f"error bits {error_bits:5d}  battery {volts:.2f} V", flush=True)
            window_frames, window_t0 = 0, now
            next_line += 1.0
            if next_line < now:  # fell behind (suspended): no burst of lines
                next_line = now + 1.0
        if seconds is not None and now - t0 >= seconds:
            return
