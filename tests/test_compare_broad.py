"""``bpms compare`` on real data: BROAD trials (real IMU data with optical ground truth, Laidig
et al. 2021, CC BY 4.0) converted to a BPMS recording plus a Vicon export, against BROAD's own
published evaluation of the same filter output.

BROAD's published ground truth ``opt_quat`` is already expressed in the IMU's frames: the
dataset's authors estimated the IMU-to-cluster and the world rotations once (the paper's
appendix C) and applied them. Its evaluation code (``broad_utils.calculateRMSE``, mirrored in
bench/broad.py's ``errors``) then computes, over the movement phases, the world-frame error
``q_imu ⊗ q_opt⁻¹``: total ``2 acos|w|``, heading ``2 atan|z/w|``, inclination
``2 acos √(w² + z²)``.

The same filter output (the ``adaptive`` filter, through ``bpms compare --filter adaptive``) is
scored both ways.

Here the truth is hidden behind known rotations (a random IMU-to-cluster rotation and a random
optical world, ENU underneath) and a known clock offset, written at 100 Hz as a Vicon CSV
covering the movement phase. ``bpms compare`` must find the offset within one sample, and with
the offset and the rotations given (``--offset``, ``--alignment``) give BROAD's RMSE within
0.1° on each trial: the resampling, the frames and the error metric are BROAD's. Its own
estimate of the rotations (from the gyros, gravity and the field) is checked against the ones
BROAD's authors applied within the bound measured below.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bpms.analysis.compare import compare, load_recording, read_optical
from bpms.analysis.compare_align import angle_deg, exp_map
from bpms.analysis.compare_synth import interpolate_rotations, write_vicon_csv
from bpms.cli import main
from bpms.filter.door import open_for_processing
from bpms.filter.rotations import dcm_to_quaternion, quaternion_to_dcm
from bpms.firmware.sim.sensors import SensorModel, SensorValues, to_raw
from bpms.io.calib_file import load_factory_calibration
from bpms.io.frames import encode_frames
from bpms.io.rawfile import new_header, write_raw

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "broad"
TRIALS = ("02_undisturbed_slow_rotation_B", "11_undisturbed_slow_translation_B",
          "25_disturbed_tapping_B")
FILTER = "adaptive"  # a filter that has converged 20 s into the trial (Mahony's factory gains
#                      have not: BROAD's own figures for it are 5-8°; the equality holds alike)
RATE = 50.0
REST_S, MOVE_S = 20.0, 60.0  # kept before the movement starts / of the movement
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

pytestmark = pytest.mark.skipif(
    not all((DATA / f"{t}.hdf5").is_file() for t in TRIALS),
    reason=f"BROAD data not found at {DATA} (../shared/data/broad from the repository root)")


def _bench():
    spec = importlib.util.spec_from_file_location("bench_broad_c", REPO / "bench" / "broad.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _trial_50hz(name: str) -> dict:
    """The trial at 50 Hz from REST_S before the movement to MOVE_S into it (as
    tools/make_broad_excerpt.py: gyro the mean rate over each 20 ms, acc/mag linear, truth
    and movement the nearest sample)."""
    import h5py

    with h5py.File(DATA / f"{name}.hdf5", "r") as f:
        fs = float(f.attrs["sampling_rate"])
        gyr, acc, mag = (np.asarray(f[k], np.float64) for k in ("imu_gyr", "imu_acc", "imu_mag"))
        quat = np.asarray(f["opt_quat"], np.float64)
        movement = np.asarray(f["movement"], bool)
    start = np.flatnonzero(movement)[0] / fs
    t_src = np.arange(len(gyr)) / fs
    t = start - REST_S + np.arange(round((REST_S + MOVE_S) * RATE) + 1) / RATE
    integral = np.concatenate([np.zeros((1, 3)), np.cumsum(gyr[:-1], axis=0) / fs])
    angle = np.stack([np.interp(t, t_src, integral[:, k]) for k in range(3)], 1)
    rate = np.diff(angle, axis=0) * RATE
    t = t[1:]
    lin = lambda x: np.stack([np.interp(t, t_src, x[:, k]) for k in range(3)], 1)  # noqa: E731
    near = np.clip(np.rint(t * fs).astype(int), 0, len(t_src) - 1)
    return dict(gyr=rate, acc=lin(acc), mag=lin(mag), quat=quat[near], movement=movement[near])


def _recording(folder: Path, d: dict) -> Path:
    """The trial as a BPMS recording: the same motion on all 18 IMUs (BROAD's sensor frame as
    each IMU's filter frame), through the simulated suit's forward model (as
    tests/test_broad_real_motion.py)."""
    acc = -d["acc"] / 9.81
    mag = 100.0 * d["mag"] / np.linalg.norm(d["mag"], axis=-1).mean()
    values = SensorValues(*(np.repeat(v[:, None, :], 18, axis=1) for v in (acc, mag, d["gyr"])))
    table = load_factory_calibration()
    raw = to_raw(values, table, SensorModel())
    path = folder / "Raw_broad_001.bpmsraw"
    t = np.arange(len(acc)) / RATE
    write_raw(path, 1.7e9 + t, encode_frames(raw), new_header(
        calibration=table.values, extra={"accel_range_g": float(SensorModel().accel_range_g)}))
    return path


def _optical(folder: Path, d: dict, seed: int) -> tuple[Path, float, np.ndarray, np.ndarray]:
    """(Vicon CSV of the movement phase at 100 Hz, offset s, S, W): the cluster orientation
    ``Q = A · q_opt · B`` with random A, B; on the recording's frames ``R = W Q S`` with
    ``W = ENU→NED · Aᵀ``, ``S = Bᵀ``."""
    rng = np.random.default_rng(seed)
    A = exp_map(rng.normal(size=3) * 0.6)
    B = exp_map(rng.normal(size=3) * 0.6)
    ok = np.isfinite(d["quat"]).all(axis=1)
    R_opt = np.full((len(ok), 3, 3), np.nan)
    R_opt[ok] = quaternion_to_dcm(d["quat"][ok])
    t = np.arange(len(ok)) / RATE
    move = np.flatnonzero(d["movement"])
    t0, t1 = t[move[0]], t[move[-1]]
    t_opt = np.arange(0.0, t1 - t0, 0.01)
    # the truth at 100 Hz: geodesic between the 50 Hz samples, missing where either is
    Q = interpolate_rotations(t, np.where(ok[:, None, None], R_opt, np.eye(3)), t0 + t_opt)
    k = np.floor((t0 + t_opt) * RATE + 1e-9).astype(int)
    lost = ~(ok[k] & ok[np.minimum(k + 1, len(ok) - 1)])
    Q = A @ Q @ B
    Q[lost] = np.nan
    path = write_vicon_csv(folder / "broad.csv", 100.0, {"Box": (Q, np.zeros((len(Q), 3)))})
    return path, float(t0), B.T, ENU_TO_NED @ A.T


@pytest.fixture(scope="module")
def trials(tmp_path_factory):
    out = []
    for k, name in enumerate(TRIALS):
        folder = tmp_path_factory.mktemp(name[:2])
        d = _trial_50hz(name)
        raw = _recording(folder, d)
        optical, offset, S, W = _optical(folder, d, seed=k)
        (folder / "map.txt").write_text("Box = Right Leg\n", encoding="utf-8")
        out.append((name, d, raw, optical, offset, S, W, folder))
    return out


def _alignment_file(folder: Path, S: np.ndarray, W: np.ndarray) -> Path:
    doc = {"segments": [{"body": "Subject:Box", "alignment": {
        "S_quaternion": dcm_to_quaternion(S).tolist(),
        "W_quaternion": dcm_to_quaternion(W).tolist()}}]}
    path = folder / "alignment.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_broad_rmse_equals_the_published_evaluation(trials, capsys):
    bench = _bench()
    found = []
    for name, d, raw, optical, offset, S, W, folder in trials:
        rec = load_recording(raw, open_for_processing(raw, algorithm=FILTER))
        # BROAD's evaluation of this filter output: the IMU's orientation as a body → ENU
        # quaternion against the published (aligned) truth, over the movement phase
        q_imu = dcm_to_quaternion(ENU_TO_NED.T @ rec.R[:, 0])
        broad = bench.errors(q_imu, d["quat"], d["movement"])
        # the clock offset from the data: within one sample
        res = compare(rec, read_optical(optical), folder / "map.txt")
        assert abs(res.offset_s - offset) < 1.0 / RATE
        # the metric, the resampling and the frames: BROAD's figures
        capsys.readouterr()
        code = main(["compare", str(raw), str(optical), "--map", str(folder / "map.txt"),
                     "--alignment", str(_alignment_file(folder, S, W)), "--json",
                     "--offset", str(offset), "--filter", FILTER, "--no-figures",
                     "-o", str(folder)])
        assert code == 0
        doc = json.loads(capsys.readouterr().out)
        seg = doc["segments"][0]
        print(name, "BROAD", np.round(broad, 3), "compare", seg["rmse_total"],
              seg["rmse_heading"], seg["rmse_inclination"], "offset", res.offset_s, offset)
        assert abs(seg["rmse_total"] - broad[0]) < 0.1
        assert abs(seg["rmse_heading"] - broad[1]) < 0.1
        assert abs(seg["rmse_inclination"] - broad[2]) < 0.1
        # the frames estimated from the data: near the rotations BROAD's authors applied
        al = res.alignments[0]
        dS, dW = float(angle_deg(al.S @ S.T)), float(angle_deg(al.W @ W.T))
        print(f"   estimated: S {dS:.2f}°, W {dW:.2f}° from BROAD's; RMSE "
              f"{res.segments[0].rmse_total:.3f}")
        found.append((dS, dW, abs(res.segments[0].rmse_total - broad[0])))
    print(found)
    assert max(f[0] for f in found) < S_MAX_DEG
    assert max(f[1] for f in found) < W_MAX_DEG
    assert max(f[2] for f in found) < RMSE_ESTIMATED_MAX_DEG


#: Measured on these trials (the movement phase, 50 Hz, adaptive filter): the estimated
#: IMU-to-cluster rotation is 0.16-0.27° from the one BROAD's authors applied, the world
#: rotation 0.4-2.2° (its heading comes from the magnetometer over the movement alone; BROAD's
#: alignment used the whole trial at 286 Hz, the accelerometer with the markers' accelerations
#: and a gyro bias, appendix C), and the RMSE is 0.3-1.2° lower than BROAD's (a world heading
#: taken from the same magnetometer as the filter's removes the field's constant part of the
#: filter's heading error). docs/compare.md reports the figures.
S_MAX_DEG = 0.5
W_MAX_DEG = 2.5
RMSE_ESTIMATED_MAX_DEG = 1.5
