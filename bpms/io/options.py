"""The options file: a commented TOML file (``calib/options.toml`` holds the factory values).

Every option has a default, a unit and a check. Reading never raises: a missing file, a TOML
syntax error, an unknown key or a bad value is reported (file, line or key, problem) and the
factory value is used instead.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from bpms.io.problems import FileProblem, report


def _opt(default: Any, help: str, **checks: Any) -> Any:
    """A dataclass field with a help text (shown as a comment) and checks (min, choices, ...)."""
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata={"help": help, **checks})
    return field(default=default, metadata={"help": help, **checks})


@dataclass
class FilterOptions:
    """Attitude filter settings (SPEC §5); changeable at run time."""

    algorithm: str = _opt(
        "mahony", "attitude filter for all 18 IMUs: 'mahony' (the original DCM filter), "
        "'observer' (quaternion observer with gyro-bias and body-acceleration estimation), "
        "'vqf' (the vqf package); docs/filters.md", choices=("mahony", "observer", "vqf"))
    kp_rollpitch: float = _opt(0.02, "roll/pitch proportional gain (per accel count)", min=0.0)
    ki_rollpitch: float = _opt(0.00002, "roll/pitch integral gain (per accel count)", min=0.0)
    kp_yaw: float = _opt(1.2, "yaw proportional gain", min=0.0)
    ki_yaw: float = _opt(0.00002, "yaw integral gain", min=0.0)
    dt: float = _opt(0.02, "filter time step, s (the suit's fixed 50 Hz period)", min=1e-4)
    failed_sensor: str = _opt(
        "hold", "a sensor flagged failed: 'hold' its last good value", choices=("hold",)
    )
    observer_k_incl: float = _opt(0.5, "observer: inclination correction gain, 1/s", min=0.0)
    observer_k_head: float = _opt(0.2, "observer: heading (magnetometer) correction gain, 1/s",
                                  min=0.0)
    observer_k_bias: float = _opt(0.01, "observer: gyro-bias estimation gain, 1/s²", min=0.0)
    observer_tau_acc_s: float = _opt(
        1.5, "observer: gravity low-pass time constant (body-acceleration estimate), s",
        min=0.0)
    observer_mag_norm_th: float = _opt(
        0.05, "observer: magnetic field norm change that counts as disturbed, fraction",
        min=0.0)
    observer_mag_dip_th_deg: float = _opt(
        5.0, "observer: magnetic dip change that counts as disturbed, degrees", min=0.0)
    observer_mag_new_time_s: float = _opt(
        10.0, "observer: a steady new magnetic field is accepted after, s", min=0.0)
    vqf_tau_acc_s: float = _opt(3.0, "vqf: accelerometer low-pass time constant, s", min=0.0)
    vqf_tau_mag_s: float = _opt(9.0, "vqf: magnetometer correction time constant, s", min=0.0)


@dataclass
class SensorOptions:
    """Axis sign vectors from the calibrated board axes into the filter frame (SPEC §4)."""

    accel_signs: list[float] = _opt([1.0, 1.0, 1.0], "accelerometer x, y, z signs", signs=True)
    mag_signs: list[float] = _opt([1.0, -1.0, -1.0], "magnetometer x, y, z signs", signs=True)
    gyro_signs: list[float] = _opt([-1.0, -1.0, -1.0], "gyroscope x, y, z signs", signs=True)


@dataclass
class DisplayOptions:
    angle_unit: str = _opt("deg", "angles shown in 'deg' or 'rad'", choices=("deg", "rad"))
    refresh_hz: float = _opt(20.0, "table and plot redraw rate, Hz", min=1.0, max=60.0)
    plot_history_s: float = _opt(60.0, "history kept in live plots, s", min=1.0, max=3600.0)


@dataclass
class SerialOptions:
    port: str = _opt("", "serial port or pyserial URL; empty = discover the suit")
    baud: int = _opt(1_000_000, "baud rate (nominal over Bluetooth SPP)", min=1200)
    discovery_timeout_s: float = _opt(1.0, "wait for the 'BPMS' answer per port, s", min=0.05)
    read_timeout_s: float = _opt(0.05, "serial read timeout, s", min=0.001)
    link_lost_after_s: float = _opt(1.0, "silence that counts as a lost link, s", min=0.1)


@dataclass
class UdpOptions:
    forward_to: list[str] = _opt(["127.0.0.1:5005"], "UDP server targets, host:port",
                                 hostports=True)
    listen: str = _opt("0.0.0.0:5005", "UDP client listens on host:port", hostport=True)
    multicast_ttl: int = _opt(1, "multicast time-to-live, hops", min=0, max=255)


@dataclass
class LoggingOptions:
    directory: str = _opt("recordings", "folder for recordings")
    name: str = _opt("", "file name stem; empty = a time stamp")
    raw: bool = _opt(True, "record raw frames")
    filtered: bool = _opt(True, "record filtered angles")
    flush_interval_s: float = _opt(1.0, "data reach the disk at least this often, s", min=0.05)


@dataclass
class PoseOptions:
    reset_window_s: float = _opt(0.5, "Reset Zero averages the DCMs over this still window, s",
                                 min=0.0, max=10.0)
    heading_reference: str = _opt(
        "hip", "body heading at Reset Zero: 'hip' IMU (SPEC §6) or the 'mean' of all IMUs' "
        "yaws (averages out mounting yaw errors)", choices=("hip", "mean"))


@dataclass
class BodyOptions:
    """Segment lengths, m (dissertation Table 2.4, 50th-percentile US male)."""

    low_spine: float = _opt(0.21, "low spine, m", min=0.0)
    mid_spine: float = _opt(0.27, "mid spine, m", min=0.0)
    neck: float = _opt(0.20, "neck, m", min=0.0)
    head: float = _opt(0.22, "head, m", min=0.0)
    shoulder: float = _opt(0.16, "shoulder, m", min=0.0)
    arm: float = _opt(0.34, "upper arm, m", min=0.0)
    forearm: float = _opt(0.27, "forearm, m", min=0.0)
    hand: float = _opt(0.19, "hand, m", min=0.0)
    hip: float = _opt(0.17, "half hip width, m", min=0.0)
    thigh: float = _opt(0.43, "thigh, m", min=0.0)
    shank: float = _opt(0.40, "shank, m", min=0.0)
    foot: float = _opt(0.27, "foot, m", min=0.0)
    height: float = _opt(1.73, "subject height, m", min=0.0)


@dataclass
class TrackOptions:
    heel_strike_g: float = _opt(2.0, "heel strike: foot acceleration peak above, g", min=0.0)
    min_step_interval_s: float = _opt(0.4, "heel strikes at least this far apart, s", min=0.0)
    declination_deg: float = _opt(0.0, "local magnetic declination, deg east", min=-180.0,
                                  max=180.0)


@dataclass
class JointOptions:  # i16: joint-angle sign convention (docs/joint-angles.md)
    convention: str = _opt("isb", "joint-angle signs: 'isb' (flexion, abduction, external "
                           "rotation positive on both sides) or 'original' (raw Euler, "
                           "left/right mirrored); docs/joint-angles.md",
                           choices=("isb", "original"))


@dataclass
class LslOptions:  # i16: Lab Streaming Layer outlets (docs/lsl.md)
    enabled: bool = _opt(False, "send segment orientations, joint angles, sensor data and "
                         "events as LSL streams; docs/lsl.md")
    link_delay_s: float = _opt(0.0, "suit → computer delay subtracted from LSL time stamps, s",
                               min=0.0, max=5.0)


@dataclass
class MvnOptions:  # i16: MVN-compatible UDP stream (docs/mvn.md)
    targets: list[str] = _opt([], "send the MVN-compatible stream to these host:port targets "
                              "(docs/mvn.md)", hostports=True)


@dataclass
class Options:
    filter: FilterOptions = field(default_factory=FilterOptions)
    sensors: SensorOptions = field(default_factory=SensorOptions)
    display: DisplayOptions = field(default_factory=DisplayOptions)
    serial: SerialOptions = field(default_factory=SerialOptions)
    udp: UdpOptions = field(default_factory=UdpOptions)
    logging: LoggingOptions = field(default_factory=LoggingOptions)
    pose: PoseOptions = field(default_factory=PoseOptions)
    body: BodyOptions = field(default_factory=BodyOptions)
    track: TrackOptions = field(default_factory=TrackOptions)
    joints: JointOptions = field(default_factory=JointOptions)
    lsl: LslOptions = field(default_factory=LslOptions)
    mvn: MvnOptions = field(default_factory=MvnOptions)
    source: str = field(default="factory", compare=False, repr=False)
    problems: list[FileProblem] = field(default_factory=list, compare=False, repr=False)

    def sections(self) -> dict[str, Any]:
        """The option sections by name (everything but ``source`` and ``problems``)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if f.name not in ("source", "problems")}


def _is_hostport(text: Any) -> bool:
    if not isinstance(text, str) or ":" not in text:
        return False
    host, _, port = text.rpartition(":")
    return bool(host) and port.isdigit() and 0 < int(port) < 65536


def _check_value(value: Any, default: Any, meta: dict[str, Any]) -> tuple[Any, str | None]:
    """(converted value, None) or (None, what is wrong)."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            return None, f"{value!r} is not true/false"
    elif isinstance(default, int | float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            return None, f"{value!r} is not a number"
        if isinstance(default, int) and not isinstance(value, int):
            return None, f"{value!r} is not a whole number"
        if not math.isfinite(value):
            return None, f"{value!r} is not finite"
        if "min" in meta and value < meta["min"]:
            return None, f"{value} is below the minimum {meta['min']}"
        if "max" in meta and value > meta["max"]:
            return None, f"{value} is above the maximum {meta['max']}"
        value = type(default)(value)
    elif isinstance(default, str):
        if not isinstance(value, str):
            return None, f"{value!r} is not text"
        if "choices" in meta and value not in meta["choices"]:
            return None, f"'{value}' is not one of {', '.join(meta['choices'])}"
        if meta.get("hostport") and not _is_hostport(value):
            return None, f"'{value}' is not host:port"
    elif isinstance(default, list):
        if not isinstance(value, list):
            return None, f"{value!r} is not a list"
        if meta.get("signs"):
            if len(value) != 3 or any(v not in (1, -1) or isinstance(v, bool) for v in value):
                return None, f"{value!r} is not three signs (1 or -1)"
            value = [float(v) for v in value]
        if meta.get("hostports") and not all(_is_hostport(v) for v in value):
            return None, f"{value!r} is not a list of host:port"
    return value, None


def options_from_dict(data: dict[str, Any], path: str | Path = "<dict>") -> Options:
    """Build Options from parsed TOML, reporting unknown keys and bad values."""
    options = Options(source=str(path))
    for section, content in data.items():
        target = options.sections().get(section)
        if target is None or not dataclasses.is_dataclass(target):
            report(options.problems, path, f"[{section}]", "unknown section", "ignored")
            continue
        if not isinstance(content, dict):
            report(options.problems, path, f"[{section}]", "is not a table", "factory values used")
            continue
        fields = {f.name: f for f in dataclasses.fields(target)}
        for key, value in content.items():
            spec = fields.get(key)
            if spec is None:
                report(options.problems, path, f"{section}.{key}", "unknown option", "ignored")
                continue
            default = getattr(target, key)
            checked, problem = _check_value(value, default, dict(spec.metadata))
            if problem:
                report(options.problems, path, f"{section}.{key}", problem,
                       f"factory value {default!r} used")
            else:
                setattr(target, key, checked)
    return options


def load_options(path: str | Path | None) -> Options:
    """Read an options file. ``None`` gives the factory options. Never raises."""
    if path is None:
        return Options()
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        options = Options(source=f"factory ({path} unreadable)")
        report(options.problems, path, "file", f"cannot be read ({exc})", "factory options used")
        return options
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        options = Options(source=f"factory ({path} invalid)")
        report(options.problems, path, "syntax", str(exc), "factory options used")
        return options
    return options_from_dict(data, path)


def format_options(options: Options) -> str:
    """Commented TOML text of ``options``."""
    out = ["# BPMS Suite options. Each value has its unit in the comment above it.", ""]
    for name, section in options.sections().items():
        out.append(f"[{name}]")
        for f in dataclasses.fields(section):
            out.append(f"# {f.metadata.get('help', '')}")
            out.append(tomli_w.dumps({f.name: getattr(section, f.name)}).rstrip())
        out.append("")
    return "\n".join(out)


def save_options(options: Options, path: str | Path) -> None:
    """Write the options file atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(format_options(options), encoding="utf-8")
    tmp.replace(path)
