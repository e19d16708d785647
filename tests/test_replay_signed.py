"""``bpms replay`` signs its datagrams with the shared key and opens the recording through the
one door (issue 16 follow-up)."""

from __future__ import annotations

import hashlib
import hmac
import os
import socket
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from waiting import receive_until_exit

from bpms.firmware.sim.session import simulate

ROOT = Path(__file__).resolve().parents[1]
KEY = "lab secret 7"


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    rec = simulate(3.0, seed=11)
    path = tmp_path_factory.mktemp("signed") / "Raw_signed_001.bpmsraw"
    rec.save_raw(path)
    return path


def _replay_and_receive(path, env):
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    sock.bind(("127.0.0.1", 0))
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(path), "--speed", "0",
                             "--udp", f"127.0.0.1:{sock.getsockname()[1]}"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    grams = receive_until_exit(sock, proc, silence=30.0)
    _, err = proc.communicate(timeout=30)
    sock.close()
    assert proc.returncode == 0, err
    return grams, err


def test_replay_signs_every_datagram_with_the_shared_key(raw):
    env = {**os.environ, "BPMS_UDP_KEY": KEY}
    grams, err = _replay_and_receive(raw, env)
    assert len(grams) >= 150
    for g in grams:
        flags = struct.unpack_from("!H", g, 6)[0]
        assert flags & 1, "HMAC flag not set"
        body, tag = g[:-32], g[-32:]
        # HMAC-SHA256 over header and payload, as docs/udp.md describes
        assert hmac.compare_digest(tag, hmac.new(KEY.encode(), body, hashlib.sha256).digest())
    # the one door says where the calibration and options came from
    assert "calibration: recording header" in err


def test_replay_without_a_key_sends_unsigned(raw):
    env = {k: v for k, v in os.environ.items() if k != "BPMS_UDP_KEY"}
    grams, _ = _replay_and_receive(raw, env)
    assert grams and not any(struct.unpack_from("!H", g, 6)[0] & 1 for g in grams)
