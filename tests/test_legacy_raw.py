"""Legacy (Python 2 pickle) raw files, SPEC §10: faithful reading, skipping, and refusal of
anything that could run code."""

from __future__ import annotations

import copyreg
import os
import pickle
import random
import struct

import numpy as np
import pytest

from bpms.io.frames import FRAME_SIZE, encode_frame
from bpms.io.legacy_raw import is_legacy_raw, read_legacy_raw
from bpms.io.rawfile import RawFileError, new_header, write_raw

T0 = 1_342_000_000.25  # a host time of 2012


def make_frames(n: int, seed: int = 3) -> list[bytes]:
    rng = np.random.default_rng(seed)
    raw = rng.integers(-32768, 32768, size=(n, 18, 9), dtype=np.int16)
    frames = [encode_frame(raw[i]) for i in range(n)]
    # Make sure the awkward bytes for protocol 0 appear: quotes, backslash, newline, NUL.
    frames[0] = frames[0][:2] + b"'\"\\\n\r\t\0\x80\xff" + frames[0][11:]
    return frames


# --- Python 2.7 pickle writers (what the original suite produced), byte for byte ----------


def _py2_repr(s: bytes) -> bytes:
    quote = b'"' if b"'" in s and b'"' not in s else b"'"
    out = bytearray(quote)
    for c in s:
        ch = bytes([c])
        if ch in (b"\\", quote):
            out += b"\\" + ch
        elif ch == b"\t":
            out += b"\\t"
        elif ch == b"\n":
            out += b"\\n"
        elif ch == b"\r":
            out += b"\\r"
        elif 0x20 <= c < 0x7F:
            out += ch
        else:
            out += b"\\x%02x" % c
    return bytes(out + quote)


def py2_record(t: float, frame: bytes, protocol: int) -> bytes:
    """``pickle.dump([t, frame_str], f, protocol)`` as Python 2.7 writes it."""
    if protocol == 0:
        return b"(lp0\nF" + repr(t).encode() + b"\naS" + _py2_repr(frame) + b"\np1\na."
    if len(frame) < 256:
        string = b"U" + bytes([len(frame)]) + frame
    else:
        string = b"T" + struct.pack("<i", len(frame)) + frame
    body = b"]q\x00(G" + struct.pack(">d", t) + string + b"q\x01e."
    return body if protocol == 1 else b"\x80\x02" + body


def py3_record(t: float, frame: bytes, protocol: int, as_bytes: bool) -> bytes:
    return pickle.dumps([t, frame if as_bytes else frame.decode("latin1")], protocol=protocol)


WRITERS = {
    **{f"py2-p{p}": (lambda t, fr, p=p: py2_record(t, fr, p)) for p in (0, 1, 2)},
    **{f"py3-str-p{p}": (lambda t, fr, p=p: py3_record(t, fr, p, False)) for p in (0, 1, 2)},
    **{f"py3-bytes-p{p}": (lambda t, fr, p=p: py3_record(t, fr, p, True)) for p in (0, 1, 2, 4)},
}


def write_legacy(path, frames, writer, times=None) -> list[int]:
    """Write records; return each record's start offset."""
    times = [T0 + 0.02 * i for i in range(len(frames))] if times is None else times
    offsets = []
    with open(path, "wb") as f:
        for t, fr in zip(times, frames, strict=True):
            offsets.append(f.tell())
            f.write(writer(t, fr))
    return offsets


@pytest.mark.parametrize("name", list(WRITERS))
def test_reads_every_protocol_and_string_kind(tmp_path, name):
    frames = make_frames(40)
    path = tmp_path / "Raw_1.txt"
    write_legacy(path, frames, WRITERS[name])
    assert is_legacy_raw(path)
    rec = read_legacy_raw(path)
    assert len(rec) == 40 and rec.problems == []
    assert [rec.frame_bytes(i) for i in range(40)] == frames
    assert np.array_equal(rec.times, T0 + 0.02 * np.arange(40))
    assert rec.header["format"] == "legacy pickle" and rec.header["frames"] == 40
    decoded = rec.decode()
    assert decoded.raw.shape == (40, 18, 9)


def test_py2_protocol0_matches_what_python_reads_back():
    # Sanity check of the hand-made Python 2 writer against Python's own unpickler.
    frame = make_frames(1)[0]
    for p in (0, 1, 2):
        assert pickle.loads(py2_record(1.5, frame, p), encoding="bytes") == [1.5, frame]


@pytest.mark.parametrize("protocol", [0, 2])
def test_bad_frames_are_skipped_as_file_errors(tmp_path, protocol):
    frames = make_frames(20)
    frames[3] = b"XX" + frames[3][2:]  # no start marker
    frames[7] = frames[7][:-2] + b"$$"  # no end marker
    frames[11] = frames[11][:-1]  # 339 bytes
    frames[12] = frames[12] + b"\0"  # 341 bytes
    path = tmp_path / "raw.txt"
    write_legacy(path, frames, WRITERS[f"py2-p{protocol}"])
    rec = read_legacy_raw(path)
    keep = [i for i in range(20) if i not in (3, 7, 11, 12)]
    assert [rec.frame_bytes(i) for i in range(len(rec))] == [frames[i] for i in keep]
    assert np.array_equal(rec.times, T0 + 0.02 * np.array(keep))
    assert rec.header["skipped_frames"] == 4 and rec.header["records"] == 20
    assert len(rec.problems) == 1 and "File Error" in rec.problems[0]
    assert "4 record(s)" in rec.problems[0]


def test_records_of_the_wrong_shape_are_skipped(tmp_path):
    frames = make_frames(3)
    path = tmp_path / "raw.txt"
    with open(path, "wb") as f:
        f.write(py2_record(T0, frames[0], 2))
        f.write(pickle.dumps([T0, frames[1], 3], protocol=2))
        f.write(pickle.dumps(["now", frames[1]], protocol=2))
        f.write(pickle.dumps([True, frames[1]], protocol=2))
        f.write(pickle.dumps({"t": T0}, protocol=2))
        f.write(pickle.dumps([T0, "\u20ac" * 340], protocol=2))  # not latin-1
        f.write(py2_record(T0, b"x" * 340, 2))  # a File Error
        f.write(py2_record(T0 + 0.02, frames[2], 2))
    rec = read_legacy_raw(path)
    assert [rec.frame_bytes(i) for i in range(len(rec))] == [frames[0], frames[2]]
    assert rec.header["skipped_records"] == 5 and rec.header["skipped_frames"] == 1
    assert len(rec.problems) == 2


@pytest.mark.parametrize("name", ["py2-p0", "py2-p1", "py2-p2", "py3-bytes-p2"])
@pytest.mark.parametrize("cut", [1, 17, -2, -1])
def test_truncated_last_record_ends_the_file(tmp_path, name, cut):
    frames = make_frames(10)
    path = tmp_path / "raw.txt"
    offsets = write_legacy(path, frames, WRITERS[name])
    data = path.read_bytes()
    end = offsets[-1] + cut if cut > 0 else len(data) + cut
    path.write_bytes(data[:end])
    rec = read_legacy_raw(path)
    assert [rec.frame_bytes(i) for i in range(len(rec))] == frames[:9]
    assert len(rec.problems) == 1 and "last record" in rec.problems[0]


@pytest.mark.parametrize("name", ["py2-p0", "py2-p2"])
def test_damaged_record_in_the_middle_is_skipped_and_reading_resumes(tmp_path, name):
    frames = make_frames(10)
    path = tmp_path / "raw.txt"
    offsets = write_legacy(path, frames, WRITERS[name])
    data = bytearray(path.read_bytes())
    data[offsets[4] : offsets[4] + 30] = b"\xfe" * 30  # smash record 4's opcodes
    path.write_bytes(bytes(data))
    rec = read_legacy_raw(path)
    assert [rec.frame_bytes(i) for i in range(len(rec))] == frames[:4] + frames[5:]
    assert rec.header["damaged_bytes"] > 0
    assert any("damaged" in p for p in rec.problems)


# --- malicious pickles ------------------------------------------------------------------


class _Evil:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


@pytest.mark.parametrize("protocol", [0, 1, 2])
@pytest.mark.parametrize("where", ["alone", "in a record", "after good records"])
def test_reduce_payload_is_refused_and_never_runs(tmp_path, protocol, where):
    marker = tmp_path / "pwned"
    evil = _Evil(marker)
    payload = {
        "alone": pickle.dumps(evil, protocol=protocol),
        "in a record": pickle.dumps([T0, evil], protocol=protocol),
        "after good records": b"".join(py2_record(T0, f, protocol) for f in make_frames(3))
        + pickle.dumps([T0, evil], protocol=protocol),
    }[where]
    path = tmp_path / "Raw_evil.txt"
    path.write_bytes(payload)
    with pytest.raises(RawFileError) as info:
        read_legacy_raw(path)
    message = str(info.value)
    assert not marker.exists()
    if where == "alone":  # not even a list: refused by sniffing, before any unpickling
        assert "not a legacy" in message
    else:
        assert "refused" in message and "system" in message
    assert "\n" not in message
    # The payload is live: an ordinary unpickler would have run it.
    if where != "after good records":
        pickle.loads(payload)
        assert marker.exists()


def _opcode_attacks(marker) -> dict[str, bytes]:
    cmd = f"touch {marker}".encode()
    start = b"(lp0\nF1.0\na"  # a record that begins like a real one
    return {
        "GLOBAL+REDUCE": start + b"cos\nsystem\n(S'" + cmd + b"'\ntRa.",
        "INST": start + b"(S'" + cmd + b"'\nios\nsystem\na.",
        "OBJ": b"\x80\x02]q\x00(G?\xf0\x00\x00\x00\x00\x00\x00(cos\nsystem\nU"
        + bytes([len(cmd)]) + cmd + b"oe.",
        "NEWOBJ": b"\x80\x02]q\x00(G?\xf0\x00\x00\x00\x00\x00\x00cos\nsystem\nU"
        + bytes([len(cmd)]) + cmd + b"\x85\x81e.",
        "STACK_GLOBAL": b"\x80\x04]q\x00(G?\xf0\x00\x00\x00\x00\x00\x00\x8c\x02os\x8c\x06system"
        b"\x93\x8c" + bytes([len(cmd)]) + cmd + b"\x85Re.",
        "PERSID": start + b"P" + cmd + b"\na.",
        "BINPERSID": b"\x80\x02]q\x00(G?\xf0\x00\x00\x00\x00\x00\x00U" + bytes([len(cmd)]) + cmd
        + b"Qe.",
        "EXT1": b"\x80\x02]q\x00(G?\xf0\x00\x00\x00\x00\x00\x00\x82\xf0U" + bytes([len(cmd)])
        + cmd + b"\x85Re.",
        # No global available: REDUCE / BUILD / OBJ on plain data only fail.
        "REDUCE on a list": start + b"(l(tRa.",
        "BUILD on a list": start + b"(l(dS'append'\nS'x'\nsba.",
        "BUILD slots on a list": b"\x80\x02]q\x00(G?\xf0\x00\x00\x00\x00\x00\x00]N}U\x06appendK"
        b"\x01s\x86be.",
        "OBJ of a str": start + b"(S'" + cmd + b"'\noa.",
    }


@pytest.mark.parametrize("name", list(_opcode_attacks("x")))
def test_object_building_opcodes_cannot_run_anything(tmp_path, name):
    marker = tmp_path / "pwned"
    good = py2_record(T0, make_frames(1)[0], 0)
    path = tmp_path / "raw.txt"
    path.write_bytes(good + _opcode_attacks(marker)[name])
    registered = name == "EXT1"
    if registered:
        copyreg.add_extension("os", "system", 0xF0)
    try:
        try:
            rec = read_legacy_raw(path)
        except RawFileError as exc:
            assert "refused" in str(exc)
            assert not any(n in name for n in ("on a list", "of a str"))
        else:
            # Plain-data attacks can only fail: the bad record is skipped, the good one kept.
            assert len(rec) == 1 and rec.problems
    finally:
        if registered:
            copyreg.remove_extension("os", "system", 0xF0)
    assert not marker.exists()


def test_random_corruption_never_runs_or_crashes(tmp_path):
    frames = make_frames(30)
    path = tmp_path / "raw.txt"
    write_legacy(path, frames, WRITERS["py2-p0"])
    original = path.read_bytes()
    rng = random.Random(5)
    for _ in range(150):
        data = bytearray(original)
        for _ in range(rng.randint(1, 20)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        if rng.random() < 0.3:
            del data[rng.randrange(len(data)) :]
        path.write_bytes(bytes(data))
        try:
            rec = read_legacy_raw(path)
        except RawFileError:
            continue
        assert len(rec) <= 30
        assert all(rec.frame_bytes(i) in frames or len(rec.frame_bytes(i)) == FRAME_SIZE
                   for i in range(len(rec)))


def test_sniffing(tmp_path):
    legacy = tmp_path / "legacy.txt"
    write_legacy(legacy, make_frames(2), WRITERS["py2-p1"])
    native = tmp_path / "native.bpmsraw"
    write_raw(native, np.zeros(2), b"".join(make_frames(2)), new_header())
    text = tmp_path / "filtered.txt"
    text.write_text("1.0,0.1,0.2\n")
    empty = tmp_path / "empty.txt"
    empty.write_bytes(b"")
    assert is_legacy_raw(legacy)
    for other in (native, text, empty, tmp_path / "missing.txt"):
        assert not is_legacy_raw(other)
        with pytest.raises(RawFileError):
            read_legacy_raw(other)
