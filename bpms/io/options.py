"""The options file: a commented TOML file (``calib/options.toml`` holds the factory values).

Every option has a default, a unit and a check. The checks live in ONE table,
:data:`VALID_RANGES` (min / max / choices per ``section.key``), shared by the file reader (a
value outside → one-line warning and the factory value), the options dialog and the run-time
API (:func:`check_option` raises :class:`OptionRangeError`, a ValueError naming the range).
Reading never raises: a missing file, a TOML syntax error, an unknown key or a bad value is
reported (file, line or key, problem) and the factory value is used instead.
docs/configuration.md lists the table and why each filter range is what it is.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from bpms.io.bounded import BoundError, read_config_bytes
from bpms.io.problems import FileProblem, report


@dataclass(frozen=True)
class Range:
    """The valid values of one option: ``lo <= v <= hi`` and/or one of ``choices``; ``why``
    says where a bound comes from (docs/configuration.md prints it)."""

    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] | None = None
    why: str = ""

    def describe(self) -> str:
        """e.g. ``[0, 0.18]``, ``>= 1e-04``, ``one of mahony, observer, vqf``."""
        if self.choices is not None:
            return "one of " + ", ".join(self.choices)
        if self.lo is not None and self.hi is not None:
            return f"[{self.lo:g}, {self.hi:g}]"
        if self.lo is not None:
            return f">= {self.lo:g}"
        return f"<= {self.hi:g}"


#: Mahony drift correction at dt = 0.02 s (docs/configuration.md, "Why these filter ranges"):
#: the roll/pitch error shrinks per step by the factor 1 − kp·|a|·dt with |a| ≈ Gravity ≤ 275
#: counts, so kp·275·0.02 must stay below 1 for a monotone (non-overshooting) correction and
#: below 2 for any stability at all: kp_rollpitch ≤ 1/(275·0.02) ≈ 0.18. The yaw error is a
#: unit sine: kp_yaw·0.02 ≤ 1 → kp_yaw ≤ 50 1/s. The integral terms add ki·|a| per step; the
#: PI loop is stable while ki < kp (Jury), bounded here well inside that.
MAHONY_DT_S = 0.02
MAHONY_GRAVITY_MAX = 275.0

#: The one table of valid values, by section then key.
#: ``FilterOptions.heading``: what every output's header says about the heading reference.
HEADING_TEXT: dict[str, str] = {
    "magnetic": "magnetic (9D: the magnetometer corrects heading)",
    "relative": "relative to the start (6D: no magnetometer)",
}
HEADINGS = tuple(HEADING_TEXT)
#: the attitude filters by their option names (bpms.filter.algorithms builds each)
ALGORITHMS = ("mahony", "observer", "vqf", "adaptive")

VALID_RANGES: dict[str, dict[str, Range]] = {
    "filter": {
        "algorithm": Range(choices=ALGORITHMS),
        "kp_rollpitch": Range(0.0, 0.18, why="monotone correction: kp·Gravity·dt ≤ 1 "
                                             "(Gravity ≤ 275 counts, dt 0.02 s)"),
        "ki_rollpitch": Range(0.0, 0.002, why="PI loop stable while ki ≪ kp; 100× factory"),
        "kp_yaw": Range(0.0, 50.0, why="monotone correction: kp_yaw·dt ≤ 1 (dt 0.02 s)"),
        "ki_yaw": Range(0.0, 0.1, why="PI loop stable while ki ≪ kp_yaw"),
        "dt": Range(1e-4, 1.0, why="the suit runs at 50 Hz (0.02 s)"),
        "failed_sensor": Range(choices=("hold",)),
        "heading": Range(choices=HEADINGS, why="6D mode: docs/filters.md"),
        "observer_k_incl": Range(0.0, 50.0, why="first-order correction: k·dt ≤ 1 (dt 0.02 s)"),
        "observer_k_head": Range(0.0, 50.0, why="first-order correction: k·dt ≤ 1 (dt 0.02 s)"),
        "observer_k_bias": Range(0.0, 1.0, why="bias loop slower than the attitude loop"),
        "observer_tau_acc_s": Range(0.0, 60.0),
        "observer_mag_norm_th": Range(0.0, 1.0),
        "observer_mag_dip_th_deg": Range(0.0, 90.0),
        "observer_mag_new_time_s": Range(0.0, 600.0),
        "vqf_tau_acc_s": Range(0.05, 100.0, why="a low-pass longer than 2.5 samples"),
        "vqf_tau_mag_s": Range(0.05, 1000.0, why="a low-pass longer than 2.5 samples"),
        "adaptive_k_incl": Range(0.0, 50.0, why="first-order correction: k·dt ≤ 1 (dt 0.02 s)"),
        "adaptive_k_head": Range(0.0, 50.0, why="first-order correction: k·dt ≤ 1 (dt 0.02 s)"),
        "adaptive_mag_norm_th": Range(0.0, 1.0),
        "adaptive_mag_dip_th_deg": Range(0.0, 90.0),
        "adaptive_rest_gyr_dps": Range(0.0, 90.0),
        "adaptive_rest_time_s": Range(0.0, 600.0),
        "adaptive_rest_tau_s": Range(0.0, 600.0),
    },
    "sensors": {
        "accel_range_g": Range(2.0, 16.0, why="the ADXL345's ranges: 2, 4, 8 or 16 g"),
    },
    "display": {
        "angle_unit": Range(choices=("deg", "rad")),
        "refresh_hz": Range(1.0, 60.0),
        "plot_history_s": Range(1.0, 3600.0),
    },
    "serial": {
        "baud": Range(1200, 4_000_000, why="serial ports and the RN-41 Bluetooth module"),
        "discovery_timeout_s": Range(0.05, 60.0),
        "read_timeout_s": Range(0.001, 10.0),
        "link_lost_after_s": Range(0.1, 600.0),
    },
    "udp": {"multicast_ttl": Range(0, 255),
            "takeover_after_s": Range(1.0, 3600.0, why="a pause of the sender followed "
                                      "shorter than this never hands the receiver over")},
    "logging": {"flush_interval_s": Range(0.05, 60.0, why="data on disk within a minute "
                                                      "at the latest"),
                "disk_reserve_s": Range(0.0, 1e8, why="seconds of raw data (17.4 kB/s); 1e8 s "
                                                      "is more than any disk")},
    "pose": {
        "reset_window_s": Range(0.0, 10.0),
        "heading_reference": Range(choices=("hip", "mean")),
    },
    "body": {name: Range(0.01, 3.0, why="a body segment, m") for name in (
        "low_spine", "mid_spine", "neck", "head", "shoulder", "arm", "forearm", "hand", "hip",
        "thigh", "shank", "foot")} | {"height": Range(0.5, 2.5)},
    "track": {
        "heel_strike_g": Range(0.5, 16.0, why="the ADXL345's widest range is ±16 g"),
        "min_step_interval_s": Range(0.05, 5.0),
        "declination_deg": Range(-180.0, 180.0),
    },
    "joints": {"convention": Range(choices=("isb", "original"))},
    "lsl": {"link_delay_s": Range(0.0, 5.0, why="Bluetooth delays are tens of ms; 5 s is "
                                               "far beyond any real link")},
}

#: Which [filter] settings belong to which attitude filter (the GUI shows the selected one's).
ALGORITHM_SETTINGS: dict[str, tuple[str, ...]] = {
    "mahony": ("kp_rollpitch", "ki_rollpitch", "kp_yaw", "ki_yaw"),
    "observer": ("observer_k_incl", "observer_k_head", "observer_k_bias", "observer_tau_acc_s",
                 "observer_mag_norm_th", "observer_mag_dip_th_deg", "observer_mag_new_time_s"),
    "vqf": ("vqf_tau_acc_s", "vqf_tau_mag_s"),
    "adaptive": ("adaptive_k_incl", "adaptive_k_head", "observer_k_bias", "observer_tau_acc_s",
                 "adaptive_mag_norm_th", "adaptive_mag_dip_th_deg", "observer_mag_new_time_s",
                 "adaptive_rest_gyr_dps", "adaptive_rest_time_s", "adaptive_rest_tau_s"),
}


class OptionRangeError(ValueError):
    """A value outside its valid range (the message names the option and the range)."""


def option_range(section: str, key: str) -> Range | None:
    """The valid range of ``section.key`` (None: no numeric bound or choice list)."""
    return VALID_RANGES.get(section, {}).get(key)


def _opt(default: Any, help: str, **checks: Any) -> Any:
    """A dataclass field with a help text (shown as a comment) and checks (signs, host:port);
    ranges come from :data:`VALID_RANGES` (:func:`_ranged`)."""
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata={"help": help, **checks})
    return field(default=default, metadata={"help": help, **checks})


@dataclass
class FilterOptions:
    """Attitude filter settings (docs/filter.md, docs/filters.md); changeable at run time."""

    algorithm: str = _opt(
        "mahony", "attitude filter for all 18 IMUs: 'mahony' (the original DCM filter), "
        "'observer' (quaternion observer with gyro-bias and body-acceleration estimation), "
        "'vqf' (the vqf package), 'adaptive' (the observer with trapezoidal gyro integration "
        "and gyro bias at rest); docs/filters.md")
    kp_rollpitch: float = _opt(0.02, "roll/pitch proportional gain (per accel count)")
    ki_rollpitch: float = _opt(0.00002, "roll/pitch integral gain (per accel count)")
    kp_yaw: float = _opt(1.2, "yaw proportional gain")
    ki_yaw: float = _opt(0.00002, "yaw integral gain")
    dt: float = _opt(0.02, "filter time step, s (the suit's fixed 50 Hz period)")
    failed_sensor: str = _opt(
        "hold", "a sensor flagged failed: 'hold' its last good value"
    )
    heading: str = _opt(
        "magnetic", "heading reference: 'magnetic' (the magnetometer corrects heading) or "
        "'relative' (6D: no magnetometer, heading relative to the start, for places without a "
        "usable field); docs/filters.md")
    observer_k_incl: float = _opt(0.5, "observer: inclination correction gain, 1/s")
    observer_k_head: float = _opt(0.2, "observer: heading (magnetometer) correction gain, 1/s")
    observer_k_bias: float = _opt(0.01, "observer: gyro-bias estimation gain, 1/s²")
    observer_tau_acc_s: float = _opt(
        1.5, "observer: gravity low-pass time constant (body-acceleration estimate), s")
    observer_mag_norm_th: float = _opt(
        0.05, "observer: magnetic field norm change that counts as disturbed, fraction")
    observer_mag_dip_th_deg: float = _opt(
        5.0, "observer: magnetic dip change that counts as disturbed, degrees")
    observer_mag_new_time_s: float = _opt(
        10.0, "observer: a steady new magnetic field is accepted after, s")
    vqf_tau_acc_s: float = _opt(3.0, "vqf: accelerometer low-pass time constant, s")
    vqf_tau_mag_s: float = _opt(9.0, "vqf: magnetometer correction time constant, s")
    # adaptive (the observer of bpms/filter/observer.py in its adaptive setting; k_bias,
    # tau_acc, mag_new_time: observer_*)
    adaptive_k_incl: float = _opt(0.5, "adaptive: inclination correction gain, 1/s")
    adaptive_k_head: float = _opt(0.2, "adaptive: heading correction gain, 1/s")
    adaptive_mag_norm_th: float = _opt(
        0.03, "adaptive: field norm change that counts as disturbed, fraction")
    adaptive_mag_dip_th_deg: float = _opt(
        3.0, "adaptive: magnetic dip change that counts as disturbed, degrees")
    adaptive_rest_gyr_dps: float = _opt(
        2.0, "adaptive: still when the bias-corrected rate is below, deg/s")
    adaptive_rest_time_s: float = _opt(1.0, "adaptive: still for this long before the gyro "
                                       "bias follows the rate, s")
    adaptive_rest_tau_s: float = _opt(
        10.0, "adaptive: the gyro bias at rest is the mean of the still samples over at most "
        "this many seconds of stillness, s (0 = off)")


@dataclass
class SensorOptions:
    """Axis sign vectors from the calibrated board axes into the filter frame (docs/units.md)."""

    accel_signs: list[float] = _opt([1.0, 1.0, 1.0], "accelerometer x, y, z signs", signs=True)
    mag_signs: list[float] = _opt([1.0, -1.0, -1.0], "magnetometer x, y, z signs", signs=True)
    gyro_signs: list[float] = _opt([-1.0, -1.0, -1.0], "gyroscope x, y, z signs", signs=True)
    accel_range_g: float = _opt(
        16.0, "accelerometer range the firmware sets, ±g (16 for this firmware, 2 for the "
        "original; the ADXL345 has 2, 4, 8, 16; full resolution keeps 256 counts/g); "
        "docs/firmware.md")


@dataclass
class DisplayOptions:
    angle_unit: str = _opt("deg", "angles shown in 'deg' or 'rad'")
    refresh_hz: float = _opt(20.0, "table and plot redraw rate, Hz")
    plot_history_s: float = _opt(60.0, "history kept in live plots, s")


@dataclass
class SerialOptions:
    port: str = _opt("", "serial port or pyserial URL; empty = discover the suit")
    baud: int = _opt(1_000_000, "baud rate (nominal over Bluetooth SPP)")
    discovery_timeout_s: float = _opt(1.0, "wait for the 'BPMS' answer per port, s")
    read_timeout_s: float = _opt(0.05, "serial read timeout, s")
    link_lost_after_s: float = _opt(1.0, "silence that counts as a lost link, s")


@dataclass
class UdpOptions:
    forward_to: list[str] = _opt(["127.0.0.1:5005"], "UDP server targets, host:port",
                                 hostports=True)
    listen: str = _opt("0.0.0.0:5005", "UDP client listens on host:port", hostport=True)
    multicast_ttl: int = _opt(1, "multicast time-to-live, hops")
    key_file: str = _opt("", "file holding the shared UDP key that signs and checks every "
                         "datagram (docs/udp.md); empty = no key; the BPMS_UDP_KEY "
                         "environment variable wins")
    takeover_after_s: float = _opt(
        5.0, "UDP client: another sender takes over only after the one followed has been "
        "silent this long, s, and then only after 25 consecutive datagrams (docs/udp.md)")


@dataclass
class LoggingOptions:
    directory: str = _opt("", "folder for recordings; empty = the per-user recordings folder")
    name: str = _opt("", "file name stem; empty = a time stamp")
    raw: bool = _opt(True, "record raw frames")
    filtered: bool = _opt(True, "record filtered angles")
    flush_interval_s: float = _opt(1.0, "data reach the disk at least this often, s")
    disk_reserve_s: float = _opt(
        120.0, "free disk space kept for the raw recording, in seconds of raw data (17.4 kB "
        "per second): below it the filtered file stops first, the raw file goes on until the "
        "disk is full; 0 = no reserve (docs/pipeline.md)")


@dataclass
class PoseOptions:
    reset_window_s: float = _opt(0.5, "Reset Zero averages the DCMs over this still window, s")
    heading_reference: str = _opt(
        "hip", "body heading at Reset Zero: the 'hip' IMU's yaw (docs/body-model.md) or the "
        "'mean' of all IMUs' yaws (averages out mounting yaw errors)")
    corrected_output: bool = _opt(
        True, "per-IMU Euler angles shown, written and streamed are the segment orientations "
        "relative to the calibration pose (Reset Zero); false: the uncorrected sensor angles")


#: The height the factory segment lengths belong to (Table 2.4), m.
REFERENCE_HEIGHT_M = 1.73


@dataclass
class BodyOptions:
    """Segment lengths, m (dissertation Table 2.4, 50th-percentile US male, 1.73 m tall).

    ``height`` is honoured when the options are read: every length not given one by one in
    the same file (or dict) is the factory length scaled by ``height / 1.73``
    (:meth:`scaled_to`)."""

    low_spine: float = _opt(0.21, "low spine, m")
    mid_spine: float = _opt(0.27, "mid spine, m")
    neck: float = _opt(0.20, "neck, m")
    head: float = _opt(0.22, "head, m")
    shoulder: float = _opt(0.16, "shoulder, m")
    arm: float = _opt(0.34, "upper arm, m")
    forearm: float = _opt(0.27, "forearm, m")
    hand: float = _opt(0.19, "hand, m")
    hip: float = _opt(0.17, "half hip width, m")
    thigh: float = _opt(0.43, "thigh, m")
    shank: float = _opt(0.40, "shank, m")
    foot: float = _opt(0.27, "foot, m")
    height: float = _opt(1.73, "subject height, m; lengths not given one by one scale with "
                         "it (factory lengths × height / 1.73)")

    def scaled_to(self, height: float, keep: tuple[str, ...] = ()) -> BodyOptions:
        """These options for a subject ``height`` m tall: every length but those in ``keep``
        is the factory length × height / 1.73."""
        factory = BodyOptions()
        ratio = height / REFERENCE_HEIGHT_M
        values = {f.name: (getattr(self, f.name) if f.name in keep
                           else getattr(factory, f.name) * ratio)
                  for f in dataclasses.fields(self) if f.name != "height"}
        return BodyOptions(**values, height=height)


@dataclass
class TrackOptions:
    heel_strike_g: float = _opt(2.0, "heel strike: foot acceleration peak above, g")
    min_step_interval_s: float = _opt(0.4, "heel strikes of one foot at least this far apart, s")
    declination_deg: float = _opt(0.0, "local magnetic declination, deg east")


@dataclass
class JointOptions:
    """Joint-angle sign convention (docs/joint-angles.md)."""

    convention: str = _opt("isb", "joint-angle signs: 'isb' (flexion, abduction, external "
                           "rotation positive on both sides) or 'original' (raw Euler, "
                           "left/right mirrored); docs/joint-angles.md")


@dataclass
class LslOptions:
    """Lab Streaming Layer outlets (docs/lsl.md)."""

    enabled: bool = _opt(False, "send segment orientations, joint angles, sensor data and "
                         "events as LSL streams; docs/lsl.md")
    link_delay_s: float = _opt(0.0, "suit → computer delay subtracted from LSL time stamps, s")


@dataclass
class MvnOptions:
    """The MVN-compatible UDP stream (docs/mvn.md)."""

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


def _attach_ranges() -> None:
    """Copy :data:`VALID_RANGES` into the fields' metadata (``min``/``max``/``choices``), so
    forms and parsers that read the metadata see the one table."""
    import types

    for name, section in Options().sections().items():
        for f in dataclasses.fields(section):
            rng = option_range(name, f.name)
            if rng is None:
                continue
            bounds = {"min": rng.lo, "max": rng.hi, "choices": rng.choices}
            f.metadata = types.MappingProxyType({**f.metadata, "range": rng, **{
                name: value for name, value in bounds.items() if value is not None}})


_attach_ranges()


def check_option(section: str, key: str, value: Any) -> Any:
    """``value`` converted for option ``section.key``, or :class:`OptionRangeError` (a
    ValueError) naming the range, e.g. ``filter.kp_rollpitch = 2.0 is outside the valid range
    [0, 0.18] (monotone correction: ...)``. Unknown keys raise OptionRangeError too."""
    target = Options().sections().get(section)
    spec = {f.name: f for f in dataclasses.fields(target)}.get(key) if target else None
    if spec is None:
        raise OptionRangeError(f"unknown option {section}.{key}")
    checked, problem = _check_value(value, getattr(target, key), dict(spec.metadata))
    if problem:
        raise OptionRangeError(f"{section}.{key}: {problem}")
    return checked


def ranges_markdown() -> str:
    """The valid-range table as a Markdown table (docs/configuration.md holds this text; a
    test keeps the two equal)."""
    rows = ["| option | valid values | factory | why |", "|---|---|---|---|"]
    factory = Options()
    for section, keys in VALID_RANGES.items():
        for key, rng in keys.items():
            value = getattr(getattr(factory, section), key)
            rows.append(f"| `{section}.{key}` | {rng.describe()} | {value!r} | {rng.why} |")
    return "\n".join(rows)


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
        if ("min" in meta and value < meta["min"]) or ("max" in meta and value > meta["max"]):
            rng = meta["range"]
            why = f" ({rng.why})" if rng.why else ""
            return None, f"{value} is outside the valid range {rng.describe()}{why}"
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
        if section == "body" and isinstance(content, dict) and "height" in content:
            given = tuple(k for k in content if k != "height")
            options.body = options.body.scaled_to(options.body.height, keep=given)
    return options


def load_options(path: str | Path | None) -> Options:
    """Read an options file. ``None`` gives the factory options. Never raises."""
    if path is None:
        return Options()
    path = Path(path)
    try:
        text = read_config_bytes(path).decode("utf-8")
    except (OSError, UnicodeDecodeError, BoundError) as exc:
        options = Options(source=f"factory ({path} unreadable)")
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        report(options.problems, path, "file", f"cannot be read ({why})", "factory options used")
        return options
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError, MemoryError) as exc:
        why = str(exc) if isinstance(exc, tomllib.TOMLDecodeError) else "nested too deeply"
        options = Options(source=f"factory ({path} invalid)")
        report(options.problems, path, "syntax", why, "factory options used")
        return options
    return options_from_dict(data, path)


def format_options(options: Options) -> str:
    """Commented TOML text of ``options``."""
    out = ["# BPMS Suite options. Each value has its unit and valid range in the comment above "
           "it (docs/configuration.md).", ""]
    owner: dict[str, str] = {}  # a setting shared by two filters sits with the first
    for algo, keys in ALGORITHM_SETTINGS.items():
        for key in keys:
            owner.setdefault(key, algo)
    for name, section in options.sections().items():
        out.append(f"[{name}]")
        fields = list(dataclasses.fields(section))
        if name == "filter":  # shared settings first, then each filter's own, grouped
            order = {algo: k for k, algo in enumerate(ALGORITHM_SETTINGS, start=1)}
            fields = sorted(fields, key=lambda f: order.get(owner.get(f.name, ""), 0))
        group = None
        for f in fields:
            if name == "filter" and owner.get(f.name) != group:
                group = owner.get(f.name)
                users = [a for a, keys in ALGORITHM_SETTINGS.items()
                         if any(owner.get(k) == group for k in keys)]
                out.append(f"\n# ---- {group} settings (used when algorithm = "
                           f"{' or '.join(repr(u) for u in users)}) ----")
            rng = f.metadata.get("range")
            valid = f"; valid {rng.describe()}" if rng is not None else ""
            out.append(f"# {f.metadata.get('help', '')}{valid}")
            out.append(tomli_w.dumps({f.name: getattr(section, f.name)}).rstrip())
        out.append("")
    return "\n".join(out)


def save_options(options: Options, path: str | Path) -> None:
    """Write the options file atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(format_options(options), encoding="utf-8")
    tmp.replace(path)
