"""``bpms sim --pty | --tcp PORT [--avr]``: run the simulated suit until Ctrl-C.

The first line printed is where to connect: the pseudo-terminal's device path (``/dev/pts/N``,
Linux and macOS) or ``socket://127.0.0.1:PORT`` (every platform, Windows included). The suit
speaks the arbiter protocol (docs/frame-format.md) and streams the scripted motion of
docs/simulated-suit.md, looped, with optional fault injection.

With ``--avr`` the suit's own firmware runs underneath: the arbiter and six cluster images,
each on a simulated ATmega328P at 16 MHz (simavr; Linux and macOS), fed the same motion
(docs/firmware.md, "The firmware in a simulator"). It prints its real-time factor and each
board's cycles per 20 ms frame every 5 simulated seconds and when it stops.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from typing import TYPE_CHECKING

from bpms.commands import CliError
from bpms.commands._shared import (
    LONGEST_S,
    number,
    refuse_special_output,
    stop_on_signals,
    warn,
)

if TYPE_CHECKING:  # numpy and the sensor model load when the suit is built, not for --help
    from bpms.firmware.sim.arbiter import Arbiter, MotionSource
    from bpms.firmware.sim.server import SimServer


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("sim", help="run the simulated suit on a pseudo-terminal or TCP port")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--pty", action="store_true",
                       help="serve on a new pseudo-terminal (its path is printed first; "
                            "Linux and macOS)")
    where.add_argument("--tcp", type=number(int, 0, 65535), metavar="PORT",
                       help="serve on 127.0.0.1:PORT (0 = any free port; the URL is printed)")
    add_sim_options(p)
    a = p.add_argument_group("the firmware in an AVR simulator")
    a.add_argument("--avr", action="store_true",
                   help="run the suit's firmware images on simulated ATmega328P boards "
                        "(simavr); --fast: as fast as this computer simulates")
    a.add_argument("--sensor-off", action="append", default=[], metavar="IMU:SENSOR:FROM:TO",
                   help="with --avr: that sensor chip (accel, mag or gyro of IMU 0-17) has no "
                        "power from FROM to TO simulated seconds after power-up (repeatable)")
    a.add_argument("--bus-stuck", action="append", default=[], metavar="CLUSTER:FROM:TO",
                   help="with --avr: cluster 0-5's I2C bus is held (SDA low) from FROM to TO "
                        "simulated seconds (repeatable)")
    a.add_argument("--report", metavar="FILE.json",
                   help="with --avr: write the simulator's final figures there (JSON)")
    return p


def add_sim_options(p: argparse.ArgumentParser) -> None:
    """Options of the simulated suit (shared with ``bpms monitor``'s fallback)."""
    g = p.add_argument_group("simulated suit")
    g.add_argument("--fast", action="store_true",
                   help="stream as fast as the host reads (default: real time, 50 frames/s)")
    g.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0,
                   help="seed of noise, mounting errors, faults")
    g.add_argument("--mag-disturbance", action="store_true",
                   help="a magnet beside the right forearm during the elbow moves")
    g.add_argument("--no-noise", action="store_true", help="noise-free sensors")
    g.add_argument("--no-mounting-errors", action="store_true",
                   help="IMUs mounted exactly along their segments")
    g.add_argument("--calibration", metavar="Calib.cfg",
                   help="the suit's true calibration (default: the factory table)")
    g.add_argument("--start-at", type=number(float, 0, LONGEST_S), default=0.0, metavar="SECONDS",
                   help="start the scripted motion this far in (docs/simulated-suit.md; e.g. "
                        "69.6: the subject is turning when the stream starts)")
    g.add_argument("--battery", type=number(float, 0, 10, above=True), default=3.35,
                   metavar="VOLTS",
                   help="battery voltage at start (default 3.35)")
    g.add_argument("--drain", type=number(float, 0, 100), default=0.1, metavar="V_PER_H",
                   help="battery drain, V per hour (default 0.1; floor 2.6 V)")
    b = p.add_argument_group("the simulated subject (docs/simulated-suit.md)")
    b.add_argument("--calibration-posture", default="neutral", metavar="POSTURE",
                   help="posture held in the still windows: neutral (default), suit "
                        "(pressure suit: shoulders abducted 20°, elbows 15°, hips 10°, knees 15° "
                        "flexed) or custom degrees of freedom 'elbow_r=15,knee_r=10'")
    b.add_argument("--mounting-error", type=number(float, 0, 45), default=None, metavar="DEG",
                   help="rms per axis of the IMUs' mounting misalignment, degrees (default 3)")
    b.add_argument("--height", type=number(float, 0.5, 2.5), default=None, metavar="M",
                   help="the subject's height, m: segment lengths scale from 1.73 m")
    b.add_argument("--segment", action="append", default=[], metavar="NAME=M",
                   help="one measured segment length, m (e.g. thigh=0.45); repeatable")
    b.add_argument("--functional", action="store_true",
                   help="begin with the functional-calibration movements")
    f = p.add_argument_group("fault injection (all off by default)")
    f.add_argument("--error-rate", type=number(float, 0, 1), default=0.0, metavar="P",
                   help="per frame, IMU and sensor: error bit set, values 0")
    f.add_argument("--drop-rate", type=number(float, 0, 1), default=0.0, metavar="P",
                   help="per frame: a run of 1-8 bytes is lost")
    f.add_argument("--corrupt-rate", type=number(float, 0, 1), default=0.0, metavar="P",
                   help="per frame: one byte is altered")
    f.add_argument("--bursty", action="store_true",
                   help="Bluetooth-like delivery: frames held back up to 300 ms, then a burst")
    f.add_argument("--silent-after", type=number(float, 0, LONGEST_S),
                   default=None, metavar="SECONDS",
                   help="go silent (a lost link) this long after start ...")
    f.add_argument("--silent-for", type=number(float, 0, LONGEST_S), default=5.0, metavar="SECONDS",
                   help="... for this long (default 5)")


def _probability(name: str, value: float) -> float:
    if not 0.0 <= value <= 1.0:
        raise CliError(f"{name} must be between 0 and 1, got {value:g}")
    return value


def build_source(args: argparse.Namespace) -> MotionSource:
    """The scripted motion's raw counts, from the sensor options."""
    from bpms.firmware.sim.arbiter import MotionSource
    from bpms.io.calib_file import load_calibration

    table = None
    if args.calibration:
        table = load_calibration(args.calibration)
        warn("sim", table.problems)
    source = MotionSource.simulated(
        seed=args.seed, mag_disturbance=args.mag_disturbance,
        mounting_errors=not args.no_mounting_errors, noise=not args.no_noise,
        calibration=table, **subject_kwargs(args))
    return source.starting_at(round(getattr(args, "start_at", 0.0) / 0.02))


def subject_kwargs(args: argparse.Namespace) -> dict:
    """``simulate()`` arguments of the simulated subject's options (CliError when bad)."""
    from bpms.firmware.sim.body import SubjectDimensions
    from bpms.firmware.sim.subject import parse_posture

    try:
        posture = parse_posture(getattr(args, "calibration_posture", None))
        lengths = {}
        for item in getattr(args, "segment", []) or []:
            name, sep, value = item.partition("=")
            if not sep:
                raise ValueError(f"--segment wants NAME=M, not {item!r}")
            lengths[name.strip()] = float(value)
        height = getattr(args, "height", None)
        subject = (SubjectDimensions.of_height(height or 1.73, **lengths)
                   if height is not None or lengths else None)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    error = getattr(args, "mounting_error", None)
    if error is not None and not 0.0 <= error <= 45.0:
        raise CliError(f"--mounting-error must be between 0 and 45 degrees, got {error:g}")
    return {"posture": posture, "subject": subject, "mounting_error_deg": error,
            "functional": bool(getattr(args, "functional", False))}


def build_arbiter(args: argparse.Namespace) -> Arbiter:
    """An :class:`Arbiter` streaming the scripted motion, configured from the options."""
    from bpms.firmware.sim.arbiter import Arbiter, Faults

    faults = Faults(
        error_rate=_probability("--error-rate", args.error_rate),
        drop_rate=_probability("--drop-rate", args.drop_rate),
        corrupt_rate=_probability("--corrupt-rate", args.corrupt_rate),
        bursty=args.bursty,
        silence_at_s=args.silent_after,
        silence_s=args.silent_for,
    )
    return Arbiter(build_source(args), faults, realtime=not args.fast, battery_v=args.battery,
                   battery_drain_v_per_h=args.drain, seed=args.seed)


def open_server(args: argparse.Namespace, suit) -> SimServer:
    """The transport the options ask for, serving ``suit`` (not started)."""
    from bpms.firmware.sim.server import PtyServer, TcpServer

    try:
        return PtyServer(suit) if args.pty else TcpServer(suit, port=args.tcp)
    except OSError as exc:
        raise CliError(f"cannot open the transport: {exc.strerror or exc}") from None


def run(args: argparse.Namespace) -> int:
    from bpms.firmware.sim.server import pty_available

    if args.pty and not pty_available():
        raise CliError("this system has no pseudo-terminals: use --tcp PORT "
                       "(then open socket://127.0.0.1:PORT)")
    if args.avr:
        return run_avr(args)
    if args.sensor_off or args.bus_stuck or args.report:
        raise CliError("--sensor-off, --bus-stuck and --report need --avr")
    arbiter = build_arbiter(args)
    server = open_server(args, arbiter)
    where = server.address
    print(where, flush=True)
    print(f"bpms sim: serving the simulated suit on {where} "
          f"({'fast' if args.fast else 'real time'}); Ctrl-C stops", file=sys.stderr, flush=True)
    stop_on_signals()
    server.start()
    try:
        while True:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    st = arbiter.stats
    print(f"bpms sim: stopped; {st.frames_sent} frames sent ({st.stale_frames} stale), "
          f"{server.frames_unread} dropped unread", file=sys.stderr)
    return 0


# ---------------------------------------------------------------- --avr
#: Options of the Python suit's fault injection, which the firmware does not have.
_NOT_WITH_AVR = (("error_rate", "--error-rate"), ("drop_rate", "--drop-rate"),
                 ("corrupt_rate", "--corrupt-rate"), ("bursty", "--bursty"),
                 ("silent_after", "--silent-after"))


def _seconds(text: str) -> float:
    """A time in seconds, finite and ≥ 0 (else ValueError)."""
    value = float(text)
    if not 0 <= value < float("inf"):
        raise ValueError(f"{text} is not a time ≥ 0 s")
    return value


def parse_sensor_off(text: str):
    """``IMU:SENSOR:FROM:TO`` (SENSOR accel, mag or gyro; seconds) → :class:`SensorOff`."""
    from bpms.firmware.avr_suit import SENSORS, SensorOff

    parts = text.split(":")
    try:
        if len(parts) != 4 or parts[1] not in SENSORS:
            raise ValueError
        return SensorOff(int(parts[0]), SENSORS.index(parts[1]), _seconds(parts[2]),
                         _seconds(parts[3]))
    except ValueError as exc:
        why = f" ({exc})" if str(exc) else ""
        raise CliError(f"--sensor-off wants IMU:SENSOR:FROM:TO with IMU 0-17, SENSOR one of "
                       f"{', '.join(SENSORS)} and FROM < TO in seconds, not {text!r}{why}"
                       ) from None


def parse_bus_stuck(text: str):
    """``CLUSTER:FROM:TO`` (seconds) → :class:`BusStuck`."""
    from bpms.firmware.avr_suit import BusStuck

    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        return BusStuck(int(parts[0]), _seconds(parts[1]), _seconds(parts[2]))
    except ValueError as exc:
        why = f" ({exc})" if str(exc) else ""
        raise CliError(f"--bus-stuck wants CLUSTER:FROM:TO with CLUSTER 0-5 and FROM < TO in "
                       f"seconds, not {text!r}{why}") from None


def _stream_rate(status: dict) -> str:
    """Frames per simulated second of the current stream, or why there is none."""
    streams = status.get("streams") or []
    if not streams or streams[-1]["frames"] < 2:
        return "not streaming"
    s = streams[-1]
    rate = (s["frames"] - 1) / (s["last_s"] - s["start_s"])
    which = "this" if status["sim_s"] - s["last_s"] < 0.1 else "the last"
    return f"{s['frames']} frames in {which} stream, {rate:.2f} per simulated second"


def avr_status_line(status: dict) -> str:
    """One line: simulated time, real-time factor, frame rate, cycle budget, faults seen."""
    cycles = status.get("cycles_per_frame") or {}
    budget = []
    arb = cycles.get("arbiter")
    if arb:
        budget.append(f"arbiter {arb['mean']:,.0f} ({arb['mean'] / 3200:.1f} %), "
                      f"max {arb['max']:,.0f}")
    clusters = [v for k, v in cycles.items() if k.startswith("cluster") and v]
    if clusters:
        top = max(v["max"] for v in clusters)
        mean = max(v["mean"] for v in clusters)
        budget.append(f"clusters {mean:,.0f} ({mean / 3200:.1f} %), max {top:,.0f}")
    line = (f"simulated {status['sim_s']:.1f} s in {status['wall_s']:.1f} s (real-time factor "
            f"{status['factor']:.2f}, last second {status['factor_recent']:.2f}); "
            f"{_stream_rate(status)}")
    if budget:
        line += "; cycles per 20 ms frame of 320,000: " + ", ".join(budget)
    c = status.get("counters", {})
    faults = {"misrouted": c.get("misrouted", 0), "cut": c.get("cut", 0),
              "host bytes lost": c.get("host_bytes_lost", 0),
              "USART overruns": sum(c.get("overruns", [])),
              "framing errors": c.get("framing_errors", 0)}
    bad = [f"{k} {v}" for k, v in faults.items() if v]
    if bad:
        line += "; WIRE FAULTS: " + ", ".join(bad)
    return line


def run_avr(args: argparse.Namespace) -> int:
    """``bpms sim --avr``: the firmware images in simavr behind the transport."""
    import json
    from pathlib import Path

    from bpms.firmware.avr_build import AvrBuildError
    from bpms.firmware.avr_suit import AvrSuit, AvrSuitError

    for name, flag in _NOT_WITH_AVR:
        if getattr(args, name):
            raise CliError(f"{flag} is the Python suit's fault injection, not available with "
                           "--avr (use --sensor-off to take a sensor chip off the bus)")
    sensor_off = [parse_sensor_off(text) for text in args.sensor_off]
    bus_stuck = [parse_bus_stuck(text) for text in args.bus_stuck]
    report = refuse_special_output(Path(args.report)) if args.report else None
    if report is not None and not report.parent.is_dir():
        raise CliError(f"cannot write the report: no folder {report.parent}")
    source = build_source(args)
    every = 5.0
    shown = [0.0]

    def show(status: dict) -> None:
        if status.get("final") or status["sim_s"] - shown[0] < every - 1e-6:
            return
        shown[0] = status["sim_s"]
        print(f"bpms sim: {avr_status_line(status)}", file=sys.stderr, flush=True)

    suit = AvrSuit(source, realtime=not args.fast, battery_v=args.battery,
                   battery_drain_v_per_h=args.drain, sensor_off=sensor_off,
                   bus_stuck=bus_stuck, on_status=show)
    print("bpms sim: building the AVR images and the simulator host (make avr-suit)",
          file=sys.stderr, flush=True)
    try:
        suit.start()
    except (AvrBuildError, AvrSuitError) as exc:
        raise CliError(str(exc)) from None
    try:
        server = open_server(args, suit)
    except CliError:
        suit.close()
        raise
    where = server.address
    print(where, flush=True)
    print(f"bpms sim: serving the suit's firmware (7 simulated ATmega328P) on {where} "
          f"({'as fast as it runs' if args.fast else 'real time at most'}); Ctrl-C stops",
          file=sys.stderr, flush=True)
    # Ctrl-C and SIGTERM only ask to stop: a second one cannot cut the summary short.
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.set())
    server.start()
    try:
        while suit.error is None and not stop.wait(0.2):
            pass
    finally:
        server.stop()
        final = suit.close()
    if suit.error is not None:
        print(f"bpms sim: error: {suit.error}", file=sys.stderr)
    if final is not None:
        print(f"bpms sim: stopped; {avr_status_line(final)}", file=sys.stderr)
        if report is not None:
            try:
                report.write_text(json.dumps(final, indent=1) + "\n")
            except OSError as exc:
                print(f"bpms sim: error: cannot write {report}: {exc.strerror or exc}",
                      file=sys.stderr)
                return 1
    return 1 if suit.error is not None else 0
