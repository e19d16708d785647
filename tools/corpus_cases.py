"""The files of the hostile-input corpus (tools/hostile_corpus.py runs commands on them).

:data:`CASES` lists every hostile input with what a correct reader makes of it, known from how
it is built (docs/raw-format.md): the frames it still holds (3 deleted bytes cost one frame and
keep its slot, a torn last record is dropped), or None when it must be refused; for absurd
configurations and headers, the text a warning must contain. :class:`CorpusFiles` builds them
from an intact 6 s recording of the simulated suit: truncations, random bytes, inserted and
deleted bytes, lost record markers, a header nested 200,000 levels deep, a 200 MB header
(sparse on the disk), empty files, directories, absurd headers, legacy pickles whose
``__reduce__`` would run code (and create :data:`MARKER`), absurd calibration and options
files.
"""

from __future__ import annotations

import os
import pickle
import shutil
import struct
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for _where in (REPO, Path(__file__).resolve().parent):
    if str(_where) not in sys.path:
        sys.path.insert(0, str(_where))

from corpus_events import N_SLOTS, record_with_events, walk  # noqa: E402  (tools/)

N_FRAMES = 300  # the intact recording: 6 s at 50 Hz
RECORD = 348  # bytes per raw record: float64 time + 340-byte frame (docs/raw-format.md)
PREAMBLE = struct.Struct("<8sHI")  # magic, version, header length (docs/raw-format.md)
MAGIC = b"BPMSRAW\0"
#: The file a pickle's ``__reduce__`` would create if the reader ran it.
MARKER = "PICKLE_RAN_CODE"


@dataclass(frozen=True)
class Case:
    """One hostile input. ``frames``: the frames a correct reader finds (None: the input must
    be refused); ``warns``: text that a warning line must contain (configurations and absurd
    headers); ``kind``: what the file is (recording, calibration, options)."""

    name: str
    damage: str  # the damage class (one line of the figures table)
    frames: int | None
    kind: str = "recording"
    warns: tuple[str, ...] = ()
    suffix: str = ".bpmsraw"
    #: event records damaged (format version 2): what the door does without them is the
    #: events' owners' (issue 43.1); the corpus checks exits, frames and outputs
    events_damaged: bool = False


R = "recording"
CASES: tuple[Case, ...] = (
    Case("intact", "control", N_FRAMES),
    Case("torn_tail", "truncation", N_FRAMES - 1),
    Case("truncated_half", "truncation", 150),
    Case("header_cut", "truncation", None),
    Case("preamble_only", "truncation", None),
    Case("deleted_3_bytes", "deleted bytes", N_FRAMES),
    Case("inserted_5_bytes", "inserted bytes", N_FRAMES),
    Case("markers_lost_5", "lost markers", N_FRAMES),
    Case("markers_lost_all", "lost markers", None),
    Case("random_body", "random bytes", None),
    Case("random_file", "random bytes", None),
    Case("empty", "empty file", None),
    Case("header_only", "empty file", None),
    Case("directory", "directory", None),
    Case("nested_header", "nested header", None),
    Case("huge_header", "200 MB header", None),
    Case("huge_length", "200 MB header", None),
    Case("header_not_json", "absurd header", None),
    Case("header_not_object", "absurd header", None),
    Case("newer_version", "absurd header", None),
    Case("absurd_times", "random bytes", N_FRAMES),
    Case("header_absurd_values", "absurd header", N_FRAMES,
         warns=("IMU 4", "kp_rollpitch")),
    Case("header_wrong_types", "absurd header", N_FRAMES, warns=("calibration",)),
    # format version 2: the events a live session writes (tools/corpus_events.py), damaged
    Case("v2_intact", "control", N_SLOTS),
    Case("v2_reset_zero_bits", "damaged events", N_SLOTS, events_damaged=True),
    Case("v2_every_event_bits", "damaged events", N_SLOTS, events_damaged=True),
    Case("v2_event_length", "damaged events", N_SLOTS, events_damaged=True),
    Case("v2_event_cut", "damaged events", N_SLOTS, events_damaged=True),
    Case("v2_event_marker_lost", "damaged events", N_SLOTS, events_damaged=True),
    Case("v2_torn_event", "damaged events", N_SLOTS, events_damaged=True),
    Case("v2_frames_and_events", "v2 random bytes", N_SLOTS, events_damaged=True),
    Case("v2_random_bits", "v2 random bytes", N_SLOTS, events_damaged=True),
    Case("v2_event_time_absurd", "absurd event time", N_SLOTS),
    Case("header_escaped_quotes", "hostile header text", None),
    Case("named_pipe", "not a file", None),
    Case("legacy_intact", "control", 40, suffix=".txt"),
    Case("legacy_reduce_exec", "pickle __reduce__", None, suffix=".txt"),
    Case("legacy_reduce_system", "pickle __reduce__", None, suffix=".txt"),
    Case("legacy_reduce_in_record", "pickle __reduce__", None, suffix=".txt"),
    Case("legacy_reduce_after_good", "pickle __reduce__", None, suffix=".txt"),
    Case("legacy_reduce_protocol_2", "pickle __reduce__", None, suffix=".txt"),
    Case("legacy_random", "random bytes", None, suffix=".txt"),
    Case("legacy_empty", "empty file", None, suffix=".txt"),
    Case("legacy_huge_int", "absurd legacy values", None, suffix=".txt"),
    # configurations, used with the intact recording
    Case("calib_gravity_tiny", "absurd calibration", N_FRAMES, "calibration", ("IMU 4",),
         ".cfg"),
    Case("calib_gyro_huge", "absurd calibration", N_FRAMES, "calibration", ("IMU 9",), ".cfg"),
    Case("calib_nan", "absurd calibration", N_FRAMES, "calibration", ("IMU 2",), ".cfg"),
    Case("calib_min_above_max", "absurd calibration", N_FRAMES, "calibration", ("IMU 5",),
         ".cfg"),
    Case("calib_17_records", "absurd calibration", N_FRAMES, "calibration",
         ("17 IMU records",), ".cfg"),
    Case("calib_random", "random bytes", N_FRAMES, "calibration", ("IMU records",), ".cfg"),
    Case("calib_empty", "empty file", N_FRAMES, "calibration", ("0 IMU records",), ".cfg"),
    Case("calib_directory", "directory", N_FRAMES, "calibration", ("cannot be read",), ".cfg"),
    Case("calib_huge", "200 MB header", N_FRAMES, "calibration", ("MiB",), ".cfg"),
    Case("calib_json_nested", "nested header", N_FRAMES, "calibration", ("nests",), ".cfg"),
    Case("calib_json_quotes", "hostile header text", N_FRAMES, "calibration",
         ("cannot be read",), ".cfg"),
    Case("options_gain_huge", "absurd options", N_FRAMES, "options", ("kp_rollpitch",),
         ".toml"),
    Case("options_gain_nan", "absurd options", N_FRAMES, "options", ("kp_yaw",), ".toml"),
    Case("options_wrong_types", "absurd options", N_FRAMES, "options",
         ("kp_rollpitch", "[display]"), ".toml"),
    Case("options_nested", "nested header", N_FRAMES, "options", ("nested too deeply",),
         ".toml"),
    Case("options_huge", "200 MB header", N_FRAMES, "options", ("MiB",), ".toml"),
    Case("options_random", "random bytes", N_FRAMES, "options", ("cannot be read",), ".toml"),
    Case("options_directory", "directory", N_FRAMES, "options", ("cannot be read",), ".toml"),
)
BY_NAME = {c.name: c for c in CASES}
RECORDING_CASES = tuple(c for c in CASES if c.kind == R)
CONFIG_CASES = tuple(c for c in CASES if c.kind != R)


# --------------------------------------------------------------------------- building


class _Reduce:
    """A pickled object whose ``__reduce__`` calls ``func(*args)`` when unpickled."""

    def __init__(self, func: Callable, *args: object) -> None:
        self.func, self.args = func, args

    def __reduce__(self):
        return self.func, self.args


def _write_raw_file(path: Path, header: bytes, body: bytes, version: int = 1,
                    length: int | None = None) -> None:
    pad = (-(PREAMBLE.size + len(header))) % 16
    header = header + b" " * pad
    path.write_bytes(PREAMBLE.pack(MAGIC, version, len(header) if length is None else length)
                     + header + body)


class CorpusFiles:
    """Every case of :data:`CASES` built in ``folder`` (``cases/<name>/``), beside the intact
    recording they are made from; :meth:`path` of each case."""

    def __init__(self, folder: str | Path) -> None:
        import numpy as np

        from bpms.firmware.sim.session import simulate
        from bpms.io.rawfile import new_header, write_raw

        self.folder = Path(folder)
        self.cases_dir = self.folder / "cases"
        self.out_dir = self.folder / "out"
        for d in (self.cases_dir, self.out_dir):
            d.mkdir(parents=True, exist_ok=True)
        rec = simulate(N_FRAMES * 0.02, seed=26)
        assert len(rec.t) == N_FRAMES
        self.frames = [rec.frames[k * 340:(k + 1) * 340] for k in range(N_FRAMES)]
        self.times = 1.7e9 + np.arange(N_FRAMES) * 0.02
        self.header = new_header(calibration=rec.calibration.values, source="hostile corpus")
        (self.folder / "intact").mkdir(exist_ok=True)
        self.intact = self.folder / "intact" / "Raw_corpus_1.bpmsraw"
        write_raw(self.intact, self.times, rec.frames, self.header)
        self._paths: dict[str, Path] = {}
        self._events: tuple[bytes, list] | None = None
        #: per version-2 case: the frame slots whose records its damage touched
        self.touched: dict[str, set[int]] = {}
        rng = np.random.default_rng(26)
        self._rng = rng
        for case in CASES:
            where = self.cases_dir / case.name
            where.mkdir(exist_ok=True)
            stem = "Raw_corpus_1" if case.kind == R else {"calibration": "Calib",
                                                          "options": "options"}[case.kind]
            path = where / (stem + case.suffix)
            getattr(self, f"_make_{case.name}")(path)
            self._paths[case.name] = path

    def path(self, case: Case) -> Path:
        return self._paths[case.name]

    # -- recordings ----------------------------------------------------------------------
    def _intact_bytes(self) -> tuple[bytearray, int]:
        data = bytearray(self.intact.read_bytes())
        length = PREAMBLE.unpack_from(data)[2]
        return data, PREAMBLE.size + length

    def _edit(self, path: Path, edit: Callable[[bytearray, int], None]) -> None:
        data, offset = self._intact_bytes()
        edit(data, offset)
        path.write_bytes(bytes(data))

    def _make_intact(self, path: Path) -> None:
        shutil.copyfile(self.intact, path)

    def _make_torn_tail(self, path: Path) -> None:
        self._edit(path, lambda d, o: d.__delitem__(slice(len(d) - 100, None)))

    def _make_truncated_half(self, path: Path) -> None:
        self._edit(path, lambda d, o: d.__delitem__(slice(o + 150 * RECORD + 200, None)))

    def _make_header_cut(self, path: Path) -> None:
        self._edit(path, lambda d, o: d.__delitem__(slice(o // 2, None)))

    def _make_preamble_only(self, path: Path) -> None:
        path.write_bytes(PREAMBLE.pack(MAGIC, 1, 1000))

    def _make_deleted_3_bytes(self, path: Path) -> None:
        self._edit(path, lambda d, o: d.__delitem__(slice(o + 150 * RECORD + 100,
                                                          o + 150 * RECORD + 103)))

    def _make_inserted_5_bytes(self, path: Path) -> None:
        def insert(d: bytearray, o: int) -> None:
            d[o + 150 * RECORD + 100:o + 150 * RECORD + 100] = b"\x55" * 5

        self._edit(path, insert)

    def _make_markers_lost_5(self, path: Path) -> None:
        def lose(d: bytearray, o: int) -> None:
            for k in range(100, 105):
                d[o + k * RECORD + 8:o + k * RECORD + 10] = b"\0\0"
                d[o + k * RECORD + 346:o + k * RECORD + 348] = b"\0\0"

        self._edit(path, lose)

    def _make_markers_lost_all(self, path: Path) -> None:
        def lose(d: bytearray, o: int) -> None:
            for k in range(N_FRAMES):
                d[o + k * RECORD + 8:o + k * RECORD + 10] = b"\0\0"

        self._edit(path, lose)

    def _make_random_body(self, path: Path) -> None:
        def randomise(d: bytearray, o: int) -> None:
            d[o:] = self._rng.bytes(len(d) - o)

        self._edit(path, randomise)

    def _make_absurd_times(self, path: Path) -> None:
        """Intact records whose receive times are damaged: 1e300 s in the first (the
        recording's start), NaN in another."""
        def times(d: bytearray, o: int) -> None:
            struct.pack_into("<d", d, o, 1e300)
            struct.pack_into("<d", d, o + 10 * RECORD, float("nan"))

        self._edit(path, times)

    def _make_random_file(self, path: Path) -> None:
        path.write_bytes(self._rng.bytes(100_000))

    def _make_empty(self, path: Path) -> None:
        path.write_bytes(b"")

    def _make_header_only(self, path: Path) -> None:
        self._edit(path, lambda d, o: d.__delitem__(slice(o, None)))

    def _make_directory(self, path: Path) -> None:
        path.mkdir()

    def _make_nested_header(self, path: Path) -> None:
        _write_raw_file(path, b"[" * 200_000, b"")

    def _make_huge_header(self, path: Path) -> None:
        """A 200 MB header, sparse on the disk (the readers must refuse it unread)."""
        length = 200 * 1000 * 1000
        with path.open("wb") as f:
            f.write(PREAMBLE.pack(MAGIC, 1, length) + b'{"notes": "')
            f.seek(PREAMBLE.size + length - 2)
            f.write(b'"}')

    def _make_huge_length(self, path: Path) -> None:
        _write_raw_file(path, b"{}", b"", length=0xFFFFFFFF)

    def _make_header_not_json(self, path: Path) -> None:
        _write_raw_file(path, b"\xff\xfe not json {{{", self._body())

    def _make_header_not_object(self, path: Path) -> None:
        _write_raw_file(path, b"[1, 2, 3]", self._body())

    def _make_newer_version(self, path: Path) -> None:
        _write_raw_file(path, self._header_json(), self._body(), version=999)

    def _make_header_absurd_values(self, path: Path) -> None:
        header = dict(self.header)
        cal = [list(row) for row in header["calibration"]]
        cal[4][0] = 1e-300  # Gravity of IMU 4
        header["calibration"] = cal
        header["options"] = {"filter": {"kp_rollpitch": 1e300}}
        header["frame_rate_hz"] = "fast"
        header["notes"] = 5
        _write_raw_file(path, self._header_json(header), self._body())

    def _make_header_wrong_types(self, path: Path) -> None:
        header = dict(self.header)
        header["calibration"] = "all of them"
        header["options"] = [1, 2]
        header["start_time"] = "yesterday"
        _write_raw_file(path, self._header_json(header), self._body())

    def _header_json(self, header: dict | None = None) -> bytes:
        import json

        return json.dumps(header or self.header).encode()

    def _body(self) -> bytes:
        return self.intact.read_bytes()[self._intact_bytes()[1]:]

    # -- format version 2: events and frames ---------------------------------------------
    def _events_recording(self) -> tuple[bytearray, list]:
        """The bytes of the live session's version-2 recording and its records (walked from
        the documented layout)."""
        if self._events is None:
            path = record_with_events(self.folder / "events")
            data = path.read_bytes()
            self._events = (data, walk(data)[1])
        data, pieces = self._events
        return bytearray(data), pieces

    def _v2(self, path: Path, damage: Callable[[bytearray, list], set[int]]) -> None:
        """Write the version-2 recording damaged by ``damage`` (which returns the frame slots
        whose records it touched)."""
        data, pieces = self._events_recording()
        self.touched[path.parent.name] = damage(data, pieces)
        path.write_bytes(bytes(data))

    @staticmethod
    def _flip(data: bytearray, at: int, bit: int = 2) -> None:
        data[at] ^= 1 << bit

    def _make_v2_intact(self, path: Path) -> None:
        self._v2(path, lambda d, p: set())

    def _make_v2_reset_zero_bits(self, path: Path) -> None:
        """One bit flipped in the middle of every Reset Zero record (its CRC then fails)."""
        def flip(d: bytearray, pieces: list) -> set[int]:
            for r in (r for r in pieces if r.kind == "reset_zero"):
                self._flip(d, r.offset + r.size // 2)
            return set()

        self._v2(path, flip)

    def _make_v2_every_event_bits(self, path: Path) -> None:
        """One bit flipped in the payload of every event record."""
        def flip(d: bytearray, pieces: list) -> set[int]:
            for r in (r for r in pieces if r.kind != "frame"):
                self._flip(d, r.offset + 14 + (r.size - 20) // 3)
            return set()

        self._v2(path, flip)

    def _make_v2_event_length(self, path: Path) -> None:
        """The manual Reset Zero's payload length 1,000 bytes too long (still plausible)."""
        def lengthen(d: bytearray, pieces: list) -> set[int]:
            r = [r for r in pieces if r.kind == "reset_zero"][2]
            n = struct.unpack_from("<I", d, r.offset + 10)[0]
            struct.pack_into("<I", d, r.offset + 10, n + 1000)
            return set()

        self._v2(path, lengthen)

    def _make_v2_event_cut(self, path: Path) -> None:
        """3 bytes deleted inside the automatic Reset Zero record."""
        def cut(d: bytearray, pieces: list) -> set[int]:
            r = [r for r in pieces if r.kind == "reset_zero"][1]
            del d[r.offset + 500:r.offset + 503]
            return set()

        self._v2(path, cut)

    def _make_v2_event_marker_lost(self, path: Path) -> None:
        """The start marker ("$E") of the marker event and of the gain change zeroed."""
        def lose(d: bytearray, pieces: list) -> set[int]:
            for r in (r for r in pieces if r.kind in ("marker", "gains")):
                d[r.offset + 8:r.offset + 10] = b"\0\0"
            return set()

        self._v2(path, lose)

    def _make_v2_torn_event(self, path: Path) -> None:
        """The file ends inside its last record (the logging-stop event): a crash."""
        def tear(d: bytearray, pieces: list) -> set[int]:
            del d[pieces[-1].offset + pieces[-1].size // 2:]
            return set()

        self._v2(path, tear)

    def _make_v2_frames_and_events(self, path: Path) -> None:
        """Three frame records' start markers lost, and a bit flipped in every event record
        after the first of them."""
        def damage(d: bytearray, pieces: list) -> set[int]:
            frames = [r for r in pieces if r.kind == "frame"]
            hit = {80, 81, 200}
            for r in frames:
                if r.slot in hit:
                    d[r.offset + 8:r.offset + 10] = b"\0\0"
            for r in pieces:
                if r.kind != "frame" and r.offset > frames[80].offset:
                    self._flip(d, r.offset + 14 + (r.size - 20) // 2)
            return hit

        self._v2(path, damage)

    def _make_v2_random_bits(self, path: Path) -> None:
        """40 bits flipped at random places among the records (seeded): the frame records
        they hit are the damaged ones."""
        def flips(d: bytearray, pieces: list) -> set[int]:
            touched: set[int] = set()
            for at in self._rng.integers(pieces[0].offset, len(d), 40):
                self._flip(d, int(at), int(at) % 8)
                touched |= {r.slot for r in pieces
                            if r.kind == "frame" and r.offset <= at < r.offset + r.size}
            return touched

        self._v2(path, flips)

    def _make_v2_event_time_absurd(self, path: Path) -> None:
        """The marker's time made 1e308 s and its frame a 400-digit integer, the note's time
        a 400-digit integer; each record rebuilt with a valid CRC (docs/raw-format.md)."""
        import json
        import zlib

        def retime(d: bytearray, pieces: list) -> set[int]:
            for r in sorted((r for r in pieces if r.kind in ("marker", "note")),
                            key=lambda r: -r.offset):  # from the end: offsets stay valid
                body = json.loads(bytes(d[r.offset + 14:r.offset + r.size - 6]))
                body["time"] = 1e308 if r.kind == "marker" else 10 ** 400
                if r.kind == "marker":
                    body["frame"] = 10 ** 400
                payload = json.dumps(body).encode()
                head = bytes(d[r.offset:r.offset + 10]) + struct.pack("<I", len(payload))
                head += payload
                d[r.offset:r.offset + r.size] = head + struct.pack("<I", zlib.crc32(head)) \
                    + b"E$"
            return set()

        self._v2(path, retime)

    def _make_header_escaped_quotes(self, path: Path) -> None:
        """A header of 1 MiB of escaped quotes in an unterminated string: the depth check was
        quadratic on it (hours; issue 43)."""
        _write_raw_file(path, b'{"notes": "' + b'\\"' * (512 * 1024), self._body())

    def _make_named_pipe(self, path: Path) -> None:
        """A named pipe where the recording should be (opening it would wait for a writer
        for ever); where there are none, an empty file."""
        if hasattr(os, "mkfifo"):
            os.mkfifo(path)
        else:
            path.write_bytes(b"")

    def _make_legacy_huge_int(self, path: Path) -> None:
        """Records whose time is a 400-digit integer (an OverflowError traceback before)."""
        path.write_bytes(b"".join(
            pickle.dumps([10 ** 400, self.frames[k].decode("latin1")], protocol=0)
            for k in range(10)))

    # -- legacy pickles ------------------------------------------------------------------
    def _legacy_records(self, n: int, protocol: int = 0) -> bytes:
        return b"".join(pickle.dumps([float(self.times[k]), self.frames[k].decode("latin1")],
                                     protocol=protocol) for k in range(n))

    def _evil(self, path: Path) -> _Reduce:
        target = path.parent / MARKER
        return _Reduce(exec, f"open({str(target)!r}, 'w').close()")

    def _make_legacy_intact(self, path: Path) -> None:
        path.write_bytes(self._legacy_records(40))

    def _make_legacy_reduce_exec(self, path: Path) -> None:
        path.write_bytes(pickle.dumps(self._evil(path), protocol=0))

    def _make_legacy_reduce_system(self, path: Path) -> None:
        target = path.parent / MARKER
        path.write_bytes(pickle.dumps(_Reduce(os.system, f"echo > {str(target)!r}"), 0))

    def _make_legacy_reduce_in_record(self, path: Path) -> None:
        path.write_bytes(pickle.dumps([1.7e9, self._evil(path)], protocol=0))

    def _make_legacy_reduce_after_good(self, path: Path) -> None:
        path.write_bytes(self._legacy_records(10)
                         + pickle.dumps([1.7e9, self._evil(path)], protocol=0))

    def _make_legacy_reduce_protocol_2(self, path: Path) -> None:
        path.write_bytes(pickle.dumps([1.7e9, self._evil(path)], protocol=2))

    def _make_legacy_random(self, path: Path) -> None:
        path.write_bytes(b"(lp0\n" + self._rng.bytes(5000))

    def _make_legacy_empty(self, path: Path) -> None:
        path.write_bytes(b"")

    # -- calibration files ---------------------------------------------------------------
    def _calib_rows(self) -> list[list[float]]:
        return [list(map(float, row)) for row in self.header["calibration"]]

    def _write_calib(self, path: Path, rows: list[list[float]]) -> None:
        path.write_text(";\n".join(",".join(repr(v) for v in row) for row in rows) + "\n")

    def _make_calib_gravity_tiny(self, path: Path) -> None:
        rows = self._calib_rows()
        rows[4][0] = 1e-300
        self._write_calib(path, rows)

    def _make_calib_gyro_huge(self, path: Path) -> None:
        rows = self._calib_rows()
        rows[9][13] = 30000.0
        self._write_calib(path, rows)

    def _make_calib_nan(self, path: Path) -> None:
        rows = self._calib_rows()
        rows[2][4] = float("nan")
        self._write_calib(path, rows)

    def _make_calib_min_above_max(self, path: Path) -> None:
        rows = self._calib_rows()
        rows[5][7], rows[5][8] = 400.0, -400.0
        self._write_calib(path, rows)

    def _make_calib_17_records(self, path: Path) -> None:
        self._write_calib(path, self._calib_rows()[:17])

    def _make_calib_random(self, path: Path) -> None:
        path.write_bytes(self._rng.bytes(3000).replace(b";", b"."))

    def _make_calib_empty(self, path: Path) -> None:
        path.write_bytes(b"")

    def _make_calib_directory(self, path: Path) -> None:
        path.mkdir()

    def _make_calib_huge(self, path: Path) -> None:
        self._write_calib(path, self._calib_rows())
        with path.open("a") as f:
            f.write("#" * (2 * 1024 * 1024))

    def _make_calib_json_quotes(self, path: Path) -> None:
        """A good Calib.cfg whose Calib.json holds 600 kB of escaped quotes in a string that
        never ends (a 60 kB one took 14 s to refuse)."""
        self._write_calib(path, self._calib_rows())
        path.with_suffix(".json").write_text('{"format": "bpms-calibration", "notes": "'
                                             + '\\"' * 300_000)

    def _make_calib_json_nested(self, path: Path) -> None:
        """A good Calib.cfg whose modern companion Calib.json nests 200,000 levels."""
        self._write_calib(path, self._calib_rows())
        path.with_suffix(".json").write_text("[" * 200_000)

    # -- options files -------------------------------------------------------------------
    def _make_options_gain_huge(self, path: Path) -> None:
        path.write_text("[filter]\nkp_rollpitch = 1e300\n")

    def _make_options_gain_nan(self, path: Path) -> None:
        path.write_text("[filter]\nkp_yaw = nan\n")

    def _make_options_wrong_types(self, path: Path) -> None:
        path.write_text('display = 5\n[filter]\nkp_rollpitch = "fast"\n')

    def _make_options_nested(self, path: Path) -> None:
        path.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")

    def _make_options_huge(self, path: Path) -> None:
        path.write_text("[filter]\nkp_yaw = 1.2\n" + "#" * (2 * 1024 * 1024) + "\n")

    def _make_options_random(self, path: Path) -> None:
        path.write_bytes(b"\xff\xfe" + self._rng.bytes(3000))

    def _make_options_directory(self, path: Path) -> None:
        path.mkdir()
