"""Format-version-2 recordings for the hostile-input corpus (issue 43.6): the events a live
session writes, and damage to events as well as to frames.

:func:`record_with_events` records the simulated suit through a real live session
(:class:`bpms.pipeline.session.LiveSession` fed by a paused replay, stepped frame by frame so
every event lands at a known frame): logging start and stop, the settings in force, the
filters restarted and re-initialised (a seek), the provisional, automatic and manual Reset
Zero, the alignment switched off and on, a filter change, a gain change, a marker and a note;
every event kind the code writes (docs/raw-format.md), in the bytes the raw logger writes.

:func:`walk` reads the layout back from docs/raw-format.md alone (preamble, header, then frame
records of 348 bytes and event records of 20 bytes + payload), never through the reader under
test: the corpus's expectations (how many frame slots, which frame records a damage touched)
come from it and from how each damage is made.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from pathlib import Path

RECORD = 348  # frame record: float64 time, "$#", 336 bytes, "#$"
PREAMBLE = struct.Struct("<8sHI")
EVENT_HEAD = struct.Struct("<d2sI")  # host time, "$E", payload length
EVENT_EXTRA = EVENT_HEAD.size + 6  # + CRC-32 and "E$"
#: The simulated frames played, and the frames re-delivered by the seek (from 250 back to 240).
PLAYED, SEEK_FROM, SEEK_TO = 300, 250, 240
#: Frame slots in the recording: every frame played, the re-delivered ones again.
N_SLOTS = PLAYED + (SEEK_FROM - SEEK_TO)


@dataclass(frozen=True)
class Piece:
    """One record of a recording: ``kind`` ("frame" or the event's kind), its byte offset and
    size, and for a frame its slot."""

    kind: str
    offset: int
    size: int
    slot: int = -1


def walk(data: bytes) -> tuple[int, list[Piece]]:
    """(offset of the first record, every record) of an intact version-2 recording, from the
    documented layout. Raises ValueError where the bytes do not follow it."""
    import json

    magic, version, length = PREAMBLE.unpack_from(data)
    if magic != b"BPMSRAW\0" or version != 2:
        raise ValueError("not a version-2 recording")
    p = first = PREAMBLE.size + length
    pieces: list[Piece] = []
    slot = 0
    while p < len(data):
        mark = data[p + 8:p + 10]
        if mark == b"$#":
            pieces.append(Piece("frame", p, RECORD, slot))
            slot += 1
            p += RECORD
        elif mark == b"$E":
            n = struct.unpack_from("<I", data, p + 10)[0]
            kind = json.loads(data[p + EVENT_HEAD.size:p + EVENT_HEAD.size + n])["kind"]
            pieces.append(Piece(kind, p, EVENT_EXTRA + n))
            p += EVENT_EXTRA + n
        else:
            raise ValueError(f"no record at byte {p}")
    return first, pieces


def record_with_events(folder: Path) -> Path:
    """A version-2 recording of the simulated suit with every event kind, made by a live
    session (see the module docstring). Takes a few seconds."""
    import numpy as np

    from bpms.filter.processor import BodyPoseProcessor
    from bpms.firmware.sim.session import simulate
    from bpms.io.options import Options
    from bpms.io.rawfile import new_header, read_raw, write_raw
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    folder.mkdir(parents=True, exist_ok=True)
    rec = simulate(PLAYED * 0.02, seed=43)
    source_path = folder / "played.bpmsraw"
    write_raw(source_path, 1.7e9 + np.arange(PLAYED) * 0.02, rec.frames,
              new_header(calibration=rec.calibration.values, source="corpus"))
    source = ReplaySource(read_raw(source_path), speed=None, autoplay=False)
    options = Options()
    session = LiveSession(source, options, BodyPoseProcessor(rec.calibration, options),
                          recording_dir=folder)
    session.start()
    delivered = 0

    def play_to(k: int) -> None:
        nonlocal delivered
        n = k - source.position
        source.step(n)
        delivered += n
        deadline = time.monotonic() + 60
        while session.status().processed < delivered:
            if time.monotonic() > deadline:
                raise TimeoutError(f"the live session did not process frame {k}")
            time.sleep(0.002)

    try:
        status = session.start_logging(raw=True, filtered=False, name="events")
        play_to(60)
        session.marker("start of squat")
        play_to(100)
        session.reset_zero()
        play_to(140)
        session.set_corrected_output(False)
        play_to(170)
        session.select_filter("observer")
        play_to(200)
        session.set_gains(kp_rollpitch=0.1)
        play_to(220)
        session.note("the subject sat down")
        session.set_corrected_output(True)
        play_to(SEEK_FROM)
        source.seek(SEEK_TO)  # the filters re-initialise; frames 240..249 come again
        play_to(PLAYED)
        final = session.stop_logging()
    finally:
        session.stop()
    assert final is not None and final.raw_path is not None and status.raw_path is not None
    return final.raw_path
