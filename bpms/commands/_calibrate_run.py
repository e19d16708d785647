"""The implementation of ``bpms calibrate`` (see :mod:`bpms.commands.calibrate`): loaded only
when the command runs, so that ``bpms --help`` stays quick."""

from __future__ import annotations

import argparse
import queue
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bpms.calibration.frames import poll_raw
from bpms.calibration.output import load_existing, save_pair
from bpms.calibration.procedures import (
    AXES,
    SENSORS,
    AccelProcedure,
    GyroProcedure,
    MagProcedure,
    pose_name,
)
from bpms.calibration.result import collect, format_summary, summary
from bpms.commands import CliError
from bpms.commands._shared import refuse_special_output
from bpms.io.events import FrameSource
from bpms.io.frames import N_IMUS
from bpms.progress import is_terminal

NO_FRAMES_S = 5.0  # give up when the source is silent this long


def parse_imus(text: str) -> list[int]:
    """``all`` or ``0,2,5-7`` → sorted IMU ids; ValueError with a one-line reason."""
    if text.strip().lower() == "all":
        return list(range(N_IMUS))
    ids: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        lo, _, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi) if hi else int(lo)
        except ValueError:
            raise ValueError(f"'{part}' is not an IMU id or range (e.g. 0,2,5-7)") from None
        if not (0 <= a <= b < N_IMUS):
            raise ValueError(f"IMU ids run from 0 to {N_IMUS - 1}, got '{part}'")
        ids.update(range(a, b + 1))
    if not ids:
        raise ValueError("no IMU chosen")
    return sorted(ids)


def parse_sensors(values: list[str] | None) -> list[str]:
    """``--sensor`` values (repeated, comma lists; none: all) → the sensors in step order."""
    chosen = [s.strip().lower() for v in values or SENSORS for s in v.split(",")]
    for s in chosen:
        if s not in SENSORS:
            raise ValueError(f"unknown sensor '{s}' (accel, mag or gyro)")
    return [s for s in SENSORS if s in chosen]


class Terminal:
    """Prompts and live status lines; stdin lines arrive through a queue (a reader thread),
    so live values keep updating while the tool waits for Enter."""

    def __init__(self, auto: bool) -> None:
        self.auto = auto
        self.lines: queue.Queue[str] = queue.Queue()
        self._last = 0.0
        self.tty = is_terminal(sys.stdout)
        if not auto:
            threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in sys.stdin:
            self.lines.put(line.strip().lower())
        self.lines.put("q")  # end of input

    def say(self, text: str) -> None:
        print(("\n" if self._last and self.tty else "") + text, flush=True)
        self._last = 0.0

    def status(self, text: str, force: bool = False) -> None:
        now = time.monotonic()
        # On a terminal one line is rewritten 4 times a second; in a log, a line every 5 s.
        if force or now - self._last > (0.25 if self.tty else 5.0):
            if self.tty:
                print("\r" + text[:150].ljust(100), end="", flush=True)
            else:
                print(text[:150], flush=True)
            self._last = now

    def answer(self) -> str | None:
        """A line typed since the last call, or None."""
        try:
            return self.lines.get_nowait()
        except queue.Empty:
            return None

    def ask(self, question: str, timeout_s: float = 600.0) -> str | None:
        """Say ``question``; the next line typed within ``timeout_s`` (None when none is)."""
        self.say(question)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                return self.lines.get(timeout=0.5)
            except queue.Empty:
                continue
        return None


class Driver:
    """Feeds a frame source into the current procedure until a condition holds."""

    def __init__(self, source: FrameSource, term: Terminal) -> None:
        self.source = source
        self.term = term

    def pump(self, feed: Callable[[np.ndarray, np.ndarray], None], until: Callable[[], bool],
             status: Callable[[], str], on_line: Callable[[str], bool] | None = None) -> None:
        last_frame = time.monotonic()
        while not until():
            raw, errors = poll_raw(self.source, 0.05)
            if len(raw):
                last_frame = time.monotonic()
                for k in range(len(raw)):
                    feed(raw[k], errors[k])
                    if until():
                        break
            elif time.monotonic() - last_frame > NO_FRAMES_S:
                raise CliError(f"no frames from the suit for {NO_FRAMES_S:g} s "
                               f"({self.source.status().state}); nothing saved")
            self.term.status(status())
            line = self.term.answer()
            if line is not None and on_line is not None and on_line(line):
                return
        self.term.status(status(), force=True)

    def wait_enter(self, text: str, feed=None, status=None) -> str:
        """Show live values until a line is typed (returns it; '' under --yes)."""
        self.term.say(text)
        if self.term.auto:
            return ""
        got: list[str] = []
        self.pump(feed or (lambda r, e: None), lambda: bool(got),
                  status or (lambda: "waiting…"), lambda line: got.append(line) or True)
        return got[0]


def _open_source(args: argparse.Namespace):
    if args.sim:
        from bpms.firmware.sim.calibration_poses import (
            CalibrationSuit,
            ScriptedCalibrationSource,
            changed_table,
        )

        if 0 < args.sim_speed < 0.01:  # nan, inf and < 0: refused by the option's type
            raise CliError("--sim-speed must be 0 (as fast as possible) or 0.01 to 1000")
        return ScriptedCalibrationSource(CalibrationSuit(changed_table()), speed=args.sim_speed)
    from bpms.io.link import LinkError
    from bpms.io.options import SerialOptions
    from bpms.pipeline.sources import SuitFrameSource

    source = SuitFrameSource(args.port or None, SerialOptions())
    try:
        source.connect()
    except LinkError as exc:
        source.close()
        raise CliError(f"cannot connect to the suit: {exc}") from None
    return source


def _scene(source, *a, **kw) -> None:
    if hasattr(source, "set_scene"):
        source.set_scene(*a, **kw)


def _gyro(drv: Driver, args, imus: list[int]) -> GyroProcedure:
    proc = GyroProcedure(imus, args.gyro_samples)
    for attempt in range(1, 6):
        drv.wait_enter(f"GYRO (attempt {attempt}): lay the suit down and keep it still; "
                       "press Enter to start")
        _scene(drv.source, "moving" if (args.sim_move_gyro and attempt == 1) else "still")
        if attempt > 1:
            proc.restart()
        drv.pump(proc.feed, lambda: proc.state != "collecting",
                 lambda: f"gyro: {100 * proc.progress:5.1f} %  motion {proc.motion:5.1f} counts "
                         f"(limit {proc.check.gyro_std_counts:g})")
        drv.term.say(("REFUSED: " if proc.state == "rejected" else "gyro: ") + proc.message)
        if proc.state == "done":
            return proc
    raise CliError("the suit kept moving during the gyro step; nothing saved")


def _accel(drv: Driver, args, imus: list[int]) -> AccelProcedure:
    proc = AccelProcedure(imus, args.accel_samples, auto=args.yes)

    def status() -> str:
        if proc.done:
            return "accel: done"
        imu, axis, sign = proc.current
        v = proc.live
        bar = "capturing %3.0f %%" % (100 * proc.progress) if proc.capturing else (
            "still" if proc.still else "moving")
        where = "at extreme" if proc.at_extreme else "not at extreme"
        return (f"IMU {imu} {pose_name(axis, sign)}: a = ({v[0]:5.0f}, {v[1]:5.0f}, "
                f"{v[2]:5.0f}) counts  {AXES[axis]} {where} (best {proc.best:.0f})  [{bar}]")

    while not proc.done:
        step = proc.current
        _scene(drv.source, "accel", *step)
        drv.term.say(proc.prompt() + ("" if args.yes else
                                      "\n  Enter = capture, s = skip, r = redo previous, "
                                      "q = end the accel step"))

        def on_line(line: str) -> bool:
            if line == "s":
                proc.skip()
                return True
            if line == "r" and proc.index > 0:
                proc.redo(proc.index - 1)
                return True
            if line == "q":
                while not proc.done:
                    proc.skip()
                return True
            if not proc.capture():
                drv.term.say(proc.message)
            return False

        drv.pump(proc.feed, lambda s=step: proc.done or proc.current != s, status, on_line)
        if proc.message:
            drv.term.say(proc.message)
    return proc


def _mag(drv: Driver, args, imus: list[int]) -> MagProcedure:
    proc = MagProcedure(imus, args.sweep_s, ellipsoid=args.ellipsoid)
    drv.wait_enter(f"MAG: away from metal, rotate the garment through every orientation for "
                   f"{args.sweep_s:g} s; press Enter to start (Enter again ends early)")
    _scene(drv.source, "sweep")

    def status() -> str:
        cov = proc.coverage() if proc.frames % 25 == 0 or proc.state == "done" else None
        worst = (f"worst coverage {100 * min(cov.values()):3.0f} %" if cov else "")
        i = imus[0]
        return (f"mag: {proc.remaining_s:5.1f} s left  {worst}  IMU {i} min/max "
                f"x {proc.mins[i, 0]:.0f}/{proc.maxs[i, 0]:.0f} y {proc.mins[i, 1]:.0f}/"
                f"{proc.maxs[i, 1]:.0f} z {proc.mins[i, 2]:.0f}/{proc.maxs[i, 2]:.0f} counts "
                f"warnings {len(proc.warnings())}")

    drv.pump(proc.feed, lambda: proc.state == "done", status,
             lambda line: proc.finish() or True)
    cov = proc.coverage()
    for imu in imus:
        drv.term.say(f"IMU {imu}: min {proc.mins[imu].round().tolist()} max "
                     f"{proc.maxs[imu].round().tolist()} counts, coverage "
                     f"{100 * cov[imu]:.0f} %")
    for w in proc.warnings():
        drv.term.say("WARNING: " + w)
    return proc


def run(args: argparse.Namespace) -> int:
    try:
        imus = parse_imus(args.imu)
        sensors = parse_sensors(args.sensor)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    for name in ("gyro_samples", "accel_samples"):
        if getattr(args, name) < 1:
            raise CliError(f"--{name.replace('_', '-')} must be at least 1")
    if args.sweep_s <= 0:
        raise CliError("--sweep-s must be positive")
    out = Path(args.output)
    if out.exists() and out.is_dir():
        raise CliError(f"{out} is a folder; give a file name such as Calib.cfg")
    for path in (out, out.with_suffix(".json")):  # the result replaces files, never devices
        refuse_special_output(path)
    existing_path = args.existing or (out if out.exists() else _user_default())
    if args.existing and not Path(args.existing).is_file():
        raise CliError(f"--existing {args.existing}: no such file")
    existing = load_existing(existing_path)
    for p in existing.problems:
        print(f"warning: {p}", file=sys.stderr)
    source = _open_source(args)
    term = Terminal(auto=args.yes)
    drv = Driver(source, term)
    try:
        term.say(f"calibrating {', '.join(sensors)} of IMU(s) {imus} "
                 f"({source.status().description})")
        gyro = _gyro(drv, args, imus) if "gyro" in sensors else None
        accel = _accel(drv, args, imus) if "accel" in sensors else None
        mag = _mag(drv, args, imus) if "mag" in sensors else None
    finally:
        source.close()
    update = collect(gyro, accel, mag, existing.table)
    new = update.merge(existing.table)
    term.say("SUMMARY (old vs new):\n" + format_summary(summary(existing.table, new, imus)))
    for line in update.quality.lines():
        term.say(line)
    if not update.imus:
        term.say("nothing was measured; nothing saved")
        return 1
    if not args.yes and term.ask(f"save to {out}? [Y/n]") not in ("", "y", "yes"):
        term.say("not saved")
        return 1
    try:
        legacy, modern = save_pair(existing, update, out, sensors)
    except OSError as exc:
        # never lose a calibration: write it somewhere that works, then say where
        stamp = time.strftime("%Y%m%d-%H%M%S")
        fallback = Path(tempfile.gettempdir()) / f"Calib-unsaved-{stamp}.cfg"
        save_pair(existing, update, fallback, sensors)
        raise CliError(f"cannot write {out} ({exc.strerror or exc}); the calibration was saved "
                       f"to {fallback} instead") from None
    term.say(f"saved {legacy} and {modern}")
    _offer_default(args, term, legacy)
    return 0


def _user_default() -> Path | None:
    from bpms.io.userdirs import default_calibration_path

    path = default_calibration_path()
    return path if path.is_file() else None


def _offer_default(args: argparse.Namespace, term: Terminal, legacy: Path) -> None:
    """--make-default, or (interactive) a question: the result becomes the user's default."""
    from bpms.io.defaults import save_default_calibration

    make = args.make_default
    if not make and not args.yes:
        make = term.ask("make it your default calibration (used when none is given)? "
                        "[y/N]") in ("y", "yes")
    if make:
        try:
            term.say(f"default calibration: {save_default_calibration(legacy)}")
        except (OSError, ValueError) as exc:
            term.say(f"not made the default: {exc}")
