"""A missing sensor costs only its segments (issue 43.2): a cluster whose three IMUs report
errors in every frame no longer silences the pose stream. `bpms replay --udp --speed 0` sends
one POSE per frame, the dead cluster's segments NaN and flagged invalid (docs/udp.md "A
segment without data"); the MVN stream sends every frame the same way.

The independent truth is the simulated suit: which IMUs failed is what the test injected
(cluster 5 = IMUs 15, 16, 17: right shoulder, left shoulder, head), and which joint angles need
them is read off docs/joint-angles.md by hand below."""

from __future__ import annotations

import socket
import struct

import numpy as np
import pytest

from bpms.cli import main
from bpms.firmware.sim.session import simulate
from bpms.io.frames import encode_frames
from bpms.io.rawfile import new_header, write_raw
from bpms.io.udp.codec import (
    DatagramError,
    MessageType,
    decode_datagram,
    encode_header,
    encode_pose_extensions,
    encode_pose_payload,
)

pytestmark = pytest.mark.timeout(120)
DEAD = (15, 16, 17)  # cluster 5
#: the joint angles that need a shoulder or the head (docs/joint-angles.md: a ball joint's
#: angles are those of its two segments; the shoulders' parent is the spine IMU)
NEEDS_DEAD = {f"{j}.{a}" for j in ("shoulder_r", "shoulder_l", "head")
              for a in ("abduction", "flexion", "rotation")}


@pytest.fixture(scope="module")
def dead_cluster(tmp_path_factory):
    rec = simulate(duration_s=4.0, seed=43)
    errors = rec.errors.copy()
    errors[:, DEAD, :] = True
    path = tmp_path_factory.mktemp("dead") / "Raw_dead_1.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, encode_frames(rec.raw, errors),
              new_header(calibration=rec.calibration.values, notes="cluster 5 dead"))
    return path, len(rec)


def _receive_all(sock: socket.socket) -> list[bytes]:
    out = []
    sock.settimeout(0.5)
    try:
        while True:
            out.append(sock.recv(65535))
    except TimeoutError:
        return out


def test_replay_sends_a_pose_per_frame_with_15_valid_segments(dead_cluster, capsys):
    from bpms.filter.joints import JOINT_ANGLE_NAMES

    path, n = dead_cluster
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
        sock.bind(("127.0.0.1", 0))
        code = main(["replay", str(path), "--udp", f"127.0.0.1:{sock.getsockname()[1]}",
                     "--speed", "0"])
        got = [decode_datagram(d) for d in _receive_all(sock)]
    assert code == 0
    poses = [d for d in got if d.type == MessageType.POSE]
    assert len([d for d in got if d.type == MessageType.RAW_FRAME]) == n
    assert len(poses) == n  # 682dd18: 0
    assert sorted(d.seq for d in poses) == list(range(n))
    with_data = [p for p in poses if p.pose.valid]
    # before the first Reset Zero no segment has data; from it on, the 15 live ones
    assert len(with_data) >= n - 60
    needs = np.array([name in NEEDS_DEAD for name in JOINT_ANGLE_NAMES])
    for d in with_data:
        valid = d.pose.segment_valid()
        assert list(np.flatnonzero(~valid)) == list(DEAD)
        assert valid.sum() == 15
        q = d.pose.quaternions
        assert np.isnan(q[list(DEAD)]).all() and np.isfinite(q[valid]).all()
        assert np.allclose(np.linalg.norm(q[valid], axis=1), 1.0, atol=1e-5)
        a = d.pose.angles
        assert np.isnan(a[needs]).all() and np.isfinite(a[~needs]).all()


def _pose(q: np.ndarray, angles: np.ndarray, ext: bytes = b"") -> bytes:
    return encode_header(MessageType.POSE, 1, 0, 0.0, 0.0) + encode_pose_payload(
        q, angles, None) + ext


def test_nan_is_allowed_only_where_the_validity_block_says_so():
    q = np.tile([1.0, 0.0, 0.0, 0.0], (18, 1))
    valid = np.ones(18, dtype=bool)
    valid[4] = False
    q[4] = np.nan
    angles = np.zeros(28)
    angles[5] = np.nan
    payload = encode_pose_payload(q, angles, valid) + encode_pose_extensions(valid=valid)
    pose = decode_datagram(encode_header(MessageType.POSE, 1, 0, 0.0, 0.0) + payload).pose
    assert pose.valid == (1 << 18) - 1 - (1 << 4)
    assert np.isnan(pose.quaternions[4]).all() and np.isnan(pose.angles[5])
    assert np.isfinite(np.delete(pose.quaternions, 4, axis=0)).all()
    # the same NaN without the block: malformed, as before
    bare = encode_header(MessageType.POSE, 1, 0, 0.0, 0.0) + payload[:-8]
    with pytest.raises(DatagramError, match="NaN"):
        decode_datagram(bare)
    # a NaN in a segment the block calls valid: malformed
    lying = payload[:-4] + struct.pack("!I", (1 << 18) - 1)
    with pytest.raises(DatagramError, match="NaN"):
        decode_datagram(encode_header(MessageType.POSE, 1, 0, 0.0, 0.0) + lying)
    # an infinity is never a flag
    with pytest.raises(ValueError):
        encode_pose_payload(q, np.full(28, np.inf), valid)
    with pytest.raises(ValueError, match="NaN"):
        _pose(q, np.zeros(28))


def test_mvn_sends_every_frame_with_the_dead_segments_nan():
    from bpms.pipeline.mvn import MVN_SEGMENTS, MvnSender

    q = np.tile([1.0, 0.0, 0.0, 0.0], (18, 1))
    q[list(DEAD)] = np.nan
    positions = np.zeros((21, 3))
    angles = np.zeros(28)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sender = MvnSender([f"127.0.0.1:{sock.getsockname()[1]}"])
        try:
            sender.send(7, 140, q, positions, angles)
        finally:
            sender.close()
        got = _receive_all(sock)
    assert [g[:6] for g in got] == [b"MXTP02", b"MXTP20"]  # 682dd18 sent nothing
    body = got[0][24:]
    nan_segments = {MVN_SEGMENTS[k] for k in range(23)
                    if np.isnan(struct.unpack_from(">i7f", body, 32 * k)[4:]).any()}
    assert nan_segments == {"RightShoulder", "LeftShoulder", "Head"}
