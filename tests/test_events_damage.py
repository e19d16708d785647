"""Damage costs only what was damaged (issue 43 item 1): a recording whose Reset Zero records
are hit by one flipped bit each keeps its angles through every door.

The recording is made as ``bpms record --filtered`` makes one (format version 2, the session's
events between the frames): the simulated suit's frames, the stream-start events, and four
Reset Zero captures (the provisional one, the automatic one and two manual ones), each stored
with its 3.6 kB ``R0``. One bit is then flipped inside the JSON of every Reset Zero record in
the file, found from the bytes themselves.

- Only one copy of each hit (the writer stores a number-changing event twice): nothing is
  lost, every door gives the intact file's numbers exactly.
- Every copy hit: the reader names each lost record's kind and frame, ``bpms filter
  --joints``, ``export opensim``, ``export bvh`` and ``replay --udp`` give a finite angle on
  every frame where the intact file has one, and say in one line that the automatic Reset
  Zero stands in.
"""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from udp_docs_reader import docs_reader

from bpms.cli import main
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.session_events import SessionEvent

MANUAL = (420, 760)  # frames of the two manual captures
FALLBACK = "the automatic Reset Zero is used from there"


def _said(err: str, command: str) -> int:
    """How many of the command's own warning lines say that the automatic Reset Zero stands
    in (the log's copy of a warning aside)."""
    return sum(1 for line in err.splitlines()
               if line.startswith(f"bpms {command}: warning: ") and FALLBACK in line)


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> Path:
    """The recording as a live session writes it (its Reset Zero events from a live run)."""
    rec = simulate(duration_s=20.0, seed=12)
    proc = BodyPoseProcessor(rec.calibration)
    for k in range(0, len(rec.raw), 20):
        if k in MANUAL:
            proc.reset_zero("manual")
        proc.process(rec.raw[k:k + 20], rec.errors[k:k + 20])
    zeros = proc.pose.captures
    assert [z.source for z in zeros] == ["provisional", "automatic", "manual", "manual"]
    events = [SessionEvent("filters", 0, data={"action": "restart", "reason": "stream start"}),
              *(SessionEvent("reset_zero", z.frame, data=_zero_data(z)) for z in zeros)]
    path = tmp_path_factory.mktemp("damage") / "Raw_field_1.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames,
              new_header(calibration=rec.calibration.values, source="simulated suit"), events)
    return path


def _zero_data(z) -> dict:
    """A capture's ``reset_zero`` data as docs/raw-format.md's table lists it."""
    return {"source": z.source, "window": int(z.window), "R0": z.R0.tolist(),
            "yaw0": float(z.yaw0), "heading": z.heading, "motion_deg": float(z.motion_deg),
            "motion_imu": int(z.motion_imu), "moved": bool(z.moved), "waited": int(z.waited)}


def _flip(src: Path, out: Path, every_copy: bool) -> Path:
    """One bit flipped inside each Reset Zero record's R0 (only the first of two identical
    records in a row when ``every_copy`` is False)."""
    original = src.read_bytes()
    data = bytearray(original)
    found, at = [], 0
    while (k := original.find(b'"kind":"reset_zero"', at)) >= 0:
        found.append(k)
        at = k + 1
    assert len(found) >= 4
    for n, k in enumerate(found):
        twin = n > 0 and original[found[n - 1]:found[n - 1] + 400] == original[k:k + 400]
        if every_copy or not twin:
            data[k + 300] ^= 0x04  # inside the R0 numbers: the record's CRC fails
    out.write_bytes(bytes(data))
    return out


def _joints(path: Path, tmp_path: Path, capsys) -> tuple[np.ndarray, str]:
    out = tmp_path / f"{path.stem}.csv"
    assert main(["filter", str(path), "--joints", "-o", str(out), "--force"]) == 0
    return read_filtered(out).joint_angles, capsys.readouterr().err


def test_one_damaged_copy_loses_nothing(intact, tmp_path, capsys):
    damaged = _flip(intact, tmp_path / "Raw_one_1.bpmsraw", every_copy=False)
    rec = read_raw(damaged)
    assert [e.kind for _, e in rec.events].count("reset_zero") == 4
    assert not any("record(s) lost" in p for p in rec.problems)
    want, _ = _joints(intact, tmp_path, capsys)
    got, err = _joints(damaged, tmp_path, capsys)
    np.testing.assert_array_equal(got, want)
    assert FALLBACK not in err and "4 damaged event record(s) whose copy" in err


def test_every_lost_reset_zero_is_named_with_its_frame(intact, tmp_path):
    damaged = _flip(intact, tmp_path / "Raw_all_1.bpmsraw", every_copy=True)
    rec = read_raw(damaged)
    frames = [e.frame for _, e in read_raw(intact).events if e.kind == "reset_zero"]
    lost = [(e.frame, e.data["kind"]) for _, e in rec.events if e.kind == "lost"]
    assert lost == [(k, "reset_zero") for k in frames]
    assert len(rec) == len(read_raw(intact)) and rec.damaged.size == 0  # no slot lost
    line = [p for p in rec.problems if "lost" in p]
    assert len(line) == 1 and "4 damaged event record(s) lost" in line[0]
    assert all(f"reset_zero at frame {k}" in line[0] for k in frames)


def _receive(sock: socket.socket, done: threading.Event) -> list[bytes]:
    out: list[bytes] = []
    sock.settimeout(0.05)
    quiet_since = None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            out.append(sock.recv(65535))
            quiet_since = None
            continue
        except TimeoutError:
            pass
        if done.is_set():
            quiet_since = quiet_since or time.monotonic()
            if time.monotonic() - quiet_since > 0.3:
                return out
    raise TimeoutError("replay did not end")


def test_every_door_keeps_the_angles_and_says_so(intact, tmp_path, capsys):
    damaged = _flip(intact, tmp_path / "Raw_all_1.bpmsraw", every_copy=True)
    want, _ = _joints(intact, tmp_path, capsys)
    got, err = _joints(damaged, tmp_path, capsys)
    has = np.isfinite(want).all(axis=1)
    assert has.sum() >= len(want) - 2  # (the intact file: all but the stream's first frames)
    assert np.isfinite(got[has]).all()
    assert _said(err, "filter") == 1 and "(frame 0, 49, 420, 760)" in err

    stem = tmp_path / "os"
    assert main(["export", "opensim", str(damaged), "-o", str(stem), "--force"]) == 0
    assert _said(capsys.readouterr().err, "export") == 1
    lines = Path(f"{stem}_orientations.sto").read_text().splitlines()
    rows = lines[lines.index("endheader") + 2:]
    assert len(rows) >= has.sum()
    values = np.array([[float(v) for v in row.replace(",", "\t").split("\t")]
                       for row in rows])
    assert np.isfinite(values).all()

    bvh = tmp_path / "walk"
    assert main(["export", "bvh", str(damaged), "-o", str(bvh), "--force"]) == 0
    assert _said(capsys.readouterr().err, "export") == 1
    text = Path(f"{bvh}.bvh").read_text()
    motion = text[text.index("Frame Time:"):].splitlines()[1:]
    values = np.array([[float(v) for v in row.split()] for row in motion])
    assert len(values) == len(want) and np.isfinite(values).all()
    assert np.abs(values[len(values) // 2:, 6:]).max() > 1.0  # rotations, not a frozen figure

    parse = docs_reader()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    sock.bind(("127.0.0.1", 0))
    done = threading.Event()
    code: list[int] = []

    def replay() -> None:
        try:
            code.append(main(["replay", str(damaged), "--speed", "0", "--udp",
                              f"127.0.0.1:{sock.getsockname()[1]}"]))
        finally:
            done.set()

    threading.Thread(target=replay, daemon=True).start()
    datagrams = _receive(sock, done)
    sock.close()
    assert code == [0]
    assert _said(capsys.readouterr().err, "replay") == 1
    poses = [m for m in map(parse, datagrams) if m is not None and m["type"] == 2]
    assert len(poses) >= has.sum()
    q = np.array([m["quaternions"] for m in poses])
    assert np.isfinite(q[-int(has.sum()):]).all()


def _records(data: bytes, kind: bytes) -> list[int]:
    """Offsets of the event records of ``kind`` (their JSON begins ``{"kind":...``)."""
    out, at = [], 0
    while (k := data.find(b'{"kind":"' + kind + b'"', at)) >= 0:
        out.append(k - 14)  # time (8), "$E" (2), length (4), then the JSON
        at = k + 1
    return out


@pytest.mark.parametrize(("where", "copies"), [
    (8, "first"), (9, "first"), (11, "first"), (8, "both"), (12, "both")])
def test_a_hit_event_header_costs_no_frame_slot(intact, tmp_path, where, copies):
    """A bit flipped in a Reset Zero record's ``$E`` marker (offset 8, 9) or its length field
    (11, 12): the record still ends with ``E$`` and says where it began, so the frames after
    it keep their slots; its intact copy stands in, or (both copies hit) it is named lost."""
    original = intact.read_bytes()
    starts = _records(original, b"reset_zero")
    hit = starts[2:4] if copies == "both" else starts[2:3]  # the automatic capture's records
    data = bytearray(original)
    for s in hit:
        data[s + where] ^= 0x10
    damaged = tmp_path / "Raw_head_1.bpmsraw"
    damaged.write_bytes(bytes(data))
    rec, want = read_raw(damaged), read_raw(intact)
    assert len(rec) == len(want) and rec.damaged.size == 0
    assert rec.frames.tobytes() == want.frames.tobytes()
    lost = [(e.frame, e.data["kind"]) for _, e in rec.events if e.kind == "lost"]
    zeros = [e.frame for _, e in want.events if e.kind == "reset_zero"]
    if copies == "first":
        assert lost == [] and [e.frame for _, e in rec.events if e.kind == "reset_zero"] == zeros
    else:
        assert lost == [(zeros[1], "reset_zero")]


def test_a_record_written_once_with_a_hit_marker_costs_no_slot(tmp_path):
    rec = simulate(duration_s=4.0, seed=1)
    path = tmp_path / "Raw_marker_1.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header(),
              [SessionEvent("marker", 100, data={"text": "squat"})])
    data = bytearray(path.read_bytes())
    data[_records(bytes(data), b"marker")[0] + 8] ^= 0x01  # "$E" → "%E"
    path.write_bytes(bytes(data))
    got = read_raw(path)
    assert len(got) == len(rec) and got.damaged.size == 0
    assert got.frames.tobytes() == rec.frames
    assert [(slot, e.kind, e.data["kind"]) for slot, e in got.events] == [
        (100, "lost", "marker")]
