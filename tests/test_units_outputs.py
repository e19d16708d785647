"""The physical units written and streamed (issue 46.1): ``bpms extract raw --calibrated``'s
CSV and the LSL "BPMS Sensors" stream (received by a pylsl inlet in another process, no bpms
import), against values worked out by hand from SPEC §4 and Table 2.2 (tests/hand_units.py),
never against SensorCalibration.physical_units.

The recording is built by hand: IMU i's frame f holds the counts hand_units.hand_raw(i, f),
with Table 2.2 (read from its CSV by tests/hand_units.py) in its header."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hand_units import hand_raw, physical, table

from bpms.io.frames import encode_frames
from bpms.io.rawfile import new_header, write_raw

ROOT = Path(__file__).resolve().parents[1]
FRAMES = 60
AXES = ("ax", "ay", "az", "mx", "my", "mz", "gx", "gy", "gz")
UNIT_ENDINGS = ("m_s2",) * 3 + ("gauss",) * 3 + ("rad_s",) * 3
#: every stream the replay offers (it waits for a consumer on each: --lsl-wait)
STREAMS = ("BPMS Segments", "BPMS Joint Angles", "BPMS Sensors", "BPMS Disturbance",
           "BPMS Events")


def _expected() -> np.ndarray:
    """[FRAMES, 18, 9] physical values by hand."""
    return np.array([[physical(i, hand_raw(i, f)) for i in range(18)] for f in range(FRAMES)])


@pytest.fixture(scope="module")
def hand_recording(tmp_path_factory) -> Path:
    raw = np.array([[hand_raw(i, f) for i in range(18)] for f in range(FRAMES)], np.int16)
    path = tmp_path_factory.mktemp("hand") / "Raw_hand_001.bpmsraw"
    write_raw(path, 1.7e9 + 0.02 * np.arange(FRAMES), encode_frames(raw),
              new_header(calibration=[list(rec.values()) for rec in table()],
                         notes="hand-built"))
    return path


def test_extract_calibrated_csv_in_physical_units(hand_recording, tmp_path):
    out = tmp_path / "cal.csv"
    done = subprocess.run([sys.executable, "-m", "bpms", "extract", "raw", str(hand_recording),
                           "--imu", "all", "--calibrated", "-o", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    with out.open(newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    names, values = rows[0], np.array(rows[1:], dtype=np.float64)
    assert names[:2] == ["time_s", "host_time_s"] and len(names) == 2 + 18 * 9
    for i in range(18):
        for k, axis in enumerate(AXES):
            name = names[2 + 9 * i + k]
            assert name.startswith(f"imu{i}_") and name.endswith(f"_{axis}_{UNIT_ENDINGS[k]}"), \
                name
    assert values.shape == (FRAMES, 2 + 18 * 9)
    np.testing.assert_allclose(values[:, 0], 0.02 * np.arange(FRAMES), atol=1e-9)
    np.testing.assert_allclose(values[:, 2:].reshape(FRAMES, 18, 9), _expected(),
                               rtol=1e-6, atol=1e-9)


@pytest.fixture
def lsl_env(tmp_path):
    """liblsl limited to this machine and to a session id of this test only."""
    import os

    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-units-{os.getpid()}\n")
    return {**os.environ, "LSLAPICFG": str(cfg)}


def test_lsl_sensor_stream_in_physical_units(hand_recording, lsl_env, deadline_scale):
    """`bpms replay --lsl`: every sample of the "BPMS Sensors" stream, 162 channels per
    frame in IMU order (ax ay az m/s², mx my mz G, gx gy gz rad/s), equals the hand values
    (float32: 1e-6 relative)."""
    wait = 60 * deadline_scale
    inlet = subprocess.Popen([sys.executable, str(ROOT / "tests" / "lsl_inlet.py"),
                              str(FRAMES), str(wait), ",".join(STREAMS), "BPMS Sensors"],
                             cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             env=lsl_env)
    sender = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(hand_recording),
                               "--lsl", "--lsl-wait", str(wait), "--speed", "4"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=lsl_env)
    out, err = inlet.communicate(timeout=2 * wait + 30)
    _, sender_err = sender.communicate(timeout=wait + 30)
    assert sender.returncode == 0, sender_err.decode()
    result = json.loads(out)
    info = result["info"]["BPMS Sensors"]
    assert info["channels"] == 162
    for i in range(18):
        for k, axis in enumerate(AXES):
            assert info["labels"][9 * i + k].endswith(f"_{axis}"), info["labels"][9 * i + k]
    got = np.array(result["data"]["BPMS Sensors"]["values"], dtype=np.float64)
    assert got.shape == (FRAMES, 162), (got.shape, err.decode()[-500:])
    np.testing.assert_allclose(got.reshape(FRAMES, 18, 9), _expected(), rtol=1e-6, atol=1e-6)
