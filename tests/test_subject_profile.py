"""The subject's profile (docs/subject.md) and the whole-body centre of mass, against values
worked out by hand from the published tables (Drillis & Contini via Winter 2009, Fig. 4.1;
Dempster via Winter 2009, Table 4.1) and against the simulated subject's own lengths."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from bpms.filter.body_model import POINT_NAMES
from bpms.filter.centre_of_mass import centre_of_mass
from bpms.filter.door import process_file
from bpms.filter.pose import body_outputs
from bpms.firmware.sim.body import SKELETON, SubjectDimensions
from bpms.firmware.sim.session import simulate
from bpms.io.options import BodyOptions
from bpms.io.subject import SubjectProfile, header_subject


def test_missing_lengths_scale_with_height_from_winters_table():
    p = SubjectProfile("S01", 1.80, 75.0, {"thigh": 0.46})
    lengths = p.lengths()
    # by hand: 1.80 m × Winter's Fig. 4.1 fractions
    assert lengths["thigh"] == 0.46  # measured
    assert lengths["arm"] == pytest.approx(0.3348)  # 0.186 H
    assert lengths["forearm"] == pytest.approx(0.2628)  # 0.146 H
    assert lengths["hand"] == pytest.approx(0.1944)  # 0.108 H
    assert lengths["shank"] == pytest.approx(0.4428)  # 0.246 H
    assert lengths["foot"] == pytest.approx(0.2736)  # 0.152 H
    assert lengths["shoulder"] == pytest.approx(0.2331)  # 0.259 H / 2
    assert lengths["hip"] == pytest.approx(0.1719)  # 0.191 H / 2
    assert lengths["low_spine"] + lengths["mid_spine"] == pytest.approx(0.5184)  # 0.288 H
    assert lengths["neck"] == pytest.approx(0.0936) and lengths["head"] == pytest.approx(0.234)
    assert "thigh" not in p.scaled() and "arm" in p.scaled()
    assert p.body_options().thigh == 0.46 and p.body_options().height == 1.80


def test_profile_text_file_and_header_round_trip(tmp_path):
    p = SubjectProfile.parse("id=S02, height=1.65, mass=58.5, forearm=0.25")
    assert (p.subject_id, p.height, p.mass, p.segments) == ("S02", 1.65, 58.5, {"forearm": 0.25})
    f = tmp_path / "s.toml"
    f.write_text('[subject]\nid = "S03"\nheight = 1.9\nthigh = 0.5\n', encoding="utf-8")
    q = SubjectProfile.parse(str(f))
    assert q.subject_id == "S03" and q.mass is None and q.segments == {"thigh": 0.5}
    assert header_subject({"subject": p.to_header()}) == (p, None)
    assert header_subject({}) == (None, None)
    profile, problem = header_subject({"subject": {"id": "x"}})
    assert profile is None and "height_m" in problem


@pytest.mark.parametrize(("text", "words"), [
    ("height=1.8", "id is needed"), ("id=a,height=3.1", "height"),
    ("id=a,height=1.8,mass=-2", "mass"), ("id=a,height=1.8,tibia=0.4", "unknown segment"),
    ("id=a,height=1.8,thigh", "KEY=VALUE"), ("id=a,height=tall", "could not convert"),
])
def test_bad_profiles_say_what_is_wrong(text, words):
    with pytest.raises(ValueError, match=words):
        SubjectProfile.parse(text)


def test_the_door_uses_the_headers_profile(tmp_path):
    """A recording of a subject 1.90 m tall with a 0.50 m thigh: with the profile in its
    header, the product's skeleton has the simulated subject's lengths; without, it has not."""
    dims = SubjectDimensions.of_height(1.90, thigh=0.50)
    rec = simulate(seed=1, duration_s=3.0, subject=dims)
    with_profile = process_file(rec.save_raw(tmp_path / "a.raw", subject_id="sim"))
    plain = process_file(rec.save_raw(tmp_path / "b.raw"))
    assert "with subject sim" in with_profile.options_source
    index = {n: i for i, n in enumerate(POINT_NAMES)}
    for name, parent, _, _, length in SKELETON:
        got = np.linalg.norm(with_profile.joint_positions[-1, index[name]]
                             - with_profile.joint_positions[-1, index[parent]])
        assert got == pytest.approx(getattr(dims, length), abs=1e-9), name
    knee = plain.joint_positions[-1, index["knee_r"]]
    hip = plain.joint_positions[-1, index["hip_r"]]
    assert np.linalg.norm(knee - hip) == pytest.approx(0.43)  # the options' length


def test_centre_of_mass_standing_by_hand():
    """The neutral pose with Table 2.4's lengths, worked out by hand (z up negative, NED):
    hand 0.012 × 0.22614, forearm 0.032 × -0.0239, upper arm 0.056 × -0.33176, foot
    0.029 × 0.83, leg 0.093 × 0.6032, thigh 0.2 × 0.18619, head and neck 0.081 × -0.68,
    trunk 0.497 × -0.24 (metres below the hips) → -0.0735841 m; the feet stand 0.83 m below
    the hips, so the centre is 0.9035841 m above the ground, 52 % of 1.73 m. Forward: the
    feet's 0.029 × 0.135 m."""
    C = np.tile(np.eye(3), (1, 18, 1, 1))
    _, points = body_outputs(C, BodyOptions())
    com = centre_of_mass(points)[0]
    pelvis = points[0, POINT_NAMES.index("pelvis")]
    assert com[2] == pytest.approx(-0.9035841, abs=1e-7)
    assert com[2] - pelvis[2] == pytest.approx(-0.0735841, abs=1e-7)
    assert com[0] - pelvis[0] == pytest.approx(0.003915, abs=1e-9)
    assert com[1] - pelvis[1] == pytest.approx(0.0, abs=1e-12)


def test_centre_of_mass_follows_the_simulated_subject():
    """The centre from the simulator's own joint positions and from the product's (filtered)
    agree within 2 cm while the subject moves."""
    rec = simulate(seed=2, duration_s=20.0)
    from bpms.filter.processor import BodyPoseProcessor

    res = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    order = [rec.truth.point_names.index(n) for n in POINT_NAMES]
    truth = rec.truth.joint_positions[:, order]
    k = rec.t >= 2.0
    mine = res.centre_of_mass[k] - res.joint_positions[k, 0]
    true = centre_of_mass(truth[k]) - truth[k, 0]
    assert np.sqrt(np.mean(np.sum((mine - true) ** 2, axis=-1))) < 0.02


def test_record_refuses_a_bad_subject_in_one_line():
    run = subprocess.run([sys.executable, "-m", "bpms", "record", "--sim", "--subject",
                          "height=1.8"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "id is needed" in run.stderr
    assert "Traceback" not in run.stderr


def test_a_profile_text_longer_than_a_file_name_is_read_as_text():
    """Every length given (≈ 300 characters): no file name the system takes, read as text
    (it raised OSError 'File name too long' from the file test, a traceback in bpms record)."""
    dims = SubjectDimensions.of_height(1.90)
    text = ",".join(["id=S9", "height=1.9", *(f"{k}={v!r}" for k, v in dims.lengths().items())])
    assert len(text) > 255
    assert SubjectProfile.parse(text).lengths() == pytest.approx(dims.lengths())
