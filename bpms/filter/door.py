"""The one door into a recording: :func:`open_for_processing`.

Every way of opening a recording for its angles goes through here — ``bpms filter``,
``export``, ``rom``, ``track``, ``extract``, ``BodyPoseProcessor.process_file``, GUI playback
and ``bpms replay`` — so that one recording gives the same numbers whichever way it is opened.

It reads a native raw recording (``.bpmsraw``, streamed from disk chunk by chunk), the
original suite's pickled raw file, or a filtered CSV file (:mod:`bpms.io.filtered_file`, any
version), picks the calibration and the options by one precedence (docs/configuration.md):

    explicit argument > the recording's header > the user's default > factory

builds the :class:`~bpms.filter.processor.BodyPoseProcessor`, and says which source it used
(:attr:`OpenedRecording.calibration_source`, :attr:`OpenedRecording.options_source`).
Results come chunk by chunk (:meth:`OpenedRecording.chunks`) so that callers write or reduce
them as they are produced and memory stays flat however long the recording.

Native recordings are read by the one reader (:class:`bpms.io.raw_reader.RawFile`): damaged
frames keep their slots, and the events recorded live (Reset Zero, alignment, filter and gain
changes, filters re-initialised) are applied at their frames, so that the numbers equal the
filtered file written live. ``reset_zero`` (:class:`bpms.filter.zero_choice.ResetZeroChoice`,
``--reset-zero``) overrides the recorded Reset Zero captures; an explicit filter or options
file overrides the recorded filter and gain changes.

Times: each chunk's ``result.t`` is stream time (:func:`bpms.io.timebase.stream_times`,
frame index × dt) and ``host_time`` the host receive time (s since the epoch, UTC).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.result import Result
from bpms.filter.zero_choice import ResetZeroChoice, fallback_line, planned_events
from bpms.io.calib_file import CalibrationTable
from bpms.io.frames import DecodedFrames, decode_frames
from bpms.io.options import HEADING_TEXT, Options, load_options, options_from_dict
from bpms.io.raw_reader import RawFile, RawFrames, no_frame_message
from bpms.io.rawfile import MAGIC, RawFileError, RawRecording
from bpms.io.recordings import read_head
from bpms.io.session_events import SessionEvent
from bpms.io.subject import header_subject

log = logging.getLogger(__name__)

CHUNK_FRAMES = 5_000  # 100 s at 50 Hz per filter call: ~50 MB of intermediate arrays at most
Progress = Callable[[str, int, int], None]
FILTERED_SUFFIXES = (".csv", ".txt")


def header_calibration(header: dict, where: str = "recording") -> CalibrationTable | None:
    """The calibration table stored in a raw recording's header, or None (none, or unusable)."""
    values = header.get("calibration")
    if values is None:
        return None
    try:
        return CalibrationTable(np.asarray(values, dtype=np.float64), source=f"{where} header")
    except (ValueError, TypeError):
        return None


def header_options(header: dict, where: str = "recording") -> Options | None:
    """The options stored in a raw recording's header, or None."""
    stored = header.get("options")
    if isinstance(stored, dict) and stored:
        return options_from_dict(stored, f"{where} header")
    return None


def resolve_calibration(explicit: str | Path | CalibrationTable | None, header: dict | None,
                        where: str = "recording", problems: list[str] | None = None
                        ) -> tuple[str | Path | CalibrationTable, str]:
    """(calibration for :class:`BodyPoseProcessor`, its source) by the precedence: explicit >
    header > the user's default > factory. A path stays a path (its ``Calib.json`` companion
    is used by the processor)."""
    from bpms.io.defaults import default_calibration

    if explicit is not None:
        label = (str(explicit) if isinstance(explicit, str | Path)
                 else getattr(explicit, "source", "table"))
        return explicit, f"given ({label})"
    if header is not None and header.get("calibration") is not None:
        table = header_calibration(header, where)
        if table is not None:
            return table, "recording header"
        if problems is not None:
            problems.append(f"{where}: the calibration in its header is unusable; the default "
                            "is used")
    table = default_calibration(announce=False)  # the sources line says "factory"
    return table, table.source


def resolve_options(explicit: str | Path | Options | None, header: dict | None,
                    where: str = "recording") -> tuple[Options, str]:
    """(options, their source) by the same precedence as :func:`resolve_calibration`."""
    from bpms.io.defaults import default_options

    if explicit is not None:
        opts = explicit if isinstance(explicit, Options) else load_options(explicit)
        label = explicit.source if isinstance(explicit, Options) else str(explicit)
        return opts, f"given ({label})"
    if header is not None:
        stored = header_options(header, where)
        if stored is not None:
            return stored, "recording header"
    opts = default_options(announce=False)
    return opts, getattr(opts, "source", "factory")


@dataclass
class Chunk:
    """Consecutive frames of a recording and their filter result.

    start: index of the first frame; result: :class:`Result` (``t`` stream time, s);
    host_time ``[n]`` s since the epoch (NaN unknown); raw ``[n, 18, 9]`` int16 and errors
    ``[n, 18, 3]`` (None for a filtered file); hole ``[n]`` bool: frames the filtered file
    marks as not filtered (all False for a raw recording).
    """

    start: int
    result: Result
    host_time: np.ndarray
    raw: np.ndarray | None = None
    errors: np.ndarray | None = None
    hole: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.result)


@dataclass
class OpenedRecording:
    """A recording opened by :func:`open_for_processing`.

    kind: ``"raw"`` (native), ``"legacy"`` (pickled) or ``"filtered"``; n_frames: frames
    (rows) it holds; processor: the processor built for it (iterate :meth:`chunks` once: it
    continues the processor's stream); calibration_source / options_source: where each came
    from (``given (...)``, ``recording header``, ``user default (...)``, ``factory``, or
    ``not used`` for a filtered file's calibration); problems: warnings met so far.
    """

    path: Path
    kind: str
    header: dict
    n_frames: int
    processor: BodyPoseProcessor
    calibration_source: str
    options_source: str
    problems: list[str] = field(default_factory=list)
    recording: RawRecording | None = field(default=None, repr=False)
    file: RawFile | None = field(default=None, repr=False)
    reset_zero: ResetZeroChoice = field(default_factory=ResetZeroChoice)
    #: an explicit filter or options file: the recorded filter and gain changes do not apply
    settings_given: bool = False
    #: host receive time of the first valid frame (s since the epoch; NaN unknown)
    first_host_time: float = math.nan
    #: the recording's slots for replay (``for_replay``: a native one read from disk as it
    #: plays, a legacy one in memory); None otherwise
    slots: RawFrames | RawRecording | None = field(default=None, repr=False)
    #: the pose calibration's event, ``(slot, reset_zero event)`` (:meth:`use_pose_calibration`)
    pose_event: tuple[int, SessionEvent] | None = field(default=None, repr=False)
    pose_report: object | None = field(default=None, repr=False)

    @property
    def has_raw(self) -> bool:
        """True when chunks carry raw counts (a raw recording, not a filtered file)."""
        return self.kind != "filtered"

    def sources_line(self) -> str:
        """``calibration: <source>; options: <source>`` (the CLI prints it on stderr)."""
        return f"calibration: {self.calibration_source}; options: {self.options_source}"

    @property
    def has_events(self) -> bool:
        """The recording stores its session's events (raw format version 2)."""
        return self.file is not None and self.file.has_events

    def use_reset_zero(self, choice: ResetZeroChoice | None = None) -> None:
        """Set which Reset Zero applies (``choice``, or the current :attr:`reset_zero`): the
        processor's own provisional and automatic captures follow from it (in force from its
        next restart)."""
        if choice is not None:
            self.reset_zero = choice
        self.processor.pose.auto = self.reset_zero.automatic(self.has_events)
        self.processor.pose.provisional = self.reset_zero.provisional(self.has_events)

    def use_pose_calibration(self, choice: str | None, posture: str | dict | None = None
                             ) -> str:
        """``--pose-calibration`` (:mod:`bpms.filter.pose_methods`): ``reset-zero`` (None)
        changes nothing; ``posture`` / ``functional`` make their event from a first pass now,
        applied by every later :meth:`chunks`. Returns its description. Raises ValueError."""
        from bpms.filter.pose_methods import PoseCalibrationChoice, calibration_event

        method = PoseCalibrationChoice.parse(choice, posture)
        self.pose_event = None
        if not method.default:
            if self.reset_zero.mode == "none":
                raise ValueError(f"{method.describe()} needs a Reset Zero still window, not "
                                 "--reset-zero none")
            self.pose_event = calibration_event(self, method)
        return method.describe()

    def chunks(self, zero_at_s: Sequence[float] = (), progress: Progress | None = None,
               chunk_frames: int = CHUNK_FRAMES,
               zero_at_frames: Sequence[int] = ()) -> Iterator[Chunk]:
        """Filter the recording as one stream, ``chunk_frames`` at a time, the recorded
        events applied at their frames (as :attr:`reset_zero` chooses).

        zero_at_s: extra Reset Zero captures at these stream times (s); zero_at_frames: the
        same as frame indices. progress(label, done, total) after each chunk."""
        proc = self.processor
        dt = proc.options.filter.dt
        choice = self.reset_zero
        extra = sorted({round(t / dt) for t in zero_at_s} | {int(k) for k in zero_at_frames}
                       | set(choice.frames(dt)))
        label = f"filtering {self.path.name}"
        self.use_reset_zero()
        proc.restart()
        chunks = self._filtered_chunks if self.kind == "filtered" else self._raw_chunks
        for chunk in chunks(extra, chunk_frames):
            yield chunk
            if progress:
                progress(label, chunk.start + len(chunk), self.n_frames)
        self.problems.extend(p for p in proc.problems if p not in self.problems)

    def raw_chunks(self, chunk_frames: int = CHUNK_FRAMES
                   ) -> Iterator[tuple[int, np.ndarray, DecodedFrames]]:
        """The raw frames without filtering: (first index, host times ``[n]`` s since the
        epoch, decoded frames) per chunk. Raises ValueError for a filtered file."""
        if not self.has_raw:
            raise ValueError(f"{self.path}: a filtered file holds no raw frames")
        for lo, host, frames, _ in self._raw_records(chunk_frames):
            yield lo, host, decode_frames(frames)

    def replay_events(self, recorded: list[tuple[int, SessionEvent]]
                      ) -> list[tuple[int, SessionEvent]]:
        """The events replay applies (``bpms replay``, GUI playback): the same rules as
        :meth:`chunks`, for the whole recording's events ``(slot, event)``."""
        dt = self.processor.options.filter.dt
        planned = planned_events(recorded, self.reset_zero, self.settings_given,
                                 self.reset_zero.frames(dt), start=True)
        if planned.fallbacks:
            self._note(fallback_line(self.path, planned.fallbacks))
        return planned

    def _raw_chunks(self, extra: list[int], chunk_frames: int) -> Iterator[Chunk]:
        proc = self.processor
        skipped = 0
        fallbacks: list[int] = []
        for lo, host, frames, recorded in self._raw_records(chunk_frames):
            decoded = decode_frames(frames)
            # the events to apply in frames lo .. lo+n-1, as (index into the chunk, event)
            planned = planned_events(recorded, self.reset_zero, self.settings_given,
                                     [k for k in extra if lo <= k < lo + len(host)], start=lo == 0)
            skipped += planned.skipped
            fallbacks += planned.fallbacks
            if self.pose_event is not None and lo <= self.pose_event[0] < lo + len(host):
                planned.append(self.pose_event)
                planned.sort(key=lambda item: item[0])
            result = proc.process(decoded.raw, decoded.errors,
                                  [(slot - lo, event) for slot, event in planned])
            yield Chunk(lo, result, host, decoded.raw, decoded.errors,
                        np.zeros(len(host), dtype=bool))
        if skipped:
            self._note(f"{self.path}: {skipped} recorded filter/gain change(s) "
                       "not applied (a filter or options file was given)")
        if fallbacks:
            self._note(fallback_line(self.path, fallbacks))

    def _raw_records(self, chunk_frames: int
                     ) -> Iterator[tuple[int, np.ndarray, bytes, list[tuple[int, SessionEvent]]]]:
        """(first index, host times, frame bytes, recorded events) per chunk; native files
        stream from disk through the one reader."""
        if self.recording is not None:
            rec = self.recording
            for lo in range(0, len(rec), chunk_frames):
                hi = min(len(rec), lo + chunk_frames)
                yield lo, rec.times[lo:hi].copy(), rec.frames[lo:hi].tobytes(), []
            return
        assert self.file is not None
        for chunk in self.file.chunks(chunk_frames):
            yield chunk.start, chunk.times.copy(), chunk.frame_bytes(), chunk.events
        for p in self.file.problems:
            self._note(p, logged=True)

    def _note(self, message: str, logged: bool = False) -> None:
        if message in self.problems:
            return
        if not logged:
            log.warning("%s", message)
        self.problems.append(message)

    def _filtered_chunks(self, extra: list[int], chunk_frames: int) -> Iterator[Chunk]:
        """R from the logged sensor Euler angles (``R = Rz Ry Rx``), then Reset Zero, joints
        and positions as the processor does."""
        from bpms.filter.rotations import euler_to_dcm
        from bpms.io.filtered_file.reader import FilteredReader

        proc = self.processor
        reader = FilteredReader(self.path)
        name = "euler_sensor" if "euler_sensor" in reader.info.groups else "euler"
        if name == "euler" and reader.info.euler_kind == "segment":
            self._note(f"{self.path}: holds Reset-Zero-corrected angles only; Reset Zero is "
                       "redone on them")
        lo = 0
        with reader:
            for block in reader.blocks(chunk_frames):
                euler = block.groups[name]
                R = euler_to_dcm(euler[..., 0], euler[..., 1], euler[..., 2])
                before = len(proc.pose.captures)
                if lo == 0 and self.reset_zero.mode == "none":
                    proc.pose.adopt(np.tile(np.eye(3), (R.shape[1], 1, 1)), 0.0, "re-analysis")
                C = proc.pose.apply(R, [k - lo for k in extra if lo <= k < lo + len(block)])
                result = Result(t=block.t, R=R, euler=euler, C=C, body=proc.options.body,
                                zeros=list(proc.pose.captures[before:]),
                                convention=proc.options.joints.convention)
                yield Chunk(lo, result, block.host_time, None, None, block.hole)
                lo += len(block)
        for p in reader.problems:
            self._note(p)

    def result(self, zero_at_s: Sequence[float] = (), progress: Progress | None = None,
               zero_at_frames: Sequence[int] = ()) -> Result:
        """The whole recording as one :class:`Result`, its arrays allocated once and filled
        chunk by chunk (memory: the returned arrays plus one chunk's; iterate :meth:`chunks`
        for constant memory). The result carries ``calibration_source`` and
        ``options_source``."""
        result: Result | None = None
        filled = 0
        for chunk in self.chunks(zero_at_s, progress, zero_at_frames=zero_at_frames):
            if result is None:
                result = Result.allocate(max(self.n_frames, len(chunk)), chunk.result)
            if filled + len(chunk) > len(result):  # more rows than counted: grow (rare)
                result = Result.concat([result.head(filled), chunk.result])
            else:
                result.put(filled, chunk.result)
            filled += len(chunk)
        if result is None:
            result = Result.empty(self.processor.options.body,
                                  self.processor.options.joints.convention)
        elif filled < len(result):
            result = result.head(filled)
        result.problems.extend(self.problems)
        result.calibration_source = self.calibration_source
        result.options_source = self.options_source
        return result


def process_file(path: str | Path, calibration: str | Path | CalibrationTable | None = None,
                 options: str | Path | Options | None = None, *,
                 zero_at_s: Sequence[float] = (), zero_at_frames: Sequence[int] = (),
                 algorithm: str | None = None, heading: str | None = None,
                 reset_zero: str | ResetZeroChoice | None = None,
                 progress: Progress | None = None, pose_calibration: str | None = None,
                 posture: str | dict | None = None) -> Result:
    """Filter a whole recording (native raw, the original suite's pickled raw, or a filtered
    CSV) through :func:`open_for_processing`: calibration and options given here, else the
    recording's header, else the user's default, else factory (the result's
    ``calibration_source`` / ``options_source`` say which); the recorded events applied at
    their frames. ``reset_zero``: ``events`` (default), ``auto``, ``at SECONDS``, ``none``
    (:mod:`bpms.filter.zero_choice`); ``zero_at_s`` / ``zero_at_frames``: extra Reset Zero
    captures; ``pose_calibration``: ``reset-zero`` (None, default), ``posture`` (with
    ``posture``) or ``functional`` (:mod:`bpms.filter.pose_methods`). Raises
    :class:`bpms.io.rawfile.RawFileError` for an unreadable file or one with no valid frame,
    ValueError for a pose calibration that cannot be made. For long recordings in constant
    memory iterate ``open_for_processing(path).chunks()`` instead."""
    opened = open_for_processing(path, calibration, options, algorithm=algorithm,
                                 heading=heading, reset_zero=reset_zero)
    opened.use_pose_calibration(pose_calibration, posture)
    return opened.result(zero_at_s, progress, zero_at_frames=zero_at_frames)


def is_raw_recording(path: str | Path) -> bool:
    """True for a native raw recording or a legacy pickled raw file."""
    from bpms.io.legacy_raw import is_legacy_raw

    try:
        return read_head(Path(path)) == MAGIC or is_legacy_raw(path)
    except RawFileError:  # cannot be read
        return False


def open_for_processing(path: str | Path, calibration: str | Path | CalibrationTable | None = None,
                        options: str | Path | Options | None = None,
                        algorithm: str | None = None, heading: str | None = None,
                        reset_zero: str | ResetZeroChoice | None = None,
                        for_replay: bool = False) -> OpenedRecording:
    """Open a recording and build its processor (the module docstring has the precedence).

    path: a native raw recording, a legacy pickled raw file, or a filtered CSV file;
    calibration / options: explicit choices (a file path or an object), None to follow the
    precedence; algorithm: the attitude filter (``FilterOptions.algorithm``) and heading: the
    Reset Zero heading reference (``PoseOptions.heading_reference``), overriding the options;
    reset_zero: which Reset Zero (:class:`bpms.filter.zero_choice.ResetZeroChoice` or its
    text); for_replay: also keep the recording's slots for a replay (:attr:`OpenedRecording.
    slots`, a raw recording only: the one scan of the file serves both). Raises
    :class:`bpms.io.rawfile.RawFileError` / :class:`bpms.io.filtered_file.
    FilteredFileError` for an unreadable file or one with no valid frame, ValueError for a bad
    ``reset_zero``, ``VqfMissingError`` for vqf without the package.
    """
    choice = ResetZeroChoice.parse(reset_zero)
    path = Path(path)
    problems: list[str] = []
    recording = None
    file = None
    first_time = math.nan
    slots: RawFrames | RawRecording | None = None
    native = read_head(path) == MAGIC
    if native and for_replay:
        kind = "raw"
        slots = RawFrames(path)
        file, header, n = slots.file, slots.header, len(slots)
        if not slots.valid_frames:
            raise RawFileError(no_frame_message(path, n))
        first = int(np.setdiff1d(np.arange(min(n, len(slots.damaged) + 1)), slots.damaged)[0])
        first_time = float(slots.read(first, first + 1)[0][0])
    elif native:
        kind = "raw"
        file = RawFile(path)
        header = file.header
        n, valid, first_time = file.survey()
        if not valid:
            raise RawFileError(no_frame_message(path, n))
    elif is_raw_recording(path):
        from bpms.io.legacy_raw import read_legacy_raw

        kind = "legacy"
        recording = read_legacy_raw(path)
        header, n = recording.header, len(recording)
        problems.extend(recording.problems)
        if not recording.valid_frames:
            raise RawFileError(no_frame_message(path, len(recording)))
        first_time = float(recording.times[0])
        slots = recording if for_replay else None
    elif path.suffix.lower() in FILTERED_SUFFIXES and not for_replay:
        from bpms.io.filtered_file.reader import FilteredReader

        FilteredReader(path).close()  # a file that is not a filtered file fails here
        kind, header, n = "filtered", {}, _count_rows(path)
    else:
        raise RawFileError(f"{path}: not a BPMS recording (neither a raw recording, the "
                           "original suite's raw file, nor a filtered .csv file)")
    opts, options_source = resolve_options(options, header if kind != "filtered" else None,
                                           str(path))
    profile, trouble = header_subject(header) if options is None else (None, None)
    if trouble:
        problems.append(f"{path}: {trouble}")
    if profile is not None:  # the subject's own lengths (docs/subject.md)
        opts = dataclasses.replace(opts, body=profile.body_options())
        options_source += f" with subject {profile.subject_id}"
    changes = []
    if algorithm is not None and algorithm != opts.filter.algorithm:
        changes.append(f"filter {algorithm}")
    if heading is not None and heading != opts.pose.heading_reference:
        changes.append(f"heading {heading}")
    settings_given = options is not None or any(c.startswith("filter") for c in changes)
    if changes:
        opts = dataclasses.replace(opts)  # never change the caller's object
        opts.filter = dataclasses.replace(opts.filter, algorithm=algorithm or opts.filter.algorithm)
        opts.pose = dataclasses.replace(opts.pose,
                                        heading_reference=heading or opts.pose.heading_reference)
        options_source += " with " + ", ".join(changes)
    if kind == "filtered":
        cal: str | Path | CalibrationTable | None = None
        calibration_source = "not used (filtered file: angles as logged)"
    else:
        cal, calibration_source = resolve_calibration(calibration, header, str(path), problems)
    processor = BodyPoseProcessor(cal, opts)
    processor.calibration_source, processor.options_source = calibration_source, options_source
    problems.extend(processor.problems)
    opened = OpenedRecording(path, kind, header, int(n), processor, calibration_source,
                             options_source, problems, recording, file, choice, settings_given,
                             first_time, slots)
    opened.use_reset_zero()
    return opened


def _count_rows(path: Path) -> int:
    """Data rows of a filtered file (lines neither blank, ``#`` nor the column row); for
    progress only."""
    with open(path, "rb") as f:
        rows = (line for line in f if line.strip() and not line.startswith(b"#"))
        first = next(rows, None)
        if first is None:
            return 0
        return sum(1 for _ in rows) + (not first.startswith(b"time_s"))


#: Column groups of the state guard's and the disturbance indicators' per-IMU flags.
FLAG_GROUPS = ("reinitialised", "mag_disturbed", "acc_disturbed")
#: Column groups of the filters' estimates (``bpms filter --estimates``).
ESTIMATE_GROUPS = ("gyro_bias", "body_acc")


def heading_header(options: Options) -> dict[str, str]:
    """The ``heading:`` header line every output carries: the heading reference in force
    (``FilterOptions.heading``; ``relative`` is the 6D mode, docs/filters.md)."""
    return {"heading": HEADING_TEXT.get(options.filter.heading, options.filter.heading)}


def filtered_convention(convention: str) -> str:
    """The ``convention:`` header line of a filtered file: the Euler convention of the angle
    columns and the joint-angle convention (:data:`bpms.filter.joints.CONVENTION_TEXT`)."""
    from bpms.filter.joints import CONVENTION_TEXT

    return ("Euler roll, pitch, yaw (R = Rz Ry Rx), frame -> NED; joint angles: "
            + CONVENTION_TEXT.get(convention, convention))


def filtered_layout(result: Result | type[Result] = Result,
                    joints: bool = True, flags: bool = True,
                    estimates: bool = False) -> tuple[list[str], str]:
    """(column groups, ``euler`` kind) of a filtered file for results like ``result`` (an
    instance or the class): ``euler`` is what ``Result.euler`` holds; when Results also carry
    uncorrected ``euler_sensor`` angles, ``euler`` holds the output angles
    (``Result.euler_output``: segment angles after Reset Zero, per row as the ``corrected``
    column says) and ``euler_sensor`` the sensor angles. flags: add :data:`FLAG_GROUPS`
    (re-initialisation and disturbance flags) when the results carry them; estimates: add
    :data:`ESTIMATE_GROUPS` (gyro bias, body acceleration)."""
    groups = ["euler"]
    kind = "sensor"
    if isinstance(result, type):  # the class: every Result has euler_sensor and may have flags
        has_sensor = has_flags = True
    else:
        has_sensor = getattr(result, "euler_sensor", None) is not None
        has_flags = getattr(result, "disturbance", None) is not None
    if has_sensor:
        groups += ["euler_sensor", "corrected"]
        kind = "segment"
    if joints:
        groups.append("joints")
    if flags and has_flags:
        groups.extend(FLAG_GROUPS)
    if estimates:
        groups.extend(ESTIMATE_GROUPS)
    return groups, kind


def filtered_arrays(result: Result, groups: Sequence[str]) -> dict[str, np.ndarray]:
    """The per-group arrays of ``result`` for :meth:`FilteredWriter.write_block` (a group the
    result does not carry, e.g. ``body_acc`` of the Mahony filter, is left out: NaN)."""
    dist = getattr(result, "disturbance", None)
    out: dict[str, np.ndarray] = {}
    for g in groups:
        if g == "euler" and "euler_sensor" in groups:
            # the output angles: segment angles after Reset Zero where 'corrected', else sensor
            out[g] = result.euler_output
        elif g == "corrected":
            out[g] = np.asarray(result.corrected, dtype=np.float64)[:, None]
        elif g == "joints":
            out[g] = result.joint_angles
        elif g in ("mag_disturbed", "acc_disturbed"):
            if dist is not None:
                out[g] = getattr(dist, g[:3])  # Disturbance.mag / .acc
        elif getattr(result, g, None) is not None:
            out[g] = getattr(result, g)
    return out
