"""BVH root translation follows the walked path (the simulated walk's true pelvis travel)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from bpms.analysis.bvh import NED_TO_BVH
from bpms.firmware.sim.motion import Still, Walk
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate

ROOT = Path(__file__).resolve().parents[1]


def test_bvh_root_moves_with_the_walk(tmp_path):
    script = [Still("still", 3.0), Walk(steps=8), Still("still (end)", 2.0)]
    rec = simulate(seed=4, script=script, model=SensorModel(mounting_error_deg=0.0))
    raw = rec.save_raw(tmp_path / "Raw_walk_001.bpmsraw")
    out = subprocess.run([sys.executable, "-m", "bpms", "export", "bvh", str(raw), "-o",
                          str(tmp_path / "walk.bvh")], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    lines = (tmp_path / "walk.bvh").read_text().splitlines()
    motion = lines[lines.index("MOTION") + 3:]
    root = np.array([[float(v) for v in row.split()[:3]] for row in (motion[0], motion[-1])])
    moved_bvh = (root[1] - root[0]) / 100.0  # cm -> m, BVH axes (y up)
    truth_ned = rec.truth.pelvis_position[-1] - rec.truth.pelvis_position[0]
    truth_bvh = NED_TO_BVH @ truth_ned
    assert np.linalg.norm(truth_ned[:2]) > 2.0  # the walk really goes somewhere
    horiz = [0, 2]
    a, b = moved_bvh[horiz], truth_bvh[horiz]
    angle = np.degrees(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b)))
    assert angle < 10.0, (moved_bvh, truth_bvh)  # walks the right way
    # as far as the heel-strike dead reckoning reaches (it measures each step from the
    # estimated leg angles; on this walk it finds every strike but reads steps ~35 % short)
    assert 0.5 < np.linalg.norm(a) / np.linalg.norm(b) < 1.2, (moved_bvh, truth_bvh)
    assert abs(moved_bvh[1]) < 0.05  # the height stays the body model's
