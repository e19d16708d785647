"""``bpms record [PORT] [-o DIR] [--name NAME] [--udp HOST:PORT]``: the headless field recorder.

Records raw frames (and, with ``--filtered``, the filtered file) with no GUI, printing one
status line per second; Ctrl-C (or SIGTERM, or ``--seconds``) closes the files cleanly. Data
reach the disk at least once per second, so even a power cut keeps all but the last second.
A lost link is reported and reconnected by itself; the same file goes on (with a gap).
Without PORT the suit is discovered; ``--sim`` records the simulated suit instead.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bpms.commands import CliError
from bpms.commands.sim import add_sim_options, build_arbiter
from bpms.firmware.sim.server import PtyServer
from bpms.io.link import LinkError
from bpms.io.options import load_options
from bpms.io.rawfile import RecordingError
from bpms.io.udp import UdpConfigError

if TYPE_CHECKING:  # the pipeline (numba, the filter bank) loads when recording starts, so
    from bpms.pipeline.session import LiveStatus  # `bpms --help` and the GUI start quickly


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("record", help="record the suit without a GUI (field recorder)",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("port", nargs="?", metavar="PORT_OR_URL",
                   help="serial port or pyserial URL (default: discover the suit)")
    p.add_argument("-o", "--output", default=None, metavar="DIR",
                   help="folder for the recordings (default: the options' logging.directory)")
    p.add_argument("--name", default=None, help="file name stem (default: a time stamp)")
    p.add_argument("--notes", default="", help="free text stored in the raw file's header")
    p.add_argument("--udp", action="append", default=[], metavar="HOST:PORT",
                   help="also forward the live stream over UDP (repeatable)")
    p.add_argument("--filtered", action="store_true", help="also record the filtered file")
    p.add_argument("--seconds", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--options", default=None, metavar="FILE", help="options file (TOML)")
    p.add_argument("--sim", action="store_true", help="record the simulated suit")
    add_sim_options(p)
    p.set_defaults(run=run)
    return p


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def status_line(status: LiveStatus, elapsed: float) -> str:
    """One status line: state, rate (Hz), frames, recording size, errors, link events, frames
    not filtered and the processing backlog (bpms.pipeline.health)."""
    src = status.source
    rec = status.recording
    raw = (f"raw {rec.raw_bytes / 1e3:8.1f} kB {rec.raw_path.name}"
           if rec is not None and rec.raw_path is not None else "raw -")
    battery = f"{src.battery_v:.2f} V" if src.battery_v is not None else "-"
    return (f"t {elapsed:7.1f} s  {src.state:<10}  {status.rate_hz:5.1f} Hz  "
            f"frames {status.frames:7d}  {raw}  error bits {status.error_bits:5d}  "
            f"resyncs {src.resyncs:3d}  links lost {src.counters.get('links_lost', 0)}  "
            f"battery {battery}  {status.health_line()}")


def run(args: argparse.Namespace) -> int:
    from bpms.pipeline.session import LiveSession
    from bpms.pipeline.sources import SuitFrameSource

    options = load_options(args.options)
    for problem in options.problems:
        print(f"warning: {problem}", file=sys.stderr)
    server = None
    port = args.port
    if args.sim:
        server = PtyServer(build_arbiter(args)).start()
        port = server.path
        print(f"recording the simulated suit on {port}", flush=True)
    source = SuitFrameSource(port, options.serial)
    try:
        source.connect()
    except LinkError as exc:
        if server is not None:
            server.stop()
        raise CliError(str(exc)) from None
    folder = Path(args.output or options.logging.directory)
    session = LiveSession(source, options, recording_dir=folder, notes=args.notes)
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    recording = None
    try:
        try:
            recording = session.start_logging(raw=True, filtered=args.filtered,
                                              name=args.name)
            if args.udp:
                session.start_forwarding(args.udp)
        except (RecordingError, UdpConfigError, OSError) as exc:
            raise CliError(str(exc)) from None
        session.start()
        print(f"recording to {recording.raw_path}"
              + (f" and {recording.filtered_path}" if recording.filtered_path else ""),
              flush=True)
        t0 = time.monotonic()
        shown_events = 0
        while args.seconds is None or time.monotonic() - t0 < args.seconds:
            time.sleep(min(1.0, max(0.0, (args.seconds or 1e9) - (time.monotonic() - t0))))
            status = session.status()
            for event in status.events[shown_events:]:
                print(f"event: {event}", flush=True)
            shown_events = len(status.events)
            print(status_line(status, time.monotonic() - t0), flush=True)
    except KeyboardInterrupt:
        print("stopping", file=sys.stderr, flush=True)
    finally:
        session.stop()
        if server is not None:
            server.stop()
    print(f"recorded {session.status().frames} frames to {recording.raw_path}", flush=True)
    return 0
