"""``bpms export opensim`` writes the joint angles as an OpenSim ``.mot`` (issue 49.2): read
through OpenSim's own ``TimeSeriesTable``, with the Rajagopal 2016 model's coordinate names and
OpenSim's signs, every frame kept; the values are the simulated script's true angles. Skipped,
saying so, where OpenSim's Python package is missing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bpms.cli import main
from bpms.firmware.sim.motion import Move, Still
from bpms.firmware.sim.session import simulate

osim = pytest.importorskip("opensim", reason="OpenSim is not installed (pip install opensim, "
                                             "on Linux and Windows; conda on macOS)")

#: The script (degrees, the simulator's own degrees of freedom, its right abduction negative):
#: an arm raised forward, both elbows bent, a sideways raise of both arms, a squat.
SCRIPT = [Still("still", 2.0), Move("right arm forward raise", 1.5, {"sh_r_flex": 60}, hold=0.5),
          Move("down", 1.2, hold=0.3),
          Move("elbows", 1.2, {"elbow_r": 100, "elbow_l": 100}, hold=0.3),
          Move("down", 1.2, hold=0.3),
          Move("sideways", 1.5, {"sh_r_abd": -80, "sh_l_abd": 80}, hold=0.3),
          Move("down", 1.5, hold=0.3),
          Move("squat", 2.0, {"hip_r_flex": 55, "hip_l_flex": 55, "knee_r": 70, "knee_l": 70},
               hold=0.5),
          Move("up", 2.0, hold=0.5), Still("still", 1.0)]
#: OpenSim coordinate → its extreme in the script, degrees, written from OpenSim's own sign
#: rules (Rajagopal 2016: flexion and knee flexion positive, adduction positive, so a
#: sideways raise is negative arm_add).
EXTREMES = {"arm_flex_r": 60, "elbow_flex_r": 100, "elbow_flex_l": 100, "arm_add_r": -80,
            "arm_add_l": -80, "hip_flexion_r": 55, "hip_flexion_l": 55, "knee_angle_r": 70,
            "knee_angle_l": 70}


def test_the_mot_reads_in_opensim_with_the_scripted_angles(tmp_path: Path):
    rec = simulate(seed=3, script=SCRIPT)
    raw = rec.save_raw(tmp_path / "Raw_mot.bpmsraw")
    assert main(["export", "opensim", str(raw), "-o", str(tmp_path / "trial")]) == 0
    table = osim.TimeSeriesTable(str(tmp_path / "trial_joint_angles.mot"))
    labels = list(table.getColumnLabels())
    assert table.getNumRows() == len(rec.t)  # every frame, none dropped
    assert table.getTableMetaDataAsString("inDegrees") == "yes"
    assert "Rajagopal" in table.getTableMetaDataAsString("model")
    assert {"hip_adduction_r", "hip_rotation_l", "lumbar_extension", "ankle_angle_r"} <= set(
        labels)
    for name, degrees in EXTREMES.items():
        col = table.getDependentColumn(name).to_numpy()
        extreme = np.nanmax(col) if degrees > 0 else np.nanmin(col)
        assert extreme == pytest.approx(degrees, abs=6.0), name
        assert abs(np.nanmedian(col[60:95])) < 3.0, name  # standing still: near zero
