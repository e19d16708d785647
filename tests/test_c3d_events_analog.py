"""C3D for the lab's tools (issue 49.1, 43.3), judged by ezc3d and the ``c3d`` package:

- a recording past the header's 65,535-frame limit is read in full by both;
- the EVENT group holds the heel strikes per side (against the simulated walk's true strikes),
  the typed marker and the Reset Zero captures (against the API);
- the analog channels hold each IMU's calibrated accelerometer, gyroscope and magnetometer
  (gravity at rest, the API's values), with units and labels;
- ``--walk`` moves the figure the way the simulated subject walked.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from bpms.firmware.sim.motion import Still, Walk
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate
from bpms.io.rawfile import new_header, write_raw
from bpms.io.session_events import SessionEvent

ezc3d = pytest.importorskip("ezc3d")
c3d = pytest.importorskip("c3d")

ROOT = Path(__file__).resolve().parents[1]
DT = 0.02
MARKER_FRAME = 160
#: NED → Z-up lab frame (x north, y west, z up), from docs/analysis.md
P = np.diag([1.0, -1.0, -1.0])


def _c3d_reader(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open(path, "rb") as f:
            reader = c3d.Reader(f)
            frames = [(points[:, :3].copy(), analog.copy())
                      for _, points, analog in reader.read_frames()]
            return reader, frames


def test_past_65535_frames_both_readers_read_every_frame(tmp_path):
    """70,000 frames (23.3 min at 50 Hz) of index-coded values through the exporter's writer."""
    from bpms.analysis.c3d_export import C3dWriter

    n, chunk = 70_000, 10_000
    path = tmp_path / "long.c3d"
    writer = C3dWriter(path, 50.0, [("recording", "long")])
    for lo in range(0, n, chunk):
        k = np.arange(lo, lo + chunk, dtype=np.float64)
        pos = np.zeros((chunk, 21, 3))
        pos[:, 0, 0] = k / 1000.0  # pelvis x = frame index, mm
        imu = tuple(np.broadcast_to(k[:, None, None] * s, (chunk, 18, 3)) for s in (1, 2, 3))
        writer.write(pos, np.zeros((chunk, 28)), imu)
    writer.close()
    f = ezc3d.c3d(str(path))
    assert f["data"]["points"].shape[-1] == n
    assert f["data"]["points"][0, 0, -1] == pytest.approx(n - 1)
    assert f["data"]["analogs"].shape[-1] == n
    assert f["data"]["analogs"][0, 0, -1] == pytest.approx(n - 1)  # imu0_acc_x
    reader, frames = _c3d_reader(path)
    assert reader.frame_count == n and len(frames) == n
    assert frames[-1][0][0, 0] == pytest.approx(n - 1)
    assert frames[-1][1][3, 0] == pytest.approx(3 * (n - 1))  # imu0_gyro_x (scale 3 here)


@pytest.fixture(scope="module")
def walked(tmp_path_factory):
    folder = tmp_path_factory.mktemp("c3dwalk")
    script = [Still("still", 3.0), Walk(steps=8), Still("still (end)", 2.0)]
    rec = simulate(seed=4, script=script, model=SensorModel(mounting_error_deg=0.0))
    raw = folder / "Raw_walk_001.bpmsraw"
    marker = SessionEvent("marker", MARKER_FRAME, 1.7e9 + MARKER_FRAME * DT,
                          {"text": "start walking"})
    write_raw(raw, 1.7e9 + rec.t, rec.frames,
              new_header(calibration=rec.calibration.values,
                         extra={"accel_range_g": float(rec.model.accel_range_g)}),
              events=[marker])
    out = {}
    for name, extra in (("still", []), ("walk", ["--walk"])):
        done = subprocess.run([sys.executable, "-m", "bpms", "export", "c3d", str(raw), "-o",
                               str(folder / name), "--reset-zero", "auto", *extra], cwd=ROOT,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        out[name] = folder / f"{name}.c3d"
    return rec, raw, out


def _events(f) -> list[tuple[str, str, float, str]]:
    ev = f["parameters"]["EVENT"]
    times = np.asarray(ev["TIMES"]["value"])  # [2, n]: minutes, seconds
    return [(lab.strip(), ctx.strip(), float(60 * m + s), d.strip()) for lab, ctx, m, s, d in
            zip(ev["LABELS"]["value"], ev["CONTEXTS"]["value"], times[0], times[1],
                ev["DESCRIPTIONS"]["value"], strict=True)]


def test_foot_strikes_per_side_match_the_simulated_walk(walked):
    rec, _, out = walked
    events = _events(ezc3d.c3d(str(out["still"])))
    for side in ("right", "left"):
        found = np.array([t for lab, ctx, t, _ in events
                          if lab == "Foot Strike" and ctx == side.title()])
        truth = np.array([t for t, s in rec.truth.heel_strikes if s == side])
        assert len(truth) >= 3
        assert abs(len(found) - len(truth)) <= 1, (found, truth)
        # each true strike has a Foot Strike of its side within 0.1 s
        near = [np.min(np.abs(found - t)) for t in truth]
        assert np.median(near) < 0.1, near


def test_marker_and_reset_zero_events(walked):
    _, raw, out = walked
    from bpms.filter.door import open_for_processing

    events = _events(ezc3d.c3d(str(out["still"])))
    markers = [e for e in events if e[0] == "Marker"]
    assert markers == [("Marker", "General", pytest.approx(MARKER_FRAME * DT, abs=1e-4),
                        "start walking")]
    opened = open_for_processing(raw, reset_zero="auto")
    zeros = [z.frame * DT for chunk in opened.chunks() for z in chunk.result.zeros]
    assert zeros
    found = [e[2] for e in events if e[0] == "Reset Zero"]
    assert found == pytest.approx(zeros, abs=1e-4)
    reader, _ = _c3d_reader(out["still"])  # the other reader sees the same labels
    labels = [s.strip() for s in reader.get("EVENT:LABELS").string_array]
    assert labels == [e[0] for e in events]


def test_analog_channels_are_the_calibrated_sensors(walked):
    rec, raw, out = walked
    from bpms.filter.door import open_for_processing

    f = ezc3d.c3d(str(out["still"]))
    analog = f["parameters"]["ANALOG"]
    labels = [s.strip() for s in analog["LABELS"]["value"]]
    units = [s.strip() for s in analog["UNITS"]["value"]]
    assert len(labels) == 18 * 9 and labels[:9] == [
        "imu0_acc_x", "imu0_acc_y", "imu0_acc_z", "imu0_gyro_x", "imu0_gyro_y", "imu0_gyro_z",
        "imu0_mag_x", "imu0_mag_y", "imu0_mag_z"]
    assert units[:9] == ["m/s^2"] * 3 + ["rad/s"] * 3 + ["G"] * 3
    data = f["data"]["analogs"][0]  # [channels, frames]
    assert data.shape == (162, len(rec.t))
    acc = data.reshape(18, 3, 3, -1)[:, 0]  # [imu, axis, frame]
    gyr = data.reshape(18, 3, 3, -1)[:, 1]
    still = slice(25, 125)  # inside the first 3 s standing still
    g = np.linalg.norm(acc[..., still], axis=1)
    assert np.abs(np.median(g, axis=1) - 9.81).max() < 0.3  # gravity, every IMU
    assert np.abs(np.median(gyr[..., still], axis=2)).max() < 0.05  # at rest
    walking = slice(200, 600)
    assert np.abs(gyr[..., walking]).max() > 1.0  # the legs swing (rad/s)
    opened = open_for_processing(raw, reset_zero="auto")
    acc_api, mag_api, gyr_api = opened.processor.sensor_calibration.physical_units(
        rec.raw.astype(np.float64))
    assert np.allclose(data.reshape(18, 3, 3, -1)[:, 2], np.moveaxis(mag_api, 0, -1),
                       atol=1e-5)
    assert np.allclose(gyr, np.moveaxis(gyr_api, 0, -1), atol=1e-5)
    assert np.allclose(acc, np.moveaxis(acc_api, 0, -1), atol=1e-4)
    _, frames = _c3d_reader(out["still"])
    assert np.allclose(frames[300][1][:, 0], data[:, 300], atol=1e-5)


def test_walk_moves_the_figure_along_the_walked_path(walked):
    rec, _, out = walked
    pelvis = {}
    for name, path in out.items():
        f = ezc3d.c3d(str(path))
        labels = [s.strip() for s in f["parameters"]["POINT"]["LABELS"]["value"]]
        xyz = f["data"]["points"][:3, labels.index("pelvis")] / 1000.0  # m, [3, frames]
        pelvis[name] = xyz[:, -1] - xyz[:, 150]  # from standing still to the end
    truth = P @ (rec.truth.pelvis_position[-1] - rec.truth.pelvis_position[150])
    assert np.linalg.norm(truth[:2]) > 2.0
    assert np.linalg.norm(pelvis["still"][:2]) < 0.05  # without --walk: over the origin
    moved = pelvis["walk"][:2]
    angle = np.degrees(np.arccos(moved @ truth[:2] / np.linalg.norm(moved)
                                 / np.linalg.norm(truth[:2])))
    assert angle < 10.0 and 0.5 < np.linalg.norm(moved) / np.linalg.norm(truth[:2]) < 1.2


def test_more_than_255_events_keep_the_first_255_and_say_so(tmp_path):
    """A C3D parameter dimension is one byte: the EVENT group holds 255 events."""
    from bpms.analysis.c3d_export import C3dWriter

    writer = C3dWriter(tmp_path / "many.c3d", 50.0, analog=False)
    writer.write(np.zeros((100, 21, 3)), np.zeros((100, 28)))
    for k in range(300):
        writer.add_event("Foot Strike", "Right" if k % 2 else "Left", k * 0.01, "strike")
    assert writer.dropped_events == 45
    writer.close()
    events = _events(ezc3d.c3d(str(tmp_path / "many.c3d")))
    assert len(events) == 255
    assert [e[2] for e in events] == pytest.approx([k * 0.01 for k in range(255)], abs=1e-5)
    reader, frames = _c3d_reader(tmp_path / "many.c3d")
    assert reader.get("EVENT:USED").int16_value == 255 and len(frames) == 100
