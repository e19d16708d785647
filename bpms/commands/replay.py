"""``bpms replay RAW_FILE [--udp HOST:PORT] [--lsl] [--mvn HOST:PORT] [--speed S]``: stream a
recording as if it were live.

The recording runs through the same pipeline as a live suit (filters, Reset Zero, joint
angles, body model), so every output the live path has is sent: UDP raw frames and poses
(docs/udp.md), LSL streams (docs/lsl.md) and the MVN-compatible stream (docs/mvn.md). The
calibration and options stored in the recording are used unless ``--options`` is given (the
one door, docs/opening-recordings.md), and the events recorded live (Reset Zero, alignment,
filter and gain changes, markers) are applied at their frames, so every pose equals the live
session's (``--reset-zero`` chooses otherwise). At every speed, as fast as possible included,
every frame gives one pose. With the shared key set (``BPMS_UDP_KEY``) every datagram is
signed (docs/udp.md).
"""

from __future__ import annotations

import argparse
import sys
import time

from bpms.analysis.cli_support import add_reset_zero_option
from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, number, warn
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.rawfile import RawFileError
from bpms.io.recordings import open_replay

#: Seconds without a frame processed, after the last was read and none waits, before replay
#: ends saying which frames were lost (a processing error; it never ends otherwise).
STALL_S = 5.0


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    from bpms.pipeline.streams import add_stream_arguments

    p = sub.add_parser("replay", help="stream a raw recording (UDP, LSL, MVN) as if it were live")
    p.add_argument("raw_file", help="raw recording (.bpmsraw, or a legacy pickled .txt)")
    p.add_argument("--udp", action="append", default=[], metavar="HOST:PORT",
                   help="UDP destination of raw frames and poses (repeatable; multicast "
                        "groups allowed)")
    add_stream_arguments(p)
    p.add_argument("--lsl-wait", type=number(float, 0, LONGEST_S), default=0.0, metavar="SECONDS",
                   help="with --lsl: wait up to this long for a consumer (e.g. LabRecorder) "
                        "on every LSL stream before playing")
    p.add_argument("--speed", type=number(float, 0, 1000), default=1.0,
                   help="playback speed, × real time (0 = as fast as possible; default 1)")
    p.add_argument("--from", dest="start_s", type=number(float, 0, LONGEST_S),
                   default=0.0, metavar="SECONDS",
                   help="start this many seconds into the recording")
    p.add_argument("--loop", action="store_true", help="start again at the end")
    p.add_argument("--options", default=None, metavar="FILE",
                   help="options file (default: the options stored in the recording)")
    add_reset_zero_option(p)
    return p


def _opened(path: str, options_path: str | None, reset_zero):
    """The recording through the one door (:mod:`bpms.filter.door`): the given options, else
    the recording's calibration and options, else the user's default, else factory; the
    sources line goes to stderr."""
    from bpms.filter.door import open_for_processing

    try:
        opened = open_for_processing(path, options=options_path, reset_zero=reset_zero)
    except (RawFileError, OSError, ValueError) as exc:
        raise CliError(str(exc)) from None
    if not opened.has_raw:
        raise CliError(f"{path}: a filtered file; give a raw recording")
    print(f"bpms replay: {opened.sources_line()}", file=sys.stderr)
    warn("replay", opened.problems)
    return opened


def run(args: argparse.Namespace) -> int:
    from bpms.io.replay import ReplaySource
    from bpms.io.udp.addresses import UdpConfigError
    from bpms.pipeline.session import LiveSession
    from bpms.pipeline.streams import start_streams, stop_streams

    if 0 < args.speed < 0.01:  # nan, inf and < 0 are refused by the option's type
        raise CliError("--speed must be 0 (as fast as possible) or 0.01 to 1000")
    if not (args.udp or args.lsl or args.mvn):
        raise CliError("nothing to send: give --udp HOST:PORT, --lsl and/or --mvn HOST:PORT")
    try:  # native (read from disk as it plays) or legacy; no valid frame is an error too
        recording = open_replay(args.raw_file)
    except RawFileError as exc:
        raise CliError(str(exc)) from None
    for problem in recording.problems:
        print(f"warning: {problem}", file=sys.stderr)
    if len(recording) == 0:
        raise CliError(f"{args.raw_file}: the recording holds no frames")
    if args.start_s >= recording.duration_s:  # nothing would play
        raise CliError(f"--from {args.start_s:g} s: the recording lasts "
                       f"{recording.duration_s:.1f} s")
    opened = _opened(args.raw_file, args.options, args.reset_zero)
    processor = opened.processor
    shown = len(opened.problems)
    events = opened.replay_events(recording.events)
    warn("replay", opened.problems[shown:])  # (a lost Reset Zero: the automatic one instead)
    source = ReplaySource(recording, speed=args.speed or None, autoplay=False, events=events)
    source.seek(seconds=args.start_s)
    session = LiveSession(source, processor.options, processor)
    bridges: list = []
    try:
        if args.udp:
            session.start_forwarding(args.udp)
        period = FRAME_PERIOD_S / args.speed if args.speed else FRAME_PERIOD_S
        bridges = start_streams(session, args.lsl, args.mvn, period)
    except (UdpConfigError, ValueError, OSError) as exc:
        stop_streams(bridges)
        session.stop()
        raise CliError(str(exc)) from None
    targets = [*args.udp, *(["LSL"] if args.lsl else []), *(f"MVN {m}" for m in args.mvn)]
    if args.lsl and args.lsl_wait > 0:
        print(f"waiting up to {args.lsl_wait:g} s for LSL consumers", flush=True)
        from bpms.pipeline.lsl import wait_for_consumers

        wait_for_consumers(bridges, args.lsl_wait)
    print(f"replaying {len(recording)} frames ({recording.duration_s:.1f} s) "
          f"to {', '.join(targets)} at {'full speed' if not args.speed else f'{args.speed}×'}",
          flush=True)
    session.start()
    source.play()
    last = time.monotonic()
    stalled = (0, time.monotonic())  # (frames processed, since when)
    unprocessed = 0
    try:
        while True:
            time.sleep(0.05)
            status = session.status()
            done = source.ended and status.processed >= status.frames
            now = time.monotonic()
            if status.processed != stalled[0] or status.processing_backlog:
                stalled = (status.processed, now)
            elif source.ended and not done and now - stalled[1] > STALL_S:
                # every frame was read, none is waiting, and the rest were never processed
                # (an error in the pipeline): end, saying so, rather than wait for ever
                unprocessed = status.frames - status.processed
                done = True
            if now - last >= 1.0 or done:
                print(f"t {source.position_s:7.1f} s  frames {status.frames:7d}  "
                      f"processed {status.processed:7d}  sent {status.forwarded:7d} "
                      f"(poses {status.forwarded_poses}, raw/zero "
                      f"{status.forwarded - status.forwarded_poses})  "
                      f"send errors {status.forward_errors}  "
                      f"no listener {status.forward_refused}", flush=True)
                last = now
            if done:
                if not args.loop:
                    break
                source.seek(0)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    finally:
        session.stop()  # every processed frame is published before the bridges drain
        stop_streams(bridges)
    if unprocessed:
        why = "; ".join(e for e in status.events if "error" in e)[-300:]
        print(f"bpms replay: {unprocessed} of {status.frames} frames were not processed"
              + (f" ({why})" if why else ""), file=sys.stderr)
        return 1
    return 0
