"""One set of numbers whichever way the kernels run (issue 18.3): the numpy twins that filter
short recordings without numba give the compiled kernels' numbers bit for bit, and a short
``bpms filter`` really runs without importing numba."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from bpms.cli import main as bpms
from bpms.filter import kernels
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate

FULL_SCALE = 32767


@pytest.fixture(scope="module")
def hard_recording():
    """38 s of the scripted motion with a magnet passing, 1 % failed readings, and 4 frames
    of a gyroscope pinned at full scale (the state guard re-initialises the filters)."""
    rec = simulate(38.0, seed=11, mag_disturbance=True, error_rate=0.01)
    raw = rec.raw.copy()
    raw[600:604, :, 6:9] = FULL_SCALE
    return raw, rec.errors


def _run(raw, errors, use_twins: bool):
    """The processor's results over three batches, with a Reset Zero, a gain change, a
    manual filter reset and non-finite input through the API; plus its final state."""
    proc = BodyPoseProcessor()
    results = []
    with kernels.twins(use_twins):
        results.append(proc.process(raw[:700], errors[:700], zero_at=[120]))
        proc.set_gains(kp_rollpitch=0.05, kp_yaw=2.0)
        proc.reset_filter(3)
        bad = raw[700:1200].astype(np.float64)
        bad[10, 5, 3] = np.nan  # a NaN magnetometer reading: held, not filtered
        results.append(proc.process(bad, errors[700:1200]))
        results.append(proc.process(raw[1200:], None, zero_at=[40]))
    state = [a.copy() for a in proc.bank.state.arrays()]
    return results, state, proc.disturbance.state.copy(), proc.guard.count.copy()


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Equal dtype, shape and bits (signed zeros told apart; a NaN's sign bit aside)."""
    if a is None or b is None:
        return a is b
    if a.dtype != b.dtype or a.shape != b.shape or not np.array_equal(a, b, equal_nan=True):
        return False
    if a.dtype.kind != "f":
        return True
    numbers = ~np.isnan(a)
    return np.array_equal(np.signbit(a[numbers]), np.signbit(b[numbers]))


def test_twins_give_the_compiled_numbers_bit_for_bit(hard_recording):
    raw, errors = hard_recording
    compiled = _run(raw, errors, use_twins=False)
    twinned = _run(raw, errors, use_twins=True)
    (res_c, state_c, dist_c, count_c), (res_t, state_t, dist_t, count_t) = compiled, twinned
    # the hard parts really happened, so the comparison covers them
    assert count_c.sum() > 0  # the state guard re-initialised filters
    assert any(r.disturbance.mag.any() for r in res_c)  # the magnet was flagged
    assert any(len(r.zeros) for r in res_c)  # Reset Zero captured
    for rc, rt in zip(res_c, res_t, strict=True):
        for name in ("t", "R", "euler", "C", "gyro_bias", "reinitialised", "corrected",
                     "joint_angles", "joint_positions"):
            assert _same(getattr(rc, name), getattr(rt, name)), name
        for name in ("mag", "acc", "mag_norm_ratio", "mag_dip_dev_deg", "acc_dev_g"):
            assert _same(getattr(rc.disturbance, name), getattr(rt.disturbance, name)), name
    for a, b in zip(state_c, state_t, strict=True):
        assert _same(a, b)
    assert _same(dist_c, dist_t)
    assert _same(count_c, count_t)


def test_twins_are_the_only_code_in_a_twins_block(hard_recording):
    # Would fail if a kernel ignored the block (or a twin silently fell back to numba): the
    # twin counts its calls.
    raw, errors = hard_recording
    calls = []
    k = kernels.registered()
    with_twin = [x for x in k if x.twin_name is not None]
    assert {x.__name__ for x in with_twin} >= {"run_batch", "calibrate_batch", "right_multiply",
                                              "_check", "run_disturbance", "step_frame"}
    originals = {x: x.twin() for x in with_twin}

    def counting(fn, name):
        def twin(*args):
            calls.append(name)
            return fn(*args)
        return twin

    try:
        for x, fn in originals.items():
            x._twin = counting(fn, x.__name__)
        with kernels.twins():
            result = BodyPoseProcessor().process(raw[:100], errors[:100], zero_at=[10])
            _ = (result.euler_output, result.joint_angles, result.joint_positions)
    finally:
        for x, fn in originals.items():
            x._twin = fn
    assert {"run_batch", "calibrate_batch", "right_multiply", "_check", "run_disturbance",
            "segment_euler", "joint_angle_frames", "joint_position_frames"} <= set(calls)


def test_short_filter_runs_without_numba_and_writes_the_same_file(tmp_path):
    raw_path = tmp_path / "Raw_short_1.bpmsraw"
    simulate(8.0, seed=2, error_rate=0.005).save_raw(raw_path)
    twinned = tmp_path / "twins.csv"
    code = ("import sys; from bpms.cli import main; rc = main(sys.argv[1:]); "
            "print('NUMBA', 'numba' in sys.modules); sys.exit(rc)")
    done = subprocess.run([sys.executable, "-c", code, "filter", str(raw_path), "-o",
                           str(twinned)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "NUMBA False" in done.stdout
    # this process has numba loaded (conftest), so the same command runs compiled here
    assert kernels.numba_loaded()
    compiled = tmp_path / "compiled.csv"
    assert bpms(["filter", str(raw_path), "-o", str(compiled)]) == 0
    assert twinned.read_bytes() == compiled.read_bytes()


def test_a_recording_over_the_budget_is_filtered_compiled(tmp_path):
    raw_path = tmp_path / "Raw_long_1.bpmsraw"
    simulate(4.0, seed=4, noise=False).save_raw(raw_path)  # 200 frames
    code = ("import sys; from bpms.cli import main; rc = main(sys.argv[1:]); "
            "print('NUMBA', 'numba' in sys.modules); sys.exit(rc)")
    runs = {}
    for budget in ("199", "200", "oops"):
        env = {**os.environ, kernels.TWIN_FRAMES_ENV: budget}
        done = subprocess.run([sys.executable, "-c", code, "filter", str(raw_path), "-o",
                               str(tmp_path / f"f{budget}.csv")], capture_output=True,
                              text=True, timeout=300, env=env)
        assert done.returncode == 0, done.stderr
        runs[budget] = done
    assert "NUMBA True" in runs["199"].stdout  # one frame over the budget: compiled
    assert "NUMBA False" in runs["200"].stdout
    # a malformed budget: one clear warning, the default (3000 frames) applies
    assert "NUMBA False" in runs["oops"].stdout
    assert "BPMS_TWIN_FRAMES='oops' is not a whole number" in runs["oops"].stderr
    assert "Traceback" not in runs["oops"].stderr
    assert (tmp_path / "f199.csv").read_bytes() == (tmp_path / "f200.csv").read_bytes()


def test_budget_is_claimed_once_and_never_after_numba():
    # numba is loaded in the test process: no twins any more, whatever the length
    assert not kernels.claim_twin_frames(1)


def test_live_step_twin_gives_the_compiled_numbers(hard_recording):
    raw, errors = hard_recording
    outputs = {}
    for use_twins in (False, True):
        proc = BodyPoseProcessor()
        rows = []
        with kernels.twins(use_twins):
            for k in range(560, 660):  # includes the pinned gyroscope (re-initialisation)
                if k == 580:
                    proc.reset_zero()
                r = proc.step(raw[k], errors[k])
                rows.append((r.R, r.euler, r.C, r.gyro_bias, r.reinitialised,
                             r.disturbance.mag_norm_ratio))
        outputs[use_twins] = rows
    assert any(row[4].any() for row in outputs[False])
    for compiled, twinned in zip(outputs[False], outputs[True], strict=True):
        for a, b in zip(compiled, twinned, strict=True):
            assert _same(a, b)


def test_bank_twin_with_per_frame_gains_and_resets(hard_recording):
    from bpms.filter.bank import MahonyBank

    raw, errors = hard_recording
    proc = BodyPoseProcessor()
    acc, mag, gyr = proc.calibrate(raw[:400])
    n = len(acc)
    params = np.tile(proc.bank.params, (n, 1))
    params[200:, 0] *= 3.0  # kp_rollpitch changes at frame 200
    resets = np.zeros((n, 18), dtype=bool)
    resets[150, [0, 7, 17]] = True  # three IMUs re-initialised mid-batch
    outs = []
    for use_twins in (False, True):
        bank = MahonyBank(proc.sensor_calibration.gravity)
        with kernels.twins(use_twins):
            out = bank.process(acc, mag, gyr, errors[:400], resets, params, store_terms=True)
        outs.append((out, [a.copy() for a in bank.state.arrays()]))
    (out_c, state_c), (out_t, state_t) = outs
    for name in ("R", "euler", "w_i", "w_p"):
        assert _same(getattr(out_c, name), getattr(out_t, name)), name
    for a, b in zip(state_c, state_t, strict=True):
        assert _same(a, b)
    # the reset happened: the re-initialised filter starts with ωI = 0
    assert (out_c.w_i[150, 7] == 0).all() and (out_c.w_i[149, 7] != 0).any()


def test_disturbance_twin_on_runaway_rotations():
    # A finite but huge DCM row (a runaway state through the public API): m·d is inf − inf,
    # NaN, which the kernel's clamp turns into −1 (dip −90°); the twin must do the same.
    from bpms.filter.disturbance import DisturbanceTracker

    n, frames = 2, 120
    acc = np.tile([0.0, 0.0, 256.0], (frames, n, 1))
    mag = np.tile([60.0, 30.0, 80.0], (frames, n, 1))
    gyr = np.zeros((frames, n, 3))
    R = np.tile(np.eye(3), (frames, n, 1, 1))
    R[:, 0, 2] = [1e308, -1e308, 0.0]
    states = []
    for use_twins in (False, True):
        tracker = DisturbanceTracker(np.full(n, 256.0), 0.02)
        with kernels.twins(use_twins), np.errstate(all="ignore"):
            out = tracker.update(acc, mag, gyr, R)
        states.append((tracker.state.copy(), out.mag_dip_dev_deg))
    assert _same(states[0][0], states[1][0])
    assert _same(states[0][1], states[1][1])


def test_gravity_must_be_positive():
    from bpms.filter.bank import MahonyBank
    from bpms.filter.disturbance import DisturbanceTracker

    for bad in ([256.0, 0.0], [256.0, np.nan], [-1.0, 256.0]):
        with pytest.raises(ValueError, match="gravity must be finite counts/g > 0"):
            MahonyBank(np.array(bad))
        with pytest.raises(ValueError, match="gravity must be finite counts/g > 0"):
            DisturbanceTracker(np.array(bad), 0.02)


def test_the_plan_ends_with_the_recording(tmp_path):
    # A short recording through the door runs on the twins; the same processor then given
    # more frames than the budget allows runs them compiled (the plan does not outlive it).
    raw_path = tmp_path / "Raw_short_1.bpmsraw"
    simulate(4.0, seed=4, noise=False).save_raw(raw_path)  # 200 frames
    code = (
        "import sys, numpy as np\n"
        "from bpms.filter.processor import BodyPoseProcessor\n"
        "proc = BodyPoseProcessor()\n"
        "proc.process_file(sys.argv[1])\n"
        "print('AFTER_FILE', 'numba' in sys.modules)\n"
        "proc.process(np.zeros((400, 18, 9), dtype=np.int16))\n"
        "print('AFTER_LONG', 'numba' in sys.modules)\n")
    env = {**os.environ, kernels.TWIN_FRAMES_ENV: "300"}
    done = subprocess.run([sys.executable, "-c", code, str(raw_path)], capture_output=True,
                          text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    assert "AFTER_FILE False" in done.stdout and "AFTER_LONG True" in done.stdout


def test_body_twins_give_the_compiled_numbers(hard_recording):
    # Segment angles, joint angles (both conventions) and joint positions (on the ground or
    # not) from segment orientations with NaN IMUs, NaN frames and entries just past ±1.
    from bpms.filter.body_model import joint_positions
    from bpms.filter.joints import joint_angles
    from bpms.filter.pose import segment_angles
    from bpms.io.options import BodyOptions

    raw, errors = hard_recording
    C = BodyPoseProcessor().process(raw[:400], errors[:400]).C.copy()
    C[100, 4] = np.nan  # one arm IMU missing
    C[101] = np.nan  # a whole frame missing
    C[102, :, 2, 0] = 1.0 + 1e-12  # rounding past the asin domain
    C[103, 6, 0, 0] = np.inf
    body = BodyOptions(arm=0.31, thigh=0.47)
    outputs = {}
    for use_twins in (False, True):
        with kernels.twins(use_twins):
            outputs[use_twins] = [segment_angles(C), joint_angles(C, "isb"),
                                  joint_angles(C, "original"), joint_positions(C, body),
                                  joint_positions(C[:3], body, on_ground=False)]
    assert np.isnan(outputs[False][1][101]).all() and np.isfinite(outputs[False][1][200]).all()
    assert np.isfinite(outputs[False][0][102]).all()  # clipped, not NaN
    for compiled, twinned in zip(outputs[False], outputs[True], strict=True):
        assert _same(compiled, twinned)


def test_every_kernel_cache_is_keyed_by_every_kernel_module():
    # A kernel that calls another module's kernel must not keep stale machine code when that
    # module changes: every kernel's cache key holds every kernel module's file stamp.
    import importlib

    for name in kernels.KERNEL_MODULES:
        importlib.import_module(f"bpms.filter.{name}")
    modules = {k.__module__.rsplit(".", 1)[-1] for k in kernels.registered()}
    assert modules == set(kernels.KERNEL_MODULES)
    stamp = kernels._sources_stamp()
    assert [entry[0] for entry in stamp] == list(kernels.KERNEL_MODULES)
    for k in kernels.registered():
        key = k.dispatcher._cache._cache_file._source_stamp
        assert key[1] == stamp, k
