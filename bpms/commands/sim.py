"""``bpms sim --pty | --tcp PORT``: run the simulated suit until Ctrl-C.

The first line printed is where to connect: the pseudo-terminal's device path (``/dev/pts/N``,
Linux and macOS) or ``socket://127.0.0.1:PORT`` (every platform, Windows included). The suit
speaks the arbiter protocol (docs/frame-format.md) and streams the scripted motion of
docs/simulated-suit.md, looped, with optional fault injection.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from typing import TYPE_CHECKING

from bpms.commands import CliError

if TYPE_CHECKING:  # numpy and the sensor model load when the suit is built, not for --help
    from bpms.firmware.sim.arbiter import Arbiter


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("sim", help="run the simulated suit on a pseudo-terminal or TCP port",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--pty", action="store_true",
                       help="serve on a new pseudo-terminal (its path is printed first; "
                            "Linux and macOS)")
    where.add_argument("--tcp", type=int, metavar="PORT",
                       help="serve on 127.0.0.1:PORT (0 = any free port; the URL is printed)")
    add_sim_options(p)
    p.set_defaults(run=run)
    return p


def add_sim_options(p: argparse.ArgumentParser) -> None:
    """Options of the simulated suit (shared with ``bpms monitor``'s fallback)."""
    g = p.add_argument_group("simulated suit")
    g.add_argument("--fast", action="store_true",
                   help="stream as fast as the host reads (default: real time, 50 frames/s)")
    g.add_argument("--seed", type=int, default=0, help="seed of noise, mounting errors, faults")
    g.add_argument("--mag-disturbance", action="store_true",
                   help="a magnet beside the right forearm during the elbow moves")
    g.add_argument("--no-noise", action="store_true", help="noise-free sensors")
    g.add_argument("--no-mounting-errors", action="store_true",
                   help="IMUs mounted exactly along their segments")
    g.add_argument("--calibration", metavar="Calib.cfg",
                   help="the suit's true calibration (default: the factory table)")
    g.add_argument("--battery", type=float, default=3.35, metavar="VOLTS",
                   help="battery voltage at start (default 3.35)")
    g.add_argument("--drain", type=float, default=0.1, metavar="V_PER_H",
                   help="battery drain, V per hour (default 0.1; floor 2.6 V)")
    f = p.add_argument_group("fault injection (all off by default)")
    f.add_argument("--error-rate", type=float, default=0.0, metavar="P",
                   help="per frame, IMU and sensor: error bit set, values 0")
    f.add_argument("--drop-rate", type=float, default=0.0, metavar="P",
                   help="per frame: a run of 1-8 bytes is lost")
    f.add_argument("--corrupt-rate", type=float, default=0.0, metavar="P",
                   help="per frame: one byte is altered")
    f.add_argument("--bursty", action="store_true",
                   help="Bluetooth-like delivery: frames held back up to 300 ms, then a burst")
    f.add_argument("--silent-after", type=float, default=None, metavar="SECONDS",
                   help="go silent (a lost link) this long after start ...")
    f.add_argument("--silent-for", type=float, default=5.0, metavar="SECONDS",
                   help="... for this long (default 5)")


def _probability(name: str, value: float) -> float:
    if not 0.0 <= value <= 1.0:
        raise CliError(f"{name} must be between 0 and 1, got {value:g}")
    return value


def build_arbiter(args: argparse.Namespace) -> Arbiter:
    """An :class:`Arbiter` streaming the scripted motion, configured from the options."""
    from bpms.firmware.sim.arbiter import Arbiter, Faults, MotionSource
    from bpms.io.calib_file import load_calibration

    table = None
    if args.calibration:
        table = load_calibration(args.calibration)
        for problem in table.problems:
            print(f"bpms sim: warning: {problem}", file=sys.stderr)
    faults = Faults(
        error_rate=_probability("--error-rate", args.error_rate),
        drop_rate=_probability("--drop-rate", args.drop_rate),
        corrupt_rate=_probability("--corrupt-rate", args.corrupt_rate),
        bursty=args.bursty,
        silence_at_s=args.silent_after,
        silence_s=args.silent_for,
    )
    source = MotionSource.simulated(
        seed=args.seed, mag_disturbance=args.mag_disturbance,
        mounting_errors=not args.no_mounting_errors, noise=not args.no_noise,
        calibration=table)
    return Arbiter(source, faults, realtime=not args.fast, battery_v=args.battery,
                   battery_drain_v_per_h=args.drain, seed=args.seed)


def _sigterm(signum, frame) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    from bpms.firmware.sim.server import PtyServer, SimServer, TcpServer, pty_available

    if args.pty and not pty_available():
        raise CliError("this system has no pseudo-terminals: use --tcp PORT "
                       "(then open socket://127.0.0.1:PORT)")
    arbiter = build_arbiter(args)
    server: SimServer
    try:
        server = PtyServer(arbiter) if args.pty else TcpServer(arbiter, port=args.tcp)
        where = server.address
    except OSError as exc:
        raise CliError(f"cannot open the transport: {exc.strerror or exc}") from None
    print(where, flush=True)
    print(f"bpms sim: serving the simulated suit on {where} "
          f"({'fast' if args.fast else 'real time'}); Ctrl-C stops", file=sys.stderr, flush=True)
    signal.signal(signal.SIGTERM, _sigterm)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # even when started in background
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
