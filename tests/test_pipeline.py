"""The headless live pipeline on real files and real UDP sockets (replay and UDP sources)."""

from __future__ import annotations

import re
import subprocess
import sys
import time

import numpy as np
import pytest
from waiting import wait_until

from bpms.filter.door import process_file
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import RecordingError, read_raw
from bpms.io.replay import ReplaySource
from bpms.io.udp.receiver import UdpSource
from bpms.pipeline.session import LiveSession
from bpms.pipeline.sources import UdpFrameSource


@pytest.fixture(scope="module")
def recording_path(tmp_path_factory):
    rec = simulate(duration_s=16.0, seed=3)
    path = tmp_path_factory.mktemp("rec") / "Raw_sim_1.bpmsraw"
    return rec.save_raw(path, notes="simulated")


def test_replay_records_every_frame_and_matches_the_batch_filter(recording_path, tmp_path):
    recording = read_raw(recording_path)
    source = ReplaySource(recording, speed=None)
    session = LiveSession(source, recording_dir=tmp_path)
    sub = session.subscribe(maxlen=len(recording))
    status = session.start_logging(raw=True, filtered=True, name="replayed")
    session.start()
    assert wait_until(lambda: session.status().processed == len(recording))
    session.stop()
    again = read_raw(status.raw_path)
    assert again.frames.tobytes() == recording.frames.tobytes()
    np.testing.assert_array_equal(again.times, recording.times)
    reference = process_file(recording_path)
    filtered = read_filtered(status.filtered_path)
    assert len(filtered.t) == len(recording)
    np.testing.assert_allclose(filtered.euler, reference.euler_output, atol=1e-8)
    np.testing.assert_allclose(filtered.joint_angles, reference.joint_angles, atol=1e-8,
                               equal_nan=True)
    samples = sub.drain()
    assert [s.index for s in samples] == list(range(len(recording)))
    np.testing.assert_array_equal(np.array([s.euler for s in samples]), reference.euler)


def test_slow_subscriber_loses_oldest_counted_and_blocks_nothing(recording_path, tmp_path):
    recording = read_raw(recording_path)
    session = LiveSession(ReplaySource(recording, speed=None), recording_dir=tmp_path)
    slow = session.subscribe(maxlen=10)
    status = session.start_logging(raw=True, filtered=False, name="slow")
    session.start()
    assert wait_until(lambda: session.status().processed == len(recording))
    session.stop()
    assert slow.dropped == len(recording) - 10
    assert session.status().dropped == len(recording) - 10
    assert [s.index for s in slow.drain()] == list(range(len(recording) - 10, len(recording)))
    assert len(read_raw(status.raw_path)) == len(recording)


def test_unwritable_folder_is_a_clear_error_and_streaming_goes_on(recording_path, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    session = LiveSession(ReplaySource(read_raw(recording_path), speed=None),
                          recording_dir=blocker / "sub")
    session.start()
    with pytest.raises((RecordingError, OSError)):
        session.start_logging(raw=True, filtered=True)
    assert wait_until(lambda: session.status().processed > 100)
    session.stop()


def test_reset_zero_on_request(recording_path, tmp_path):
    session = LiveSession(ReplaySource(read_raw(recording_path), speed=4.0),
                          recording_dir=tmp_path)
    session.start()
    assert wait_until(lambda: session.status().processed > 120)
    before = len(session.processor.pose.captures)
    session.reset_zero()
    assert wait_until(lambda: len(session.processor.pose.captures) == before + 1, 5.0)
    session.stop()


def test_forwarding_and_udp_client_mode(recording_path, tmp_path):
    recording = read_raw(recording_path)
    client = LiveSession(UdpFrameSource("127.0.0.1:0"), recording_dir=tmp_path / "client")
    port = client.source.udp.address[1]
    status = client.start_logging(raw=True, filtered=True, name="client")
    client.start()
    server = LiveSession(ReplaySource(recording, speed=8.0), recording_dir=tmp_path / "server")
    server.start_forwarding([f"127.0.0.1:{port}"])
    server.start()
    assert wait_until(lambda: client.status().processed == len(recording))
    server.stop()
    client.stop()
    assert client.status().source.counters["lost"] == 0
    assert read_raw(status.raw_path).frames.tobytes() == recording.frames.tobytes()
    filtered = read_filtered(status.filtered_path)
    reference = process_file(recording_path)
    np.testing.assert_allclose(filtered.euler, reference.euler_output, atol=1e-8)
    np.testing.assert_allclose(filtered.t, np.arange(len(recording)) * 0.02)


def test_bpms_replay_command_feeds_a_udp_client(recording_path):
    udp = UdpSource("127.0.0.1:0")
    port = udp.address[1]
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(recording_path),
                             "--udp", f"127.0.0.1:{port}", "--speed", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    frames = []
    end = time.monotonic() + 30
    while len(frames) < 800 and time.monotonic() < end:
        got = udp.read(0.5)
        if got is not None:
            frames.append(got)
    out, err = proc.communicate(timeout=30)
    udp.close()
    assert proc.returncode == 0, err
    assert len(frames) == 800 and "replaying 800 frames" in out
    assert [round(f.suit_time / 0.02) for f in frames] == list(range(800))
    # the last status line counts the POSE datagrams apart: one per frame, the 800 RAW
    # frames and the ZERO messages beside them
    last = re.findall(r"sent\s+(\d+) \(poses (\d+), raw/zero (\d+)\)", out)[-1]
    sent, poses, others = map(int, last)
    assert poses == 800 and others > 800 and sent == poses + others


@pytest.mark.parametrize("content", [b"", b"not a recording at all"])
def test_bpms_replay_refuses_foreign_files(tmp_path, content):
    path = tmp_path / "x.bpmsraw"
    path.write_bytes(content)
    proc = subprocess.run([sys.executable, "-m", "bpms", "replay", str(path), "--udp",
                           "127.0.0.1:9"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "not a BPMS raw recording" in proc.stderr and "Traceback" not in proc.stderr
