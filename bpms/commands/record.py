"""``bpms record [PORT] [-o DIR] [--name NAME] [--udp HOST:PORT]``: the headless field recorder.

Records raw frames (and, with ``--filtered``, the filtered file) with no GUI, printing one
status line per second; Ctrl-C (or SIGTERM, or ``--seconds``) closes the files cleanly. Data
reach the disk at least once per second, so even a power cut keeps all but the last second.
A lost link is reported (state silent or gone) and reconnected by itself; the same file goes
on (with a gap). A write error (disk full, folder removed, device unplugged) is shown in every
later status line; the final line gives the frames on the disk and the frames lost, and the
exit code is 1. Without PORT the suit is discovered (a real suit only); ``--sim`` records
the simulated suit instead, and then every status line says SIMULATED.

Field commands, typed on standard input (for use over SSH), each followed by Enter:

  z        Reset Zero (the subject stands in the calibration pose)
  v        alignment off/on: the output angles corrected by Reset Zero or the sensor angles
  m TEXT   a marker note, stored in the recording at this frame
  p [POSTURE]  pose calibration in a declared posture (--posture, or the one given here:
           suit, neutral or 'elbow_r.flexion=15,...'; docs/pose-calibration.md)
  f [SECONDS]  functional pose calibration: stand still 0.5 s, then knee and elbow flexions,
           an arm swing, a few steps for SECONDS (default 30)

Each goes into the raw recording at the frame it applies at, the event lines and the LSL event
stream; ``bpms filter`` and ``bpms replay`` of the recording apply them where they happened.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, number, stop_on_signals
from bpms.commands.sim import add_sim_options, build_arbiter
from bpms.firmware.sim.server import local_server
from bpms.io.link import LinkError
from bpms.io.rawfile import RecordingError
from bpms.io.udp.addresses import UdpConfigError
from bpms.pipeline.streams import add_stream_arguments, start_streams, stop_streams

if TYPE_CHECKING:  # the pipeline (numba, the filter bank) loads when recording starts, so
    from bpms.pipeline.session import (  # `bpms --help` and the GUI start quickly
        LiveStatus,
        RecordingStatus,
    )


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("record", help="record the suit without a GUI (field recorder)")
    p.add_argument("port", nargs="?", metavar="PORT_OR_URL",
                   help="serial port or pyserial URL (default: discover the suit)")
    p.add_argument("-o", "--output", default=None, metavar="DIR",
                   help="folder for the recordings (default: the options' logging.directory, "
                        "else the per-user recordings folder)")
    p.add_argument("--name", default=None, help="file name stem (default: a time stamp)")
    p.add_argument("--notes", default="", help="free text stored in the raw file's header")
    p.add_argument("--posture", default=None, metavar="POSTURE",
                   help="the declared posture of the field command p (default neutral): "
                        "suit or 'elbow_r.flexion=15,...' (docs/pose-calibration.md)")
    p.add_argument("--subject", default=None, metavar="PROFILE",
                   help="the subject's profile, stored in the header and used for the body "
                        "model: 'id=S01,height=1.80,mass=75,thigh=0.46' or a TOML file "
                        "(docs/subject.md)")
    p.add_argument("--udp", action="append", default=[], metavar="HOST:PORT",
                   help="also forward the live stream over UDP (repeatable)")
    p.add_argument("--filtered", action="store_true", help="also record the filtered file")
    add_stream_arguments(p)  # --lsl, --mvn (i16)
    p.add_argument("--lsl-wait", type=number(float, 0, LONGEST_S), default=0.0, metavar="SECONDS",
                   help="with --lsl: wait up to this long for a consumer (e.g. LabRecorder) on "
                        "every LSL stream before recording (the suit streams meanwhile)")
    p.add_argument("--seconds", type=number(float, 0, LONGEST_S, above=True), default=None,
                   help="stop after this many seconds")
    p.add_argument("--options", default=None, metavar="FILE", help="options file (TOML)")
    p.add_argument("--sim", action="store_true", help="record the simulated suit")
    add_sim_options(p)
    return p


def status_line(status: LiveStatus, elapsed: float) -> str:
    """One status line: state, rate (Hz), frames, recording size, errors, link events, frames
    not filtered and the processing backlog (bpms.pipeline.health); then why the link is down,
    a write error and SIMULATED, whenever they apply."""
    src = status.source
    rec = status.recording
    raw = (f"raw {rec.raw_bytes / 1e3:8.1f} kB {rec.raw_path.name}"
           if rec is not None and rec.raw_path is not None else "raw -")
    battery = f"{src.battery_v:.2f} V" if src.battery_v is not None else "-"
    line = (f"t {elapsed:7.1f} s  {src.state:<10}  {status.rate_hz:5.1f} Hz  "
            f"frames {status.frames:7d}  {raw}  error bits {status.error_bits:5d}  "
            f"resyncs {src.resyncs:3d}  links lost {src.counters.get('links_lost', 0)}  "
            f"battery {battery}  {status.health_line()}")
    if status.reinit_count:
        line += f"  filter re-inits {status.reinit_count}"
    if status.reset_zero.startswith("waiting"):
        line += f"  Reset Zero {status.reset_zero}"
    if src.state != "streaming" and src.reason:
        line += f"  ({src.reason})"
    if rec is not None and rec.error:
        line += f"  WRITE ERROR, not recording: {rec.error}"
    if rec is not None and rec.filtered_stopped:
        line += f"  FILTERED FILE STOPPED: {rec.filtered_stopped}"
    if src.simulated:
        line += "  SIMULATED"
    return line


def summary(status: RecordingStatus) -> tuple[str, int]:
    """The closing line and the exit code (1 when the recording failed)."""
    if status.error:
        return (f"recording FAILED: {status.error}; {status.raw_on_disk} frames on disk in "
                f"{status.raw_path}, {status.raw_lost} frames lost", 1)
    lost = f", {status.raw_lost} frames lost" if status.raw_lost else ""
    return f"recorded {status.raw_on_disk} frames to {status.raw_path}{lost}", (1 if lost else 0)


FIELD_HELP = ("field commands: z + Enter = Reset Zero, v = alignment off/on, m TEXT = marker, "
              "p [POSTURE] = pose calibration in a declared posture, f [SECONDS] = "
              "functional pose calibration")


def field_command(session, line: str, posture: str | None = None) -> str | None:
    """Run one line typed on standard input; the reply to print (None: nothing to say)."""
    text = line.strip()
    if not text:
        return None
    word, _, rest = text.partition(" ")
    if word == "z":
        session.reset_zero("manual")
        return "Reset Zero at the next frame"
    if word == "p":
        from bpms.filter.posture_calibration import parse_posture

        text = rest.strip() or posture or "neutral"
        try:
            declared = parse_posture(text)
        except ValueError as exc:
            return str(exc)
        session.calibrate_posture(declared)
        return f"pose calibration in the declared posture ({text}) at the next frame"
    if word == "f":
        try:
            seconds = float(rest) if rest.strip() else 30.0
        except ValueError:
            seconds = -1.0
        if not 5.0 <= seconds <= 600.0:
            return "f wants the movements' length in seconds, 5 to 600: f 30"
        session.calibrate_functional(seconds)
        return (f"functional calibration: stand still 0.5 s, then {seconds:g} s of knee and "
                "elbow flexions, an arm swing, a few steps")
    if word == "v":
        session.set_corrected_output(None)
        return "alignment switched at the next frame"
    if word == "m":
        if not rest.strip():
            return "a marker needs a text: m TEXT"
        session.marker(rest.strip())
        return None
    return f"unknown command {word!r}; {FIELD_HELP}"


def _read_commands(session, stream, posture: str | None = None) -> None:
    """Standard input, line by line, until it ends (a recorder started without one, or with
    /dev/null, simply has no field commands)."""
    try:
        for line in stream:
            reply = field_command(session, line, posture)
            if reply:
                print(reply, flush=True)
    except (OSError, ValueError):  # closed under the thread at exit
        return


def run(args: argparse.Namespace) -> int:
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.io.defaults import announce_factory, calibration_or_default, options_or_default
    from bpms.pipeline.session import LiveSession
    from bpms.pipeline.sources import SuitFrameSource

    # explicit file > the user's default > factory (a one-line notice when factory)
    options = options_or_default(args.options, announce=False)
    if args.posture:
        from bpms.filter.posture_calibration import parse_posture

        try:
            parse_posture(args.posture)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    profile = None
    if args.subject:
        from bpms.io.subject import SubjectProfile

        try:
            profile = SubjectProfile.parse(args.subject)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        options.body = profile.body_options()
    table = calibration_or_default(args.calibration, announce=False)
    for problem in (*options.problems, *table.problems):
        print(f"warning: {problem}", file=sys.stderr)
    # the calibration the header stores is the one the processor uses: --calibration (for a
    # real suit as for the simulated one), else the user's default
    processor = BodyPoseProcessor(args.calibration or None, options)
    server = None
    port = args.port
    if args.sim:
        server = local_server(build_arbiter(args)).start()
        port = server.address
        print(f"recording the SIMULATED suit on {port}", flush=True)
    source = SuitFrameSource(port, options.serial, simulated=args.sim)
    # the kernels loaded before the suit streams: on a busy computer loading them takes
    # longer than the suit holds frames for a host that does not read (docs/pipeline.md)
    from bpms.pipeline.steady import warm_up

    warm_up(processor)  # (the session freezes the heap when it starts, as always)
    try:
        source.connect()
    except LinkError as exc:
        if server is not None:
            server.stop()
        raise CliError(str(exc)) from None
    # the one-line notice about missing defaults, now that recording really starts
    announce_factory(options=not args.options, calibration=not args.calibration)
    folder = Path(args.output) if args.output else None  # None: options, else per-user folder
    session = LiveSession(source, options, processor, recording_dir=folder, notes=args.notes)
    if profile is not None:
        session.header_extra["subject"] = profile.to_header()
    stop_on_signals()
    recording = None
    bridges: list = []
    wait = args.lsl_wait if args.lsl else 0.0

    def start_recording():
        try:
            started = session.start_logging(raw=True, filtered=args.filtered, name=args.name)
            if args.udp:
                session.start_forwarding(args.udp)
        except (RecordingError, UdpConfigError, OSError, ValueError) as exc:
            raise CliError(str(exc)) from None
        return started

    try:
        try:
            bridges = start_streams(session, args.lsl, args.mvn)
        except (OSError, ValueError) as exc:
            raise CliError(str(exc)) from None
        if not wait:
            recording = start_recording()
        session.start()
        if wait:  # the session runs (frames reach LSL), the files begin once consumers are in
            from bpms.pipeline.lsl import wait_for_consumers

            print(f"waiting up to {wait:g} s for LSL consumers", flush=True)
            wait_for_consumers(bridges, wait)
            recording = start_recording()
        print(f"recording to {recording.raw_path}"
              + (f" and {recording.filtered_path}" if recording.filtered_path else ""),
              flush=True)
        if sys.stdin is not None and not sys.stdin.closed:
            print(FIELD_HELP, flush=True)
            threading.Thread(target=_read_commands, args=(session, sys.stdin, args.posture),
                             name="bpms-field-commands", daemon=True).start()
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
        session.stop()  # closes the raw file: `recording` then holds the final counts
        stop_streams(bridges)
        if server is not None:
            server.stop()
    if recording is None:  # stopped while waiting for LSL consumers
        return 130
    line, code = summary(recording)
    print(line, flush=True, file=sys.stderr if code else sys.stdout)
    return code
