"""The disturbance indicators over the network (issue 19.2): the UDP POSE extension block
(tag 3, two 18-bit masks) and the ``BPMS Disturbance`` LSL stream, both fed by ``bpms replay``
of a simulated suit with a magnet beside the right forearm, received by independent readers."""

from __future__ import annotations

import dataclasses
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

from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import generate_motion
from bpms.firmware.sim.session import default_disturbance, simulate
from bpms.io.options import Options
from bpms.io.rawfile import new_header, write_raw
from bpms.io.udp.codec import (
    decode_datagram,
    encode_header,
    encode_pose_extensions,
    encode_pose_payload,
)

ROOT = Path(__file__).resolve().parents[1]
#: the feet and shanks, where the simulated magnet's field stays under 4 % of the earth's (the
#: thighs and the hip, beside the hanging right hand, see it turn the field by more than 5 %
#: of the earth's: they are flagged, rightly)
FAR_FROM_IT = [1, 2, 13, 14]


@pytest.fixture(scope="module")
def magnet(tmp_path_factory):
    """30 s of the simulated suit, a magnet beside IMU 5 (right forearm), recorded with the
    observer filter in its options; and the batch filter's indicators of the same frames."""
    mag = dataclasses.replace(default_disturbance(generate_motion(1500)), strength=150.0)
    rec = simulate(30.0, seed=3, mag_disturbance=True, disturbances=[mag])
    path = tmp_path_factory.mktemp("net") / "Raw_magnet_001.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames,
              new_header(calibration=rec.calibration.values,
                         options={"filter": {"algorithm": "observer"}}))
    options = Options()
    options.filter.algorithm = "observer"
    batch = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
    assert batch.disturbance.mag[:, 5].any()  # the scene: the magnet is seen
    return rec, path, batch.disturbance


def _masks(flags: np.ndarray) -> np.ndarray:
    """Bit i = IMU i, written out independently of bpms.io.udp."""
    return (flags.astype(np.int64) * (1 << np.arange(flags.shape[-1]))).sum(axis=-1)


def test_pose_datagrams_carry_the_disturbance_masks(magnet):
    rec, path, dist = magnet
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    sock.bind(("127.0.0.1", 0))
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(path), "--speed", "0",
                             "--udp", f"127.0.0.1:{sock.getsockname()[1]}"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    grams = receive_until_exit(sock, proc, silence=30.0)
    assert proc.wait(30) == 0
    poses = [decode_datagram(g) for g in grams if g[5] == 2]
    assert len(poses) > len(rec) - 10
    frames = np.array([round(p.suit_time / 0.02) for p in poses])
    mag = np.array([p.pose.mag_disturbed for p in poses])
    acc = np.array([p.pose.acc_disturbed for p in poses])
    np.testing.assert_array_equal(mag, _masks(dist.mag[frames]))
    np.testing.assert_array_equal(acc, _masks(dist.acc[frames]))
    assert (mag & (1 << 5)).any() and not (mag & _masks(np.isin(np.arange(18),
                                                                FAR_FROM_IT))).any()


def test_a_reader_that_knows_only_tags_1_and_2_skips_tag_3():
    """A version-2 reader written from docs/udp.md that walks the blocks by their length."""
    q = np.tile([1.0, 0.0, 0.0, 0.0], (18, 1))
    flags = np.zeros(18, dtype=bool)
    flags[[5, 17]] = True
    payload = encode_pose_payload(q, np.zeros(28)) + encode_pose_extensions(
        None, "isb", (flags, ~flags))
    data = encode_header(2, 1, 0, 0.0, 0.0, version=2) + payload
    pos, seen = 4 + 16 * 18 + 4 * 28, {}
    while pos < len(payload):
        tag, length = struct.unpack_from("!HH", payload, pos)
        seen[tag] = payload[pos + 4:pos + 4 + length]
        pos += 4 + length
    assert pos == len(payload) and seen[2] == b"isb"
    assert struct.unpack("!II", seen[3]) == ((1 << 5) | (1 << 17), 0x3FFFF ^ ((1 << 5)
                                                                          | (1 << 17)))
    pose = decode_datagram(data).pose
    assert pose.mag_disturbed == (1 << 5) | (1 << 17) and pose.convention == "isb"


@pytest.fixture()
def lsl_env(tmp_path):
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-dist-{os.getpid()}\n")
    return {**os.environ, "LSLAPICFG": str(cfg)}


def test_lsl_disturbance_stream_reaches_an_inlet_in_another_process(magnet, lsl_env):
    rec, path, dist = magnet
    inlet = subprocess.Popen([sys.executable, str(ROOT / "tests" / "lsl_inlet.py"),
                              str(len(rec)), "120"], cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=lsl_env)
    sender = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(path), "--lsl",
                               "--lsl-wait", "60", "--speed", "4"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=lsl_env)
    out, _ = inlet.communicate(timeout=180)
    _, err = sender.communicate(timeout=120)
    assert sender.returncode == 0, err.decode()
    result = json.loads(out)
    info = result["info"]["BPMS Disturbance"]
    assert info["channels"] == 36 and info["type"] == "Misc"
    assert info["labels"][5] == "imu5_right_forearm_mag_disturbed"
    assert info["labels"][18] == "imu0_right_leg_acc_disturbed"
    values = np.array(result["data"]["BPMS Disturbance"]["values"])
    assert values.shape == (len(rec), 36)
    np.testing.assert_array_equal(values, np.concatenate([dist.mag, dist.acc], axis=1))
