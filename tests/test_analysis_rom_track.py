"""``bpms rom`` and ``bpms track`` on the simulated suit's scripted motion and walk."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.analysis.track import FOOT_IMUS, walked_path
from bpms.cli import main
from bpms.filter.body_model import joint_positions
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate

WALK_START_S = 56.7  # "turn to walk" starts here; the walk itself 59.2–69.1 s


@pytest.fixture(scope="module")
def script(tmp_path_factory):
    # no mounting misalignment: with it the filter itself shows 4–7° cross-talk on some
    # abduction/rotation angles (docs/analysis.md), which is not the report's doing
    # ±16 g: heel strikes (2.5 g) must not be clipped for the detector's 2 g threshold; at the
    # firmware's ±2 g the accelerometer saturates below it.
    rec = simulate(seed=1, model=SensorModel(mounting_error_deg=0.0, accel_range_g=16.0))
    folder = tmp_path_factory.mktemp("script")
    path = folder / "Raw_script_001.bpmsraw"
    rec.save_raw(path)
    return rec, path


def read_rom_csv(path):
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    cols = lines[0].split(",")
    names = [ln.split(",")[0] for ln in lines[1:]]
    values = np.array([[float(c) for c in ln.split(",")[1:]] for ln in lines[1:]])
    return cols, names, values


def test_rom_matches_the_truth_extremes_within_3deg(script, tmp_path, capsys):
    rec, path = script
    out = tmp_path / "report"
    assert main(["rom", str(path), "--from", "0", "--to", str(WALK_START_S),
                 "-o", str(out)]) == 0
    cols, names, values = read_rom_csv(out / "rom.csv")
    assert names == ["joint_" + n.replace(".", "_") for n in JOINT_ANGLE_NAMES]
    assert cols[1:] == ["Raw_script_001_min_deg", "Raw_script_001_max_deg",
                        "Raw_script_001_range_deg"]
    window = rec.t <= WALK_START_S
    truth = np.degrees(rec.truth.joint_angles[window])
    assert (truth.max(0) - truth.min(0) > 10.0).sum() >= 16  # the script exercises them
    np.testing.assert_allclose(values[:, 0], truth.min(0), atol=3.0)
    np.testing.assert_allclose(values[:, 1], truth.max(0), atol=3.0)
    np.testing.assert_allclose(values[:, 2], values[:, 1] - values[:, 0], atol=0.011)
    md = (out / "rom.md").read_text()
    assert md == capsys.readouterr().out
    assert "| joint_knee_r_flexion |" in md and "min / max / range, deg" in md
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == [f"rom_{g}.png" for g in
                    ("ankle", "elbow", "head", "hip", "knee", "shoulder", "torso")]
    assert all((out / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def test_rom_compares_files_side_by_side_and_rezeroes(script, tmp_path):
    _, path = script
    out = tmp_path / "cmp"
    assert main(["rom", str(path), str(path), "--label", "unsuited", "--label", "suited",
                 "--from", "3", "--to", "30", "--reset-at", "72", "-o", str(out),
                 "--no-figures"]) == 0
    cols, _, values = read_rom_csv(out / "rom.csv")
    assert cols[1] == "unsuited_min_deg" and cols[4] == "suited_min_deg"
    np.testing.assert_array_equal(values[:, :3], values[:, 3:])
    assert main(["rom", str(path), "--from", "80", "--to", "90", "-o", str(out)]) == 2
    assert main(["rom", str(path), "--from", "9", "--to", "3", "-o", str(out)]) == 2


def test_heel_strikes_match_the_truth(script, tmp_path):
    rec, path = script
    out = tmp_path / "walk.csv"
    assert main(["track", str(path), "-o", str(out), "--declination", "10"]) == 0
    lines = out.read_text().splitlines()
    assert lines[0].startswith("step,time_s,side,peak_g,step_north_m")
    rows = [ln.split(",") for ln in lines[1:]]
    truth = rec.truth.heel_strikes
    assert len(rows) == len(truth)
    for row, (t, side) in zip(rows, truth, strict=True):
        assert abs(float(row[1]) - t) <= 0.021 and row[2] == side
        assert float(row[3]) > 2.0
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    # the declination turns the straight-north walk 10° east
    north, east = float(rows[-1][7]), float(rows[-1][8])
    assert np.degrees(np.arctan2(east, north)) == pytest.approx(10.0, abs=2.0)


def test_path_length_from_the_lower_body_chain_within_10_percent(script):
    """The dead-reckoning method on the walk's true segment orientations gives the pelvis
    displacement within 10 %; on the filtered orientations see docs/analysis.md (the filter
    underestimates the leg angles at heel strike)."""
    rec, _ = script
    acc = {side: np.linalg.norm(rec.truth.imu_acceleration[:, i] - [0, 0, 9.81], axis=-1)
           / 9.81 for side, i in FOOT_IMUS.items()}
    track = walked_path(rec.t, acc, joint_positions(rec.truth.C), 2.0, 0.4)
    t0, t1 = rec.truth.heel_strikes[0][0] - 0.5, rec.t[-1]
    p = rec.truth.pelvis_position
    walked = np.linalg.norm(p[rec.t.searchsorted(t1) - 1, :2] - p[rec.t.searchsorted(t0), :2])
    assert len(track.times) == len(rec.truth.heel_strikes)
    assert track.length_m == pytest.approx(walked, rel=0.10)


def test_track_with_a_walking_filter_within_10_percent_of_the_true_path(tmp_path):
    """The whole command on the simulated walk (mounting errors on) with the observer filter
    (the original filter's accelerometer trust tilts the swinging legs: docs/analysis.md)."""
    rec = simulate(seed=1, model=SensorModel(accel_range_g=16.0))  # heel strikes unclipped
    path = tmp_path / "Raw_walk_001.bpmsraw"
    rec.save_raw(path)
    out = tmp_path / "walk.csv"
    assert main(["track", str(path), "--filter", "observer", "-o", str(out), "--no-figure"]) == 0
    rows = [ln.split(",") for ln in out.read_text().splitlines()[1:]]
    steps = np.array([[float(r[4]), float(r[5])] for r in rows])
    length = np.linalg.norm(steps, axis=1).sum()
    t0 = rec.truth.heel_strikes[0][0] - 0.5
    p = rec.truth.pelvis_position
    walked = np.linalg.norm(p[-1, :2] - p[rec.t.searchsorted(t0), :2])
    assert len(rows) == len(rec.truth.heel_strikes)
    assert length == pytest.approx(walked, rel=0.10)


def test_rom_with_mounting_errors_within_3deg_using_vqf_and_the_mean_heading(tmp_path):
    """With the simulator's default 3° IMU mounting misalignment, the hip IMU's mounting yaw
    rotates every joint frame under SPEC §6's hip heading (4–7° cross-talk, docs/analysis.md);
    the mean heading of all IMUs and a filter that handles body acceleration keep every
    joint angle's extremes within 3°."""
    rec = simulate(seed=2)  # the seed with the largest hip-heading cross-talk
    path = tmp_path / "Raw_mounted_001.bpmsraw"
    rec.save_raw(path)
    out = tmp_path / "report"
    assert main(["rom", str(path), "--from", "0", "--to", str(WALK_START_S), "-o", str(out),
                 "--filter", "vqf", "--heading", "mean", "--no-figures"]) == 0
    _, names, values = read_rom_csv(out / "rom.csv")
    assert names == ["joint_" + n.replace(".", "_") for n in JOINT_ANGLE_NAMES]
    truth = np.degrees(rec.truth.joint_angles[rec.t <= WALK_START_S])
    np.testing.assert_allclose(values[:, 0], truth.min(0), atol=3.0)
    np.testing.assert_allclose(values[:, 1], truth.max(0), atol=3.0)
