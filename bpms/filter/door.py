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

Times: each chunk's ``result.t`` is stream time (:func:`bpms.io.timebase.stream_times`,
frame index × dt) and ``host_time`` the host receive time (s since the epoch, UTC).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.result import Result
from bpms.io.calib_file import CalibrationTable
from bpms.io.frames import DecodedFrames, decode_frames
from bpms.io.options import HEADING_TEXT, Options, load_options, options_from_dict
from bpms.io.rawfile import MAGIC, RECORD_DTYPE, RECORD_SIZE, RawFileError, RawRecording

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
        label = explicit.source if isinstance(explicit, CalibrationTable) else str(explicit)
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
    _data_offset: int = field(default=0, repr=False)

    @property
    def has_raw(self) -> bool:
        """True when chunks carry raw counts (a raw recording, not a filtered file)."""
        return self.kind != "filtered"

    def sources_line(self) -> str:
        """``calibration: <source>; options: <source>`` (the CLI prints it on stderr)."""
        return f"calibration: {self.calibration_source}; options: {self.options_source}"

    def chunks(self, zero_at_s: Sequence[float] = (), progress: Progress | None = None,
               chunk_frames: int = CHUNK_FRAMES,
               zero_at_frames: Sequence[int] = ()) -> Iterator[Chunk]:
        """Filter the recording as one stream, ``chunk_frames`` at a time.

        zero_at_s: extra Reset Zero captures at these stream times (s); zero_at_frames: the
        same as frame indices. progress(label, done, total) after each chunk."""
        dt = self.processor.options.filter.dt
        zero = sorted({round(t / dt) for t in zero_at_s} | {int(k) for k in zero_at_frames})
        label = f"filtering {self.path.name}"
        self.processor.restart()
        if self.kind == "filtered":
            source = self._filtered_chunks(zero, chunk_frames)
        else:
            source = self._raw_chunks(zero, chunk_frames)
        for chunk in source:
            yield chunk
            if progress:
                progress(label, chunk.start + len(chunk), self.n_frames)
        self.problems.extend(p for p in self.processor.problems if p not in self.problems)

    def raw_chunks(self, chunk_frames: int = CHUNK_FRAMES
                   ) -> Iterator[tuple[int, np.ndarray, DecodedFrames]]:
        """The raw frames without filtering: (first index, host times ``[n]`` s since the
        epoch, decoded frames) per chunk. Raises ValueError for a filtered file."""
        if not self.has_raw:
            raise ValueError(f"{self.path}: a filtered file holds no raw frames")
        for lo, host, frames in self._raw_records(chunk_frames):
            yield lo, host, decode_frames(frames)

    def _frames_in(self, zero: list[int], lo: int, n: int) -> list[int]:
        return [k - lo for k in zero if lo <= k < lo + n]

    def _raw_chunks(self, zero: list[int], chunk_frames: int) -> Iterator[Chunk]:
        proc = self.processor
        for lo, host, frames in self._raw_records(chunk_frames):
            decoded = decode_frames(frames)
            result = proc.process(decoded.raw, decoded.errors, self._frames_in(zero, lo,
                                                                              len(host)))
            yield Chunk(lo, result, host, decoded.raw, decoded.errors,
                        np.zeros(len(host), dtype=bool))

    def _raw_records(self, chunk_frames: int) -> Iterator[tuple[int, np.ndarray, bytes]]:
        """(first index, host times, frame bytes) per chunk; native files stream from disk."""
        if self.recording is not None:
            rec = self.recording
            for lo in range(0, len(rec), chunk_frames):
                hi = min(len(rec), lo + chunk_frames)
                yield lo, rec.times[lo:hi].copy(), rec.frames[lo:hi].tobytes()
            return
        index = 0
        damaged = 0
        with open(self.path, "rb") as f:
            f.seek(self._data_offset)
            while True:
                data = f.read(RECORD_SIZE * chunk_frames)
                if not data:
                    break
                torn = len(data) % RECORD_SIZE
                if torn:
                    self._note(f"{self.path}: the last record is incomplete ({torn} of "
                               f"{RECORD_SIZE} bytes, the recording was cut off): ignored")
                    data = data[: len(data) - torn]
                records = np.frombuffer(data, dtype=RECORD_DTYPE)
                good = ((records["frame"]["start"] == b"$#")
                        & (records["frame"]["end"] == b"#$"))
                if not good.all():
                    damaged += int((~good).sum())
                    records = records[good]
                if len(records):
                    yield index, records["time"].copy(), records["frame"].tobytes()
                    index += len(records)
                if torn:
                    break
        if damaged:
            self._note(f"{self.path}: {damaged} damaged record(s) without frame markers: "
                       "skipped")

    def _note(self, message: str) -> None:
        log.warning("%s", message)
        self.problems.append(message)

    def _filtered_chunks(self, zero: list[int], chunk_frames: int) -> Iterator[Chunk]:
        """R from the logged sensor Euler angles (``R = Rz Ry Rx``), then Reset Zero, joints
        and positions as the processor does."""
        from bpms.filter.rotations import euler_to_dcm
        from bpms.io.filtered_file.reader import FilteredReader

        proc = self.processor
        reader = FilteredReader(self.path)
        name = ("euler_sensor" if "euler_sensor" in reader.info.groups
                else "euler")
        if name == "euler" and reader.info.euler_kind == "segment":
            self._note(f"{self.path}: holds Reset-Zero-corrected angles only; Reset Zero is "
                       "redone on them")
        lo = 0
        with reader:
            for block in reader.blocks(chunk_frames):
                euler = block.groups[name]
                R = euler_to_dcm(euler[..., 0], euler[..., 1], euler[..., 2])
                before = len(proc.pose.captures)
                C = proc.pose.apply(R, self._frames_in(zero, lo, len(block)))
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
                 auto_zero: bool = True, progress: Progress | None = None) -> Result:
    """Filter a whole recording (native raw, the original suite's pickled raw, or a filtered
    CSV) through :func:`open_for_processing`: calibration and options given here, else the
    recording's header, else the user's default, else factory (the result's
    ``calibration_source`` / ``options_source`` say which). ``zero_at_s`` /
    ``zero_at_frames``: extra Reset Zero captures. Raises :class:`bpms.io.rawfile.RawFileError`
    for an unreadable file. For long recordings in constant memory iterate
    ``open_for_processing(path).chunks()`` instead."""
    opened = open_for_processing(path, calibration, options, algorithm=algorithm,
                                 heading=heading, auto_zero=auto_zero)
    return opened.result(zero_at_s, progress, zero_at_frames=zero_at_frames)


def is_raw_recording(path: str | Path) -> bool:
    """True for a native raw recording or a legacy pickled raw file."""
    from bpms.io.legacy_raw import is_legacy_raw

    try:
        with open(path, "rb") as f:
            if f.read(len(MAGIC)) == MAGIC:
                return True
    except OSError:
        return False
    return is_legacy_raw(path)


def open_for_processing(path: str | Path, calibration: str | Path | CalibrationTable | None = None,
                        options: str | Path | Options | None = None,
                        algorithm: str | None = None, heading: str | None = None,
                        auto_zero: bool = True) -> OpenedRecording:
    """Open a recording and build its processor (the module docstring has the precedence).

    path: a native raw recording, a legacy pickled raw file, or a filtered CSV file;
    calibration / options: explicit choices (a file path or an object), None to follow the
    precedence; algorithm: the attitude filter (``FilterOptions.algorithm``) and heading: the
    Reset Zero heading reference (``PoseOptions.heading_reference``), overriding the options.
    Raises :class:`bpms.io.rawfile.RawFileError` / :class:`bpms.io.filtered_file.
    FilteredFileError` for an unreadable file, ``VqfMissingError`` for vqf without the package.
    """
    path = Path(path)
    problems: list[str] = []
    try:
        with path.open("rb") as f:
            head = f.read(len(MAGIC))
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    recording = None
    offset = 0
    if head == MAGIC:
        from bpms.io.rawfile import read_header

        kind = "raw"
        header, offset = read_header(path)
        size = path.stat().st_size - offset
        n = size // RECORD_SIZE
    elif is_raw_recording(path):
        from bpms.io.legacy_raw import read_legacy_raw

        kind = "legacy"
        recording = read_legacy_raw(path)
        header, n = recording.header, len(recording)
        problems.extend(recording.problems)
    elif path.suffix.lower() in FILTERED_SUFFIXES:
        from bpms.io.filtered_file.reader import FilteredReader

        FilteredReader(path).close()  # a file that is not a filtered file fails here
        kind, header, n = "filtered", {}, _count_rows(path)
    else:
        raise RawFileError(f"{path}: not a BPMS recording (neither a raw recording, the "
                           "original suite's raw file, nor a filtered .csv file)")
    opts, options_source = resolve_options(options, header if kind != "filtered" else None,
                                           str(path))
    changes = []
    if algorithm is not None and algorithm != opts.filter.algorithm:
        changes.append(f"filter {algorithm}")
    if heading is not None and heading != opts.pose.heading_reference:
        changes.append(f"heading {heading}")
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
    processor = BodyPoseProcessor(cal, opts, auto_zero=auto_zero)
    problems.extend(processor.problems)
    return OpenedRecording(path, kind, header, int(n), processor, calibration_source,
                           options_source, problems, recording, offset)


def _count_rows(path: Path) -> int:
    """Data rows of a filtered file (lines neither blank, ``#`` nor the column row); for
    progress only."""
    count = 0
    header = 0
    with open(path, "rb") as f:
        for line in f:
            if line.strip() and not line.startswith(b"#"):
                count += 1
                if count == 1 and line.startswith(b"time_s"):
                    header = 1
    return count - header


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
    if isinstance(result, type):
        has_sensor = (hasattr(result, "euler_sensor")
                      or "euler_sensor" in getattr(result, "__dataclass_fields__", {}))
        has_flags = True
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
            out[g] = result.corrected.astype(np.float64)[:, None]
        elif g == "joints":
            out[g] = result.joint_angles
        elif g == "mag_disturbed":
            if dist is not None:
                out[g] = dist.mag
        elif g == "acc_disturbed":
            if dist is not None:
                out[g] = dist.acc
        elif getattr(result, g, None) is not None:
            out[g] = getattr(result, g)
    return out
