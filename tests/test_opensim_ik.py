"""OpenSense end to end (tools/opensim_ik.py): ``bpms export opensim`` of a simulated trial,
OpenSim's IMU placer and IMU inverse kinematics; the joint coordinates OpenSim finds agree with
the script's true angles. Skipped, saying so, where OpenSim's Python package is missing."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bpms.firmware.sim.motion import Move, Still
from bpms.firmware.sim.session import simulate

pytest.importorskip("opensim", reason="OpenSim is not installed (pip install opensim, on "
                                      "Linux and Windows; conda on macOS)")

ROOT = Path(__file__).resolve().parents[1]
#: The scripted truth (degrees): the simulated subject raises the right arm 60°, bends both
#: elbows 100°, then squats (hips 55°, knees 70°, ankles 30°, arms forward 45°).
SQUAT = {"pelvis_tilt": -15, "torso_flex": -10, "hip_r_flex": 55, "hip_l_flex": 55,
         "knee_r": 70, "knee_l": 70, "ankle_r": 30, "ankle_l": 30, "sh_r_flex": 45,
         "sh_l_flex": 45}
SCRIPT = [Still("still", 2.0), Move("right arm forward raise", 1.5, {"sh_r_flex": 60}, hold=0.5),
          Move("arm down", 1.5, hold=0.3),
          Move("elbows", 1.2, {"elbow_r": 100, "elbow_l": 100}, hold=0.3),
          Move("elbows extended", 1.2, hold=0.2), Move("squat", 2.0, SQUAT, hold=0.5),
          Move("up", 2.0, hold=0.5), Still("still", 1.0)]
TRUTH = {"arm_flex_r": 60, "arm_flex_l": 45, "elbow_flex_r": 100, "elbow_flex_l": 100,
         "hip_flexion_r": 55, "hip_flexion_l": 55, "knee_angle_r": 70, "knee_angle_l": 70,
         "ankle_angle_r": 30}


def test_opensense_placer_and_ik_recover_the_scripted_angles(tmp_path):
    raw = simulate(seed=3, script=SCRIPT).save_raw(tmp_path / "Raw_opensim.bpmsraw")
    done = subprocess.run([sys.executable, "-m", "bpms", "export", "opensim", str(raw), "-o",
                           str(tmp_path / "trial")], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "opensim_ik.py"),
                           str(tmp_path / "trial_orientations.sto"),
                           str(tmp_path / "trial_calibration.sto"), "-o", str(tmp_path / "ik")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr + done.stdout
    sys.path.insert(0, str(ROOT / "tools"))
    from opensim_ik import read_motion

    columns = read_motion(tmp_path / "ik" / "ik_trial_orientations.mot")
    assert len(columns["time"]) == 735
    for name, degrees in TRUTH.items():
        assert max(columns[name]) == pytest.approx(degrees, abs=3.0), name
    # still at the start: every joint near zero (the calibration pose)
    for name in TRUTH:
        assert abs(columns[name][25]) < 3.0, name
