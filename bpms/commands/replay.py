"""``bpms replay RAW_FILE --udp HOST:PORT [--speed S]``: stream a recording to the network as
if it were live (the same datagrams as the live UDP server)."""

from __future__ import annotations

import argparse
import sys
import time

from bpms.commands import CliError
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.rawfile import RawFileError, RawRecording
from bpms.io.recordings import open_recording
from bpms.io.replay import ReplaySource
from bpms.io.udp import UdpConfigError, UdpForwarder


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("replay", help="stream a raw recording over UDP as if it were live",
                       description=__doc__)
    p.add_argument("raw_file", help="raw recording (.bpmsraw, or a legacy pickled .txt)")
    p.add_argument("--udp", action="append", required=True, metavar="HOST:PORT",
                   help="destination (repeat for several; multicast groups allowed)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="playback speed, × real time (0 = as fast as possible; default 1)")
    p.add_argument("--from", dest="start_s", type=float, default=0.0, metavar="SECONDS",
                   help="start this many seconds into the recording")
    p.add_argument("--loop", action="store_true", help="start again at the end")
    p.set_defaults(run=run)
    return p


def load_recording(path: str) -> RawRecording:
    """A native or legacy raw recording, or a CliError naming the problem."""
    try:
        return open_recording(path)
    except RawFileError as exc:
        raise CliError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    if args.speed < 0:
        raise CliError("--speed must be ≥ 0 (0 = as fast as possible)")
    recording = load_recording(args.raw_file)
    for problem in recording.problems:
        print(f"warning: {problem}", file=sys.stderr)
    if len(recording) == 0:
        raise CliError(f"{args.raw_file}: the recording holds no frames")
    try:
        forwarder = UdpForwarder(args.udp)
    except UdpConfigError as exc:
        raise CliError(str(exc)) from None
    source = ReplaySource(recording, speed=args.speed or None)
    source.seek(seconds=args.start_s)
    print(f"replaying {len(recording)} frames ({len(recording) * FRAME_PERIOD_S:.1f} s) "
          f"to {', '.join(args.udp)} at {'full speed' if not args.speed else f'{args.speed}×'}",
          flush=True)
    last = time.monotonic()
    try:
        while True:
            for event in source.read(0.2):
                forwarder.send_frame(event.frame, event.index * FRAME_PERIOD_S)
            now = time.monotonic()
            if now - last >= 1.0 or source.ended:
                st = forwarder.stats
                print(f"t {source.position_s:7.1f} s  frames sent {st.frames:7d}  "
                      f"send errors {st.errors}", flush=True)
                last = now
            if source.ended:
                if not args.loop:
                    break
                source.seek(0)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    finally:
        forwarder.close()
        source.close()
    return 0
