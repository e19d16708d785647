"""The filtered file carries the state guard's re-initialisation flags, the disturbance
indicators and (``--estimates``) the filters' gyro-bias / body-acceleration estimates, written
by ``bpms filter`` and the live session through the same helpers and read back by the one
reader (issues 12.4, 19.2, 19.4)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bpms.cli import main
from bpms.filter.joints import CONVENTION_TEXT
from bpms.firmware.sim.motion import generate_motion
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import default_disturbance, simulate
from bpms.io.filtered_file.reader import read_filtered

#: the feet and shanks, where the simulated magnet's field stays under 4 % of the earth's (the
#: thighs and the hip, beside the hanging right hand, see it turn the field by more than 5 %
#: of the earth's: they are flagged, rightly)
FAR_FROM_IT = [1, 2, 13, 14]
BIAS_DPS = 3.0


@pytest.fixture(scope="module")
def magnet_raw(tmp_path_factory):
    """A simulated suit with a magnet beside the right forearm (IMU 5, 2.5× the default
    strength)."""
    magnet = dataclasses.replace(default_disturbance(generate_motion(1500)), strength=150.0)
    rec = simulate(30.0, seed=3, mag_disturbance=True, disturbances=[magnet])
    path = tmp_path_factory.mktemp("raw") / "Raw_magnet.bpmsraw"
    rec.save_raw(path)
    return rec, magnet, path


@pytest.fixture(scope="module")
def bias_raw(tmp_path_factory):
    """A simulated suit with a residual gyro bias of 3 °/s on every IMU."""
    rec = simulate(20.0, seed=2, model=SensorModel(gyro_bias_dps=BIAS_DPS))
    path = tmp_path_factory.mktemp("raw") / "Raw_bias.bpmsraw"
    rec.save_raw(path)
    return rec, path


def test_bpms_filter_writes_disturbance_and_reinit_flags(magnet_raw, tmp_path):
    rec, magnet, raw = magnet_raw
    out = tmp_path / "f.csv"
    assert main(["filter", str(raw), "-o", str(out), "--filter", "observer"]) == 0
    data = read_filtered(out)
    for g in ("reinitialised", "mag_disturbed", "acc_disturbed"):
        assert g in data.info.groups and data.groups[g].shape == (len(rec), 18)
    assert not data.extra  # every column belongs to a group the reader knows
    t = data.t
    mag = data.groups["mag_disturbed"] == 1
    window = (t > magnet.t0 + 1.0) & (t < magnet.t1 - 1.0)
    assert mag[window, 5].mean() > 0.5  # the magnet is beside the right forearm
    assert not mag[t < magnet.t0 - 1.0].any()  # before it comes: all quiet
    assert not mag[:, FAR_FROM_IT].any()  # far from it
    assert set(np.unique(data.groups["reinitialised"])) <= {0.0, 1.0}
    # the joint-angle convention is stated in the header
    assert CONVENTION_TEXT["isb"] in data.info.meta["convention"]
    assert "gyro_bias" not in data.info.groups  # estimates only on request
    # --no-flags leaves them out
    out2 = tmp_path / "g.csv"
    assert main(["filter", str(raw), "-o", str(out2), "--no-flags"]) == 0
    assert read_filtered(out2).info.groups == ["euler", "euler_sensor", "corrected"]


def test_bpms_filter_estimates_give_the_gyro_bias(bias_raw, tmp_path):
    rec, raw = bias_raw
    out = tmp_path / "e.csv"
    assert main(["filter", str(raw), "-o", str(out), "--filter", "observer", "--estimates",
                 "--degrees"]) == 0
    data = read_filtered(out)
    bias = data.groups["gyro_bias"]
    assert bias.shape == (len(rec), 18, 3) and data.groups["body_acc"].shape == bias.shape
    # rad/s and m/s² whatever the angle unit: the same numbers as the processor gives
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.io.options import Options

    options = Options()
    options.filter.algorithm = "observer"
    api = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
    np.testing.assert_allclose(bias, api.gyro_bias, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(data.groups["body_acc"], api.body_acc, rtol=1e-9, atol=1e-9)
    # the estimate moves towards the simulated 3 °/s bias (it converges slowly)
    norm = np.degrees(np.linalg.norm(bias[-50:].mean(axis=0), axis=1))
    assert 0.5 < np.median(norm) < 1.5 * BIAS_DPS


def test_a_reinitialisation_is_flagged_in_the_file(tmp_path):
    """A frame whose quaternion state is broken (NaN gyro reading passed through as data) is
    re-initialised by the state guard; the file's flag marks exactly the frames the result
    marks."""
    from bpms.filter.door import filtered_arrays, filtered_layout
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.io.filtered_file.writer import FilteredWriter

    rec = simulate(4.0, seed=5)
    proc = BodyPoseProcessor(rec.calibration)
    res = proc.process(rec.raw, rec.errors)
    flags = np.zeros((len(rec), 18), dtype=bool)
    flags[[10, 60], [3, 7]] = True  # hand-set: the writer must put them where they are
    res.reinitialised = flags
    groups, kind = filtered_layout(res, joints=False)
    with FilteredWriter(tmp_path / "r.csv", groups=groups, euler=kind) as w:
        w.write_block(res.t, **filtered_arrays(res, groups))
    back = read_filtered(tmp_path / "r.csv").groups["reinitialised"]
    np.testing.assert_array_equal(back == 1, flags)


def test_live_recording_writes_the_same_groups(magnet_raw, tmp_path):
    """The live session's filtered recording (replay at full speed) carries the same flag
    groups, equal to the batch filter's, and states the convention."""
    from waiting import wait_until

    from bpms.filter.processor import BodyPoseProcessor
    from bpms.io.options import Options
    from bpms.io.rawfile import read_raw
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    rec, _, raw = magnet_raw
    options = Options()
    options.filter.algorithm = "observer"
    recording = read_raw(raw)
    session = LiveSession(ReplaySource(recording, speed=None), options,
                          BodyPoseProcessor(rec.calibration, options), recording_dir=tmp_path)
    status = session.start_logging(raw=False, filtered=True, name="live")
    session.start()
    assert wait_until(lambda: session.status().processed == len(recording), 120)
    session.stop()
    data = read_filtered(status.filtered_path)
    assert not data.hole.any()
    batch = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
    np.testing.assert_array_equal(data.groups["mag_disturbed"] == 1, batch.disturbance.mag)
    np.testing.assert_array_equal(data.groups["acc_disturbed"] == 1, batch.disturbance.acc)
    np.testing.assert_array_equal(data.groups["reinitialised"] == 1, batch.reinitialised)
    assert data.groups["mag_disturbed"][:, 5].any()  # the magnet is seen live too
    assert CONVENTION_TEXT["isb"] in data.info.meta["convention"]


def test_batch_filtered_output_has_the_same_groups(magnet_raw, tmp_path):
    """``bpms batch --outputs filter`` writes its filtered files through the same helpers."""
    from bpms.analysis.batch import Job, process_one

    rec, _, raw = magnet_raw
    outcome = process_one(Job(str(raw), "S01", "magnet"), str(tmp_path), ("filter",))
    assert outcome.error is None, outcome.error
    data = read_filtered(tmp_path / "S01" / "magnet_filtered.csv")
    assert {"reinitialised", "mag_disturbed", "acc_disturbed"} <= set(data.info.groups)
    assert data.unit == "deg" and len(data.t) == len(rec)
    assert CONVENTION_TEXT["isb"] in data.info.meta["convention"]
