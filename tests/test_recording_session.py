"""The recording reproduces the session (issue 25), headless: a ``bpms record --sim
--filtered`` session started while the simulated subject turns, ``z`` typed on its standard
input while the right arm is raised, then ``v`` twice and a marker. Every door agrees with the
filtered file written live: ``bpms filter`` and the Python API within 1e-9 rad, a replayed
session's numbers within 1e-9 rad and 1e-9 m, the UDP, LSL and MVN pose streams of
``bpms replay --speed 0`` within 1e-6 rad (float32), one pose per frame;
``--reset-zero auto`` differs after the ``z``: the event is in the file. The automatic Reset Zero
waited for a still pose and said when, and with what motion.

The truth: the simulated suit's script (docs/simulated-suit.md) started 69.6 s in: the subject
finishes a 30° turn (moving, 0–1.5 s), stands still (1.5–7.5 s), raises the right arm forward to
60° (7.5–9.5 s) and holds it (9.5–10.0 s) before lowering it (10.0–12.3 s)."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from udp_docs_reader import docs_reader
from waiting import receive_until_exit, wait_until

from bpms.cli import main
from bpms.filter.door import process_file
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import read_raw
from bpms.pipeline.mvn import MVN_SEGMENTS, SEGMENT_SOURCES

ROOT = Path(__file__).resolve().parents[1]
TOL = 1e-9  # rad (files, the API and the sessions), m for positions
TOL32 = 1e-6  # rad: float32 streams
START_AT = 69.6  # s into the script: the turn back to the start heading
STREAMS = ("BPMS Segments", "BPMS Joint Angles", "BPMS Sensors", "BPMS Disturbance",
           "BPMS Events")



class _Recorder:
    """``bpms record`` as a real process, driven through its standard input."""

    def __init__(self, out: Path) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "bpms", "record", "--sim", "--filtered", "--start-at",
             str(START_AT), "-o", str(out), "--name", "field", "--seconds", "60"],
            cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, bufsize=1)
        self.lines: list[str] = []
        self._frames = (0, time.monotonic())
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip())
            m = re.match(r"t\s+\S+ s .* frames\s+(\d+)", line)
            if m:
                self._frames = (int(m.group(1)), time.monotonic())

    def stream_time(self) -> float:
        """Where the stream is now, s (the last status line, and the time since)."""
        frames, at = self._frames
        return frames * 0.02 + (time.monotonic() - at) if frames else 0.0

    def type_at(self, seconds: float, line: str) -> None:
        assert wait_until(lambda: self.stream_time() >= seconds, 40), self.lines[-5:]
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    """The live session: its raw recording, its filtered file and its output lines."""
    out = tmp_path_factory.mktemp("field")
    rec = _Recorder(out)
    rec.type_at(9.7, "z")  # the right arm held up
    rec.type_at(10.6, "v")
    rec.type_at(11.6, "v")
    rec.type_at(12.4, "m arm coming down")
    assert wait_until(lambda: any("arm coming down" in ln for ln in rec.lines), 20)
    rec.proc.send_signal(signal.SIGINT)  # Ctrl-C: the files close cleanly
    rec.proc.wait(60)
    err = rec.proc.stderr.read()
    assert rec.proc.returncode == 0, err
    raw, filtered = out / "Raw_field_1.bpmsraw", out / "Filtered_field_1.csv"
    return raw, filtered, rec.lines, out


@pytest.fixture(scope="module")
def api(field):
    return process_file(field[0])


@pytest.fixture(scope="module")
def live(field):
    return read_filtered(field[1])


def _events(raw, kind):
    return [(slot, e) for slot, e in read_raw(raw).events if e.kind == kind]


def test_the_field_commands_and_the_automatic_reset_zero_are_in_the_recording(field):
    raw, _, lines, _ = field
    zeros = [(slot, e.data) for slot, e in _events(raw, "reset_zero")]
    sources = [d["source"] for _, d in zeros]
    assert sources == ["provisional", "automatic", "manual"], zeros
    # the automatic one waited (the subject turned), then captured a still window
    (auto_at, auto), (manual_at, manual) = zeros[1], zeros[2]
    assert auto["waited"] > 0 and auto_at == 49 + auto["waited"]  # 1.0 s nominally
    assert auto["motion_deg"] <= 5.0 and 1.0 < auto_at * 0.02 < 2.5
    waiting = [ln for ln in lines if "waiting for a still pose" in ln]
    assert waiting, lines
    moved = float(re.search(r"moved ([\d.]+)°", waiting[0]).group(1))
    assert moved > 5.0  # the motion it measured while it waited
    assert any(f"Reset Zero (automatic) at {auto_at * 0.02:.2f} s" in ln for ln in lines)
    # z while the right arm is held up; v twice; the marker
    assert 9.5 <= manual_at * 0.02 <= 10.3 and manual["window"] == 25
    alignment = [(slot, e.data["on"]) for slot, e in _events(raw, "alignment")
                 if e.data.get("source") != "in force"]
    assert [on for _, on in alignment] == [False, True]
    assert manual_at < alignment[0][0] < alignment[1][0]
    markers = _events(raw, "marker")
    assert [e.data["text"] for _, e in markers] == ["arm coming down"]
    assert alignment[1][0] < markers[0][0]
    assert any("marker at" in ln and "arm coming down" in ln for ln in lines)


def test_bpms_filter_and_the_api_equal_the_live_filtered_file(field, api, live, tmp_path):
    raw = field[0]
    out = tmp_path / "again.csv"
    assert main(["filter", str(raw), "--joints", "-o", str(out)]) == 0
    again = read_filtered(out)
    assert len(live.t) == len(again.t) == len(api) == len(read_raw(raw))
    np.testing.assert_array_equal(again.t, live.t)
    for got in (again.euler, api.euler_output):
        np.testing.assert_allclose(got, live.euler, rtol=0, atol=TOL)
    for got in (again.joint_angles, api.joint_angles):
        np.testing.assert_allclose(got, live.joint_angles, rtol=0, atol=TOL)
    # the alignment switched off and on again, as live: sensor angles in between
    off = np.flatnonzero(~api.corrected)
    assert len(off) > 40 and np.array_equal(live.groups["corrected"][:, 0] == 0,
                                            ~api.corrected)


def test_reset_zero_auto_differs_after_the_z(field, api):
    auto = process_file(field[0], reset_zero="auto")
    manual_at = _events(field[0], "reset_zero")[-1][0]
    before = np.abs(auto.euler_segment[:manual_at] - api.euler_segment[:manual_at])
    after = np.abs(auto.euler_segment[manual_at:] - api.euler_segment[manual_at:])
    assert np.nanmax(before) == 0.0
    assert np.degrees(np.nanmax(after)) > 10.0  # the raised arm is the new zero
    none = process_file(field[0], reset_zero="none")
    np.testing.assert_allclose(none.C, none.R, atol=1e-12)  # segments = the IMUs themselves


def test_a_replayed_session_equals_the_api_on_every_frame(field, api):
    """What GUI playback and ``bpms replay`` run: the recording's frames and events through a
    live session (the same processor calls as live)."""
    from bpms.filter.door import open_for_processing
    from bpms.io.recordings import open_replay
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    raw = field[0]
    opened = open_for_processing(raw)
    recording = open_replay(raw)
    source = ReplaySource(recording, speed=None, events=opened.replay_events(recording.events))
    session = LiveSession(source, opened.processor.options, opened.processor)
    sub = session.subscribe(maxlen=5000)
    with session:
        assert wait_until(lambda: session.status().processed == len(api), 60)
    samples = sub.drain()
    assert [s.index for s in samples] == list(range(len(api)))
    C = np.stack([s.C for s in samples])
    np.testing.assert_allclose(C, api.C, rtol=0, atol=TOL)
    np.testing.assert_allclose(np.stack([s.joint_positions for s in samples]),
                               api.joint_positions, rtol=0, atol=TOL)
    np.testing.assert_allclose(np.stack([s.euler_output for s in samples]), api.euler_output,
                               rtol=0, atol=TOL)
    lines = session.status().events
    assert any("Reset Zero (manual)" in ln for ln in lines)
    assert any("marker at" in ln for ln in lines)


def _lsl_env(tmp_path):
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-rec-{os.getpid()}\n")
    return {**os.environ, "LSLAPICFG": str(cfg)}


def _mvn_quaternions(datagrams):
    """MXTP02 datagrams → ``[n, 23, 4]`` (w, x, y, z, MVN's Z-up frame), read from docs/mvn.md's
    layout: a 24-byte header, then per segment int32 id and 7 float32."""
    out = []
    for d in datagrams:
        if d[:6] != b"MXTP02":
            continue
        q = [struct.unpack_from(">i7f", d, 24 + 32 * k)[4:] for k in range(len(MVN_SEGMENTS))]
        out.append(q)
    return np.array(out)


def test_replay_streams_one_pose_per_frame_equal_to_the_api(field, api, tmp_path):
    """``bpms replay --speed 0`` with UDP, MVN and LSL at once: every frame's pose on every
    stream, decoded by readers written from the docs alone (docs/udp.md's script, docs/mvn.md's
    layout, pylsl), equal to the API's segment quaternions."""
    parse = docs_reader()
    raw = field[0]
    udp, mvn = (socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2))
    for s in (udp, mvn):
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        s.bind(("127.0.0.1", 0))
    env = _lsl_env(tmp_path)
    n = len(api)
    inlet = subprocess.Popen([sys.executable, str(ROOT / "tests" / "lsl_inlet.py"), str(n),
                              "60", ",".join(STREAMS), "BPMS Segments"], cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(raw), "--speed", "0",
                             "--udp", f"127.0.0.1:{udp.getsockname()[1]}", "--mvn",
                             f"127.0.0.1:{mvn.getsockname()[1]}", "--lsl", "--lsl-wait", "30"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    got: dict = {}
    threading.Thread(target=lambda: got.update(mvn=receive_until_exit(mvn, proc)),
                     daemon=True).start()
    datagrams = receive_until_exit(udp, proc)
    _, err = proc.communicate(timeout=60)
    lsl_out, _ = inlet.communicate(timeout=60)
    assert proc.returncode == 0, err.decode()
    assert wait_until(lambda: "mvn" in got, 10)
    msgs = [m for m in map(parse, datagrams) if m is not None]
    poses = [m for m in msgs if m["type"] == 2]
    assert [round(m["suit_time"] / 0.02) for m in poses] == list(range(n))  # one per frame
    q = np.array([m["quaternions"] for m in poses])
    want = api.segment_quaternions
    sign = np.sign((q * want).sum(axis=-1, keepdims=True))  # q and -q are one rotation
    np.testing.assert_allclose(q * sign, want, rtol=0, atol=TOL32)
    zeros = [m for m in msgs if m["type"] == 3]
    assert zeros and zeros[-1]["source"] == 0  # ZERO: the manual Reset Zero (source 0)
    # MVN: the segments made from one IMU each; MVN's frame is (w, x, -y, -z) of NED's
    mq = _mvn_quaternions(got["mvn"])
    assert len(mq) == n
    for k, src in enumerate(SEGMENT_SOURCES):
        if src.a == src.b:
            ref = want[:, src.a] * [1, 1, -1, -1]
            s = np.sign((mq[:, k] * ref).sum(axis=-1, keepdims=True))
            np.testing.assert_allclose(mq[:, k] * s, ref, rtol=0, atol=TOL32)
    # LSL: the segment stream, every sample, and the recorded events as markers
    lsl = json.loads(lsl_out)["data"]
    seg = np.array(lsl["BPMS Segments"]["values"], dtype=np.float64).reshape(-1, 18, 4)
    assert len(seg) == n
    s = np.sign((seg * want).sum(axis=-1, keepdims=True))
    np.testing.assert_allclose(seg * s, want, rtol=0, atol=TOL32)
    events = lsl["BPMS Events"]["values"]
    assert any(e.startswith("Reset Zero (manual)") for e in events), events
    assert any("arm coming down" in e for e in events), events


def _damage(raw: Path, out: Path, case: str) -> Path:
    """A damaged copy of the field recording. Record positions come from the bytes themselves
    (a frame's 340 bytes found in the file; an event's JSON): events sit between frames."""
    data = bytearray(raw.read_bytes())
    intact = read_raw(raw)

    def frame_at(k: int) -> int:
        return bytes(data).index(intact.frames[k].tobytes()) - 8

    manual = bytes(data).index(b'"source":"manual"')
    event = bytes(data).rindex(b"$E", 0, manual) - 8
    if case == "deleted":
        at = frame_at(300) + 100
        del data[at:at + 3]
    elif case == "inserted":
        data[event:event] = b"\x55" * 5  # just before the manual Reset Zero's record
    elif case == "markers_lost":
        for k in range(500, 505):
            at = frame_at(k)
            data[at + 8:at + 10] = b"\0\0"
    elif case == "event_lost":
        data[manual + 3] ^= 0x20  # inside its JSON: its CRC fails (its copy stands in)
    elif case == "both_copies_lost":
        copy = bytes(data).index(b'"source":"manual"', manual + 1)
        data[manual + 3] ^= 0x20
        data[copy + 3] ^= 0x20
    elif case == "all_markers_lost":
        start = bytes(data).index(intact.frames[0].tobytes())
        for k in range(len(intact)):
            at = bytes(data).index(intact.frames[k].tobytes()[:40], start)
            data[at:at + 2] = b"\0\0"
    out.write_bytes(bytes(data))
    return out


@pytest.mark.parametrize("case", ["deleted", "inserted", "markers_lost", "event_lost",
                                  "both_copies_lost"])
def test_damaged_copies_keep_every_slot_and_every_other_event(field, api, case, tmp_path,
                                                               capsys):
    damaged = _damage(field[0], tmp_path / f"Raw_{case}_1.bpmsraw", case)
    rec = read_raw(damaged)
    assert len(rec) == len(api)  # every slot kept: no time shift
    lost = {"deleted": [300], "markers_lost": [500, 501, 502, 503, 504]}.get(case, [])
    assert rec.damaged.tolist() == lost
    out = tmp_path / "f.csv"
    assert main(["filter", str(damaged), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert ("damaged" in err or "inserted" in err) and "warning" in err
    rows = read_filtered(out)
    np.testing.assert_allclose(rows.t, np.arange(len(rec)) * 0.02, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows.host_time, rec.times, rtol=0, atol=1e-6)
    again = process_file(damaged)
    want = [(z.source, z.frame) for z in api.zeros]
    got = [(z.source, z.frame) for z in again.zeros]
    if case != "both_copies_lost":
        assert got == want
    else:  # the manual capture lost: the automatic one from its frame on, said in one line
        assert got[:-1] == want[:-1] and got[-1][0] == "automatic"
        assert got[-1][1] >= want[-1][1]
        assert "the automatic Reset Zero is used from there" in err


def test_a_copy_without_a_valid_frame_is_refused_in_one_line(field, tmp_path):
    damaged = _damage(field[0], tmp_path / "Raw_none_1.bpmsraw", "all_markers_lost")
    assert read_raw(damaged).valid_frames == 0
    for args in (["filter", str(damaged), "-o", str(tmp_path / "f.csv")],
                 ["replay", str(damaged), "--udp", "127.0.0.1:9", "--speed", "0"]):
        run = subprocess.run([sys.executable, "-m", "bpms", *args], cwd=ROOT,
                             capture_output=True, text=True, timeout=60)
        lines = [ln for ln in run.stderr.strip().splitlines() if "WARNING" not in ln]
        assert run.returncode == 2 and len(lines) == 1, run.stderr
        assert lines[0].startswith(f"bpms {args[0]}: ") and "no valid frame" in lines[0]
