"""The simulated subject (docs/simulated-suit.md): its own dimensions, calibration posture,
functional movements and true joint positions, and the product's body model measured against
them (a changed default segment length in the product fails here)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from bpms.commands._shared import CliError
from bpms.commands.sim import subject_kwargs
from bpms.filter.body_model import POINT_NAMES
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.body import SKELETON, SubjectDimensions
from bpms.firmware.sim.session import simulate
from bpms.io.options import BodyOptions, Options

#: The specification's Table 2.4 (50th-percentile US male, 1.73 m), m, written out here.
TABLE_2_4 = {"low_spine": 0.21, "mid_spine": 0.27, "neck": 0.20, "head": 0.22,
             "shoulder": 0.16, "arm": 0.34, "forearm": 0.27, "hand": 0.19, "hip": 0.17,
             "thigh": 0.43, "shank": 0.40, "foot": 0.27}


def segment_distances(points: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    """Each segment's length measured between its two points ``[21, 3]``."""
    index = {n: i for i, n in enumerate(names)}
    return {f"{parent}->{name}": float(np.linalg.norm(points[index[name]] - points[index[parent]]))
            for name, parent, _, _, _ in SKELETON}


def test_sim_dimensions_are_table_2_4():
    assert SubjectDimensions().lengths() == TABLE_2_4


def test_true_joint_positions_have_the_subjects_lengths():
    dims = SubjectDimensions.of_height(1.85, thigh=0.5)
    rec = simulate(seed=1, duration_s=2.0, subject=dims)
    got = segment_distances(rec.truth.joint_positions[-1], rec.truth.point_names)
    want = {f"{parent}->{name}": getattr(dims, length)
            for name, parent, _, _, length in SKELETON}
    assert got == pytest.approx(want, abs=1e-9)
    assert dims.thigh == 0.5 and dims.shank == pytest.approx(0.40 * 1.85 / 1.73)


@pytest.mark.parametrize("height", [1.73, 1.60])
def test_product_body_model_matches_the_simulated_subject(height):
    """The product's joint positions (default options, scaled to the height) keep the simulated
    subject's segment lengths: a wrong default length in the product breaks one."""
    dims = SubjectDimensions.of_height(height)
    rec = simulate(seed=2, duration_s=2.0, subject=dims)
    options = Options()
    options.body = BodyOptions().scaled_to(height)
    res = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
    product = segment_distances(res.joint_positions[-1], POINT_NAMES)
    truth = segment_distances(rec.truth.joint_positions[-1], rec.truth.point_names)
    assert product == pytest.approx(truth, abs=1e-6)


def test_suit_posture_is_held_in_the_still_windows():
    rec = simulate(seed=1, duration_s=4.0, posture="suit")
    k = round(1.0 / 0.02)
    names = rec.truth.joint_names
    got = dict(zip(names, np.degrees(rec.truth.joint_angles[k]), strict=True))
    assert got["elbow_r.flexion"] == pytest.approx(15)
    assert got["knee_l.flexion"] == pytest.approx(15)
    assert got["shoulder_r.abduction"] == pytest.approx(20)  # ISB: abduction positive
    assert got["shoulder_l.abduction"] == pytest.approx(20)
    assert got["hip_r.flexion"] == pytest.approx(10) and got["ankle_l.flexion"] == pytest.approx(5)
    assert rec.still_windows[0][0] == 0.0 and rec.still_windows[0][1] >= 2.9
    # the feet stay on the ground: both ankles at the same height as the toes
    pts = rec.truth.joint_positions[k]
    idx = {n: i for i, n in enumerate(rec.truth.point_names)}
    assert pts[idx["ankle_r"], 2] == pytest.approx(pts[idx["toe_r"], 2], abs=1e-9)


def test_functional_prefix_and_mounting_error():
    rec = simulate(seed=1, duration_s=35.0, functional=True, mounting_error_deg=15.0)
    names = [p[2] for p in rec.phases]
    assert names[0] == "still (calibration posture)"
    assert "knee r flexion 1" in names and "elbow l flexion 2" in names
    assert "functional steps" in names
    tilt = np.degrees(np.arccos(np.clip((np.trace(rec.truth.E, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    # three axes of 15° rms each: a rotation of about 15 × √3 ≈ 26° rms
    assert 15.0 < np.sqrt(np.mean(tilt ** 2)) < 40.0
    assert rec.model.mounting_error_deg == 15.0


def test_sim_cli_subject_options():
    args = argparse.Namespace(calibration_posture="suit", segment=["thigh=0.45"], height=1.8,
                              mounting_error=10.0, functional=True)
    kw = subject_kwargs(args)
    assert kw["posture"]["knee_r"] == 15.0 and kw["subject"].thigh == 0.45
    assert kw["subject"].arm == pytest.approx(0.34 * 1.8 / 1.73)
    for bad in ({"calibration_posture": "slouch"}, {"segment": ["tibia=0.4"]},
                {"mounting_error": 90.0}, {"height": 4.0}):
        with pytest.raises(CliError):
            subject_kwargs(argparse.Namespace(**{**vars(args), **bad}))
