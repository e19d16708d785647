"""The headless processor on simulated-suit data: live = batch, chunks, files, accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.door import process_file
from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.rotations import dcm_to_euler, heading_error, inclination_error
from bpms.firmware.sim.session import simulate
from bpms.io.calib_file import load_factory_calibration
from bpms.io.options import Options
from bpms.io.rawfile import new_header, write_raw


@pytest.fixture(scope="module")
def short_rec():
    return simulate(duration_s=8.0, seed=2, error_rate=0.002)


@pytest.fixture(scope="module")
def full_rec():
    return simulate(seed=0)


def test_step_equals_process(short_rec):
    rec = short_rec
    batch = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    live = BodyPoseProcessor(rec.calibration)
    frames = [live.step(rec.raw[k], rec.errors[k]) for k in range(len(rec))]
    for name in ("R", "euler", "C", "t"):
        got = np.concatenate([getattr(f, name) for f in frames])
        np.testing.assert_allclose(got, getattr(batch, name), atol=1e-12, err_msg=name)
    np.testing.assert_allclose(np.concatenate([f.joint_angles for f in frames]),
                               batch.joint_angles, atol=1e-12)
    assert batch.held_count.sum() > 0  # the injected errors were held
    np.testing.assert_array_equal(frames[-1].held_count, batch.held_count)


def test_chunks_equal_one_pass_and_reset_zero_on_request(short_rec):
    rec = short_rec
    one = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors, zero_at=[300])
    proc = BodyPoseProcessor(rec.calibration)
    parts = [proc.process(rec.raw[:120], rec.errors[:120]),
             proc.process(rec.raw[120:300], rec.errors[120:300])]
    proc.reset_zero()
    parts.append(proc.process(rec.raw[300:], rec.errors[300:]))
    np.testing.assert_allclose(np.concatenate([p.C for p in parts]), one.C, atol=1e-12)
    assert [z.frame for z in one.zeros] == [0, 49, 300]
    assert np.allclose(np.concatenate([p.t for p in parts]), np.arange(len(rec)) * 0.02)


def test_outputs_shapes_and_figure_on_the_ground(short_rec):
    rec = short_rec
    res = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    n = len(rec)
    assert res.R.shape == (n, 18, 3, 3) and res.euler.shape == (n, 18, 3)
    assert res.C.shape == (n, 18, 3, 3) and res.quaternions.shape == (n, 18, 4)
    assert res.joint_angles.shape == (n, 28) and res.joint_positions.shape == (n, 21, 3)
    np.testing.assert_allclose(res.joint_positions[..., 2].max(axis=-1), 0.0, atol=1e-12)
    np.testing.assert_allclose(dcm_to_euler(res.R), res.euler, atol=1e-12)


def test_calibration_pose_after_auto_zero(full_rec):
    """During the still start, after the automatic Reset Zero, joint angles ≈ 0 and every
    segment reads the hip's heading."""
    rec = full_rec
    res = BodyPoseProcessor(rec.calibration).process(rec.raw[:150], rec.errors[:150])
    still = slice(60, 140)  # 1.2–2.8 s, inside the still window 0–3 s
    assert np.degrees(np.abs(res.joint_angles[still])).max() < 1.5
    psi0 = res.zeros[-1].yaw0
    yaw = dcm_to_euler(res.C[still])[..., 2]
    assert np.degrees(np.abs(np.angle(np.exp(1j * (yaw - psi0))))).max() < 1.5


def test_process_file_equals_process(tmp_path, short_rec):
    rec = short_rec
    path = tmp_path / "Raw_sim.bpmsraw"
    write_raw(path, rec.t + 1.7e9, rec.frames, new_header(calibration=rec.calibration.values))
    res = process_file(path, rec.calibration)
    ref = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    np.testing.assert_array_equal(res.euler, ref.euler)


def test_options_gains_reach_the_filter(short_rec):
    rec = short_rec
    opts = Options()
    opts.filter.kp_yaw = 0.0
    a = BodyPoseProcessor(rec.calibration, opts).process(rec.raw[:200])
    b = BodyPoseProcessor(rec.calibration).process(rec.raw[:200])
    assert not np.allclose(a.euler[50:], b.euler[50:])
    proc = BodyPoseProcessor(load_factory_calibration())
    proc.set_gains(kp_yaw=0.0)
    assert proc.bank.params[2] == 0.0


def test_accuracy_on_the_undisturbed_script(full_rec):
    """Original gains, simulated suit, after 1 s: inclination RMS < 2°, joint-angle RMS < 3°."""
    rec = full_rec
    res = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    k = rec.t >= 1.0
    incl = np.degrees(inclination_error(res.R[k], rec.truth.R[k]))
    head = np.degrees(heading_error(res.R[k], rec.truth.R[k]))
    joints = np.degrees(np.angle(np.exp(1j * (res.joint_angles[k] - rec.truth.joint_angles[k]))))
    assert np.sqrt(np.mean(incl**2)) < 2.0
    assert np.sqrt(np.mean(joints**2)) < 3.0
    assert np.sqrt(np.mean(head**2)) < 2.0


def test_compiled_calibration_equals_sensor_calibration(short_rec):
    rec = short_rec
    proc = BodyPoseProcessor(rec.calibration)
    fast = proc.calibrate(rec.raw)
    slow = proc.sensor_calibration.calibrate(rec.raw)
    for f, s in zip(fast, slow, strict=True):
        np.testing.assert_allclose(f, s, rtol=1e-13, atol=1e-12)
    as_float = proc.calibrate(rec.raw[:5].astype(np.float64)[:, :, :])
    np.testing.assert_allclose(as_float[0], slow[0][:5], rtol=1e-13, atol=1e-12)
