"""Replay feeds the live outputs: UDP POSE, LSL (received through a real pylsl inlet in another
process) and the MVN-compatible stream (decoded by a decoder written here from the public
protocol description, independent of bpms.pipeline.mvn)."""

from __future__ import annotations

import json
import os
import socket
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from waiting import receive_until_exit

from bpms.filter.body_model import POINT_NAMES
from bpms.firmware.sim.session import simulate
from bpms.io.frames import IMU_NAMES
from bpms.io.udp.codec import (
    decode_datagram,
    encode_header,
    encode_pose_extensions,
    encode_pose_payload,
)

ROOT = Path(__file__).resolve().parents[1]
SECONDS = 6.0
FRAMES = round(SECONDS * 50)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    rec = simulate(SECONDS, seed=2)
    path = tmp_path_factory.mktemp("lab") / "Raw_lab_001.bpmsraw"
    rec.save_raw(path)
    return rec, path


def _udp_socket():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(20.0)
    return sock


def _receive_all(sock, proc):
    """Datagrams until the sender has exited and the socket is quiet."""
    return receive_until_exit(sock, proc, silence=20.0)


def _replay(path, *extra):
    return subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(path), "--speed", "0",
                             *extra], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=os.environ.copy())


def test_replay_sends_raw_frames_and_poses(recording):
    _, path = recording
    sock = _udp_socket()
    proc = _replay(path, "--udp", f"127.0.0.1:{sock.getsockname()[1]}")
    grams = _receive_all(sock, proc)
    assert proc.wait(30) == 0, proc.stderr.read().decode()
    kinds = [g[5] for g in grams if g[:4] == b"BPMS"]
    assert kinds.count(1) == FRAMES  # RAW_FRAME, every frame
    # POSE once the segment orientations exist (the provisional Reset Zero at the first frame)
    assert kinds.count(2) >= FRAMES - 5
    last = [g for g in grams if g[5] == 2][-1]
    assert last[4] == 3  # format version 3 (the POSE extension blocks exist since version 2)
    pose = decode_datagram(last)
    pts = pose.pose.positions
    assert pts.shape == (21, 3) and pose.pose.convention == "isb"
    # NED, lowest foot on the ground: the head's top is about the subject's height up
    head_top = pts[POINT_NAMES.index("head_top")]
    assert -1.8 < head_top[2] < -1.5 and abs(pts[:, 2].max()) < 1e-3


def test_pose_version_2_readers_skip_unknown_extension_blocks():
    q = np.tile([1.0, 0.0, 0.0, 0.0], (18, 1))
    base = encode_pose_payload(q, np.zeros(28))
    unknown = struct.pack("!HH", 99, 5) + b"later"
    positions = np.arange(63, dtype=float).reshape(21, 3)
    payload = base + unknown + encode_pose_extensions(positions, "original")
    data = encode_header(2, 1, 0, 0.0, 0.0, version=2) + payload
    pose = decode_datagram(data).pose
    np.testing.assert_allclose(pose.positions, positions)
    assert pose.convention == "original"
    # a version-1 POSE is still read as before
    assert decode_datagram(encode_header(2, 1, 0, 0.0, 0.0, version=1)
                           + base).pose.positions is None


# -- MVN: a decoder from the public "MVN real-time network streaming protocol" ---------------

def decode_mvn(data: bytes) -> dict:
    """Header: 6 s ID string, I sample counter, B datagram counter, B items, I time code,
    B character id, B segments, B props, B finger segments, 2 reserved, H payload size."""
    ident, sample, dcount, items, timecode, _char, nseg, _nprop, _nfing, _, size = struct.unpack(
        ">6sIBBIBBBB2sH", data[:24])
    body = data[24:]
    assert len(body) == size
    out = {"id": ident.decode(), "sample": sample, "last": bool(dcount & 0x80), "items": items,
           "time_ms": timecode, "segments": nseg}
    if ident == b"MXTP02":
        recs = [struct.unpack(">i7f", body[k * 32:(k + 1) * 32]) for k in range(items)]
        out["ids"] = [r[0] for r in recs]
        out["pos_m"] = np.array([r[1:4] for r in recs])
        out["quat"] = np.array([r[4:8] for r in recs])
    elif ident == b"MXTP20":
        recs = [struct.unpack(">II3f", body[k * 20:(k + 1) * 20]) for k in range(items)]
        out["parent"] = [r[0] >> 8 for r in recs]
        out["child"] = [r[1] >> 8 for r in recs]
        out["angles"] = np.array([r[2:] for r in recs])
    return out


def test_mvn_stream_decodes_from_the_public_layout(recording):
    rec, path = recording
    sock = _udp_socket()
    proc = _replay(path, "--mvn", f"127.0.0.1:{sock.getsockname()[1]}")
    grams = _receive_all(sock, proc)
    assert proc.wait(30) == 0, proc.stderr.read().decode()
    poses = [decode_mvn(g) for g in grams if g[:6] == b"MXTP02"]
    joints = [decode_mvn(g) for g in grams if g[:6] == b"MXTP20"]
    assert len(poses) >= FRAMES - 5 and len(joints) == len(poses)
    assert all(len(g) == 760 for g in grams if g[:6] == b"MXTP02")
    p = poses[-1]
    assert p["ids"] == list(range(1, 24)) and p["last"] and p["segments"] == 23
    assert p["time_ms"] == p["sample"] * 20
    np.testing.assert_allclose(np.linalg.norm(p["quat"], axis=1), 1.0, atol=1e-5)
    # Z up, metres: standing, the head is ~1.5 m above the toes, the pelvis ~1 m
    head, pelvis, toe = p["pos_m"][6], p["pos_m"][0], p["pos_m"][18]
    assert 1.40 < head[2] - toe[2] < 1.75 and 0.80 < pelvis[2] - toe[2] < 1.10
    # the pelvis stands upright: its z axis is the world's up
    R_pelvis = _quat_to_dcm(p["quat"][0])
    assert R_pelvis[2, 2] > 0.99
    j = joints[-1]
    assert j["parent"][:2] == [1, 2] and j["child"][:2] == [2, 3] and j["items"] == 22
    # at the end the script raises the right arm forward: the geometry of the true segments
    C = rec.truth.C[j["sample"]]
    arm = C[15].T @ C[4] @ np.array([0.0, 0.0, 1.0])
    flexion = np.degrees(np.arctan2(arm[0], arm[2]))
    assert flexion > 30
    k = j["child"].index(9)  # RightUpperArm's joint: z = flexion
    assert j["angles"][k][2] == pytest.approx(flexion, abs=5.0)
    # the upper arm segment points forward-down in MVN's frame (x forward, z up)
    R_arm = _quat_to_dcm(p["quat"][8])
    assert R_arm[0, 2] < -0.3 or R_arm[0, 2] > 0.3


def _quat_to_dcm(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


# -- LSL ---------------------------------------------------------------------------------------

@pytest.fixture()
def lsl_env(tmp_path):
    """liblsl limited to this machine and to a session id of this test only."""
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-test-{os.getpid()}\n")
    return {**os.environ, "LSLAPICFG": str(cfg)}


def test_every_lsl_stream_reaches_an_inlet_in_another_process(recording, lsl_env):
    _, path = recording
    inlet = subprocess.Popen([sys.executable, str(ROOT / "tests" / "lsl_inlet.py"), str(FRAMES),
                              "90"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             env=lsl_env)
    sender = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(path), "--lsl",
                               "--lsl-wait", "60", "--speed", "4"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=lsl_env)
    out, _err = inlet.communicate(timeout=120)
    _sender_out, sender_err = sender.communicate(timeout=60)
    assert sender.returncode == 0, sender_err.decode()
    result = json.loads(out)
    info, data = result["info"], result["data"]
    assert set(info) == {"BPMS Segments", "BPMS Joint Angles", "BPMS Sensors",
                         "BPMS Disturbance", "BPMS Events"}
    seg, jnt, sen = info["BPMS Segments"], info["BPMS Joint Angles"], info["BPMS Sensors"]
    assert seg["channels"] == 72 and seg["type"] == "MoCap" and seg["rate"] == 50.0
    assert seg["labels"][:4] == [f"{IMU_NAMES[0].lower().replace(' ', '_')}_q{c}"
                                 for c in "wxyz"]
    assert jnt["channels"] == 28 and jnt["labels"][2] == "knee_r.flexion"
    assert jnt["convention"].startswith("isb")
    assert sen["channels"] == 162 and sen["type"] == "IMU"
    assert info["BPMS Disturbance"]["channels"] == 36
    for name in ("BPMS Segments", "BPMS Joint Angles", "BPMS Sensors", "BPMS Disturbance"):
        stamps = np.array(data[name]["stamps"])
        assert len(stamps) == FRAMES, name
        assert np.all(np.diff(stamps) > 0), name
        # replay at 4×: the frame clock's period is 5 ms
        assert np.median(np.diff(stamps)) == pytest.approx(0.005, abs=0.001), name
    events = data["BPMS Events"]["values"]
    assert "filter re-initialised" in events and "reset zero" in events, events
    assert np.all(np.diff(data["BPMS Events"]["stamps"]) >= 0)


def test_live_recording_streams_link_events_over_lsl(tmp_path, lsl_env):
    """`bpms record --sim --lsl` with the simulated suit falling silent for 3 s: the inlet in
    another process sees the link lost and recovered, the filter re-initialised, and
    increasing time stamps on every data stream."""
    inlet = subprocess.Popen([sys.executable, str(ROOT / "tests" / "lsl_inlet.py"),
                              "100000", "60"], cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, env=lsl_env)
    recorder = subprocess.Popen([sys.executable, "-m", "bpms", "record", "--sim", "--lsl",
                                 "--silent-after", "8", "--silent-for", "3", "--seconds", "16",
                                 "-o", str(tmp_path)], cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, env=lsl_env)
    _, rec_err = recorder.communicate(timeout=120)
    out, _ = inlet.communicate(timeout=120)
    assert recorder.returncode == 0, rec_err.decode()
    data = json.loads(out)["data"]
    events = data["BPMS Events"]["values"]
    assert "link lost" in events and "link recovered" in events, events
    assert events.index("link lost") < events.index("link recovered")
    assert "filter re-initialised" in events[events.index("link lost"):], events
    for name in ("BPMS Segments", "BPMS Joint Angles", "BPMS Sensors"):
        stamps = np.array(data[name]["stamps"])
        assert len(stamps) > 300, name  # ≥ 6 s of 50 Hz reached the inlet
        assert np.all(np.diff(stamps) > 0), name
        # the de-jittered clock: steps of 20 ms except across the silence, which shows as
        # a gap of about its length (the suit sampled nothing then)
        assert np.median(np.diff(stamps)) == pytest.approx(0.02, abs=0.002), name
        assert 2.0 < np.diff(stamps).max() < 4.5, name
