"""The pose a sender streams, and the Reset Zero it carries (issue 25): POSE datagrams decoded by
the reader written from docs/udp.md alone equal the API's segment quaternions (after Reset
Zero, not the sensors' attitudes); a UDP client that joins while the sender's subject walks
adopts the sender's Reset Zero (ZERO datagrams) and, once its filters converged, shows the
sender's segment angles in the still pose; a client whose user pressed their own Reset Zero
keeps it. Real sockets on 127.0.0.1, real processes for ``bpms replay``."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from udp_docs_reader import docs_reader
from waiting import receive_until_exit, wait_until

from bpms.filter.door import process_file
from bpms.filter.rotations import dcm_to_euler
from bpms.firmware.sim.session import simulate
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession
from bpms.pipeline.sources import UdpFrameSource

ROOT = Path(__file__).resolve().parents[1]



@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    """The simulated suit's whole script (74 s): still, arm raises, ..., a walk, still."""
    rec = simulate(seed=5)
    path = tmp_path_factory.mktemp("udp") / "Raw_trial_1.bpmsraw"
    write_raw(path, rec.t + 1.7e9, rec.frames, new_header(calibration=rec.calibration.values))
    return rec, path


def test_replayed_pose_datagrams_are_the_segment_orientations(trial, tmp_path):
    """``bpms replay --speed 0`` of 12 s: one POSE per frame, each equal (float32) to the
    API's segment quaternions, which differ from the IMUs' own attitudes by the mounting."""
    rec, _ = trial
    n = 600
    path = tmp_path / "Raw_short_1.bpmsraw"
    write_raw(path, rec.t[:n] + 1.7e9, rec.frames[:n * 340],
              new_header(calibration=rec.calibration.values))
    api = process_file(path)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    sock.bind(("127.0.0.1", 0))
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(path), "--speed",
                             "0", "--udp", f"127.0.0.1:{sock.getsockname()[1]}"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    datagrams = receive_until_exit(sock, proc)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err.decode()
    parse = docs_reader()
    poses = [m for m in map(parse, datagrams) if m is not None and m["type"] == 2]
    assert [round(m["suit_time"] / 0.02) for m in poses] == list(range(n))
    q = np.array([m["quaternions"] for m in poses])
    want = api.segment_quaternions
    sign = np.sign((q * want).sum(axis=-1, keepdims=True))
    np.testing.assert_allclose(q * sign, want, rtol=0, atol=1e-6)
    sensors = api.quaternions
    apart = 1 - np.abs((want * sensors).sum(axis=-1))
    assert apart.max() > 1e-3  # the two are told apart (mounting errors of the suit)


def _follow(trial, press_own: bool):
    """A sender replays the trial 8× real time; a client gets its UDP stream from 62 s in (the
    subject walks). Returns (sender samples, client samples) by frame index, the client's
    event lines and its zero in force at the end."""
    rec, path = trial
    client_source = UdpFrameSource("127.0.0.1:0")
    port = client_source.udp.address[1]
    sender = LiveSession(ReplaySource(read_raw(path), speed=8.0))
    sender_sub = sender.subscribe(maxlen=5000, lossless=True)
    client = LiveSession(client_source)
    client_sub = client.subscribe(maxlen=5000)
    got_sender, got_client = {}, {}
    with sender:
        with client:  # listening (and warmed up) before the stream reaches it
            assert wait_until(lambda: sender.status().processed >= round(62.0 / 0.02), 60)
            sender.start_forwarding([f"127.0.0.1:{port}"])
            if press_own:
                assert wait_until(lambda: client.status().processed > 100, 20)
                client.reset_zero()
            assert wait_until(lambda: sender.status().source.state == "ended"
                              and sender.status().processed == len(rec.t), 60)
            assert wait_until(lambda: client.status().processed > 550, 20)
            events = client.status().events
            zero = client.processor.pose.zero
        for s in sender_sub.drain():
            got_sender[s.index] = s.C
    for s in client_sub.drain():
        got_client[s.index] = s.C
    return got_sender, got_client, events, zero


def _still_end_difference_deg(got_sender, got_client) -> float:
    """Largest segment-angle difference, deg, over the still pose at the end, 10 s after the
    client joined (72–74 s)."""
    frames = [k for k in range(round(72.0 / 0.02), round(74.0 / 0.02)) if k in got_client]
    assert len(frames) >= 90
    a = dcm_to_euler(np.stack([got_sender[k] for k in frames]))
    b = dcm_to_euler(np.stack([got_client[k] for k in frames]))
    d = np.angle(np.exp(1j * (a - b)))
    return float(np.degrees(np.abs(d)).max())


def test_a_udp_client_shows_the_senders_segment_angles(trial):
    sender, client, events, zero = _follow(trial, press_own=False)
    assert any("Reset Zero (network)" in e for e in events), events
    assert zero.source == "network"
    assert _still_end_difference_deg(sender, client) < 0.5


def test_a_client_that_pressed_reset_zero_keeps_its_own(trial):
    _, _, events, zero = _follow(trial, press_own=True)
    pressed = [k for k, e in enumerate(events) if "Reset Zero (manual)" in e]
    assert pressed, events
    # its own zero holds to the end: the sender's (sent every second) is not followed again
    assert zero.source == "manual"
    assert not any("Reset Zero (network)" in e for e in events[pressed[0]:]), events
