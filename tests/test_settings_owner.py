"""Settings with one owner (issue 12.3): one valid-range table, refused at the API with the
range named, replaced by the factory value in files; per-filter values kept when switching
filter and back; changes through one queue; [body] height honoured."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from waiting import wait_until

from bpms.filter.algorithms import make_bank
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.options import (
    ALGORITHM_SETTINGS,
    VALID_RANGES,
    FilterOptions,
    OptionRangeError,
    Options,
    load_options,
    options_from_dict,
)
from bpms.io.rawfile import read_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession


@pytest.fixture(scope="module")
def rec():
    return simulate(duration_s=8.0, seed=2)


def test_every_numeric_and_choice_option_has_a_range():
    for name, section in Options().sections().items():
        for f in dataclasses.fields(section):
            value = getattr(section, f.name)
            if isinstance(value, bool | list):
                continue
            if isinstance(value, int | float) or f.name in ("algorithm", "angle_unit"):
                assert f.name in VALID_RANGES.get(name, {}), f"{name}.{f.name} has no range"
    # and the factory values lie inside their ranges
    for name, keys in VALID_RANGES.items():
        section = getattr(Options(), name)
        for key, rng in keys.items():
            value = getattr(section, key)
            if rng.choices is not None:
                assert value in rng.choices
            else:
                assert (rng.lo is None or value >= rng.lo) and (rng.hi is None or value <= rng.hi)


def test_api_refuses_out_of_range_gains_naming_the_range():
    proc = BodyPoseProcessor()
    with pytest.raises(OptionRangeError, match=r"kp_rollpitch.*2\.0.*\[0, 0\.18\]"):
        proc.set_gains(kp_rollpitch=2.0)
    assert isinstance(OptionRangeError("x"), ValueError)
    assert proc.options.filter.kp_rollpitch == 0.02  # nothing changed
    with pytest.raises(OptionRangeError, match=r"\[0, 50\]"):
        proc.set_gains(observer_k_incl=80.0)
    with pytest.raises(ValueError, match="mahony, observer, vqf"):
        proc.select_filter("kalman")
    assert proc.options.filter.algorithm == "mahony"


def test_the_recorded_settings_in_force_apply_on_replay_text_options_included():
    """A live session records every filter setting in force when logging starts, text ones
    ('failed_sensor', 'heading') among the numbers: replay applies them all, not one refused
    (a gain the operator had changed before starting then holds on replay too)."""
    from bpms.io.session_events import SessionEvent

    values = {k: v for k, v in dataclasses.asdict(FilterOptions()).items() if k != "algorithm"}
    values["kp_rollpitch"] = 0.05  # changed by the operator before logging started
    proc = BodyPoseProcessor()
    assert proc.apply_event(SessionEvent("gains", data={"values": values,
                                                        "source": "in force"}))
    assert proc.problems == []
    assert proc.options.filter.kp_rollpitch == 0.05
    assert proc.options.filter.heading == "magnetic"
    # an unreadable value is one problem line, nothing changed, no exception
    bad = SessionEvent("gains", data={"values": {"kp_rollpitch": "fast"}})
    assert not proc.apply_event(bad)
    assert len(proc.problems) == 1 and "kp_rollpitch" in proc.problems[0]
    assert proc.options.filter.kp_rollpitch == 0.05


def test_live_session_refuses_in_the_callers_thread(rec, tmp_path):
    path = rec.save_raw(tmp_path / "Raw_refuse_1.bpmsraw")
    session = LiveSession(ReplaySource(read_raw(path), speed=None))
    with pytest.raises(OptionRangeError, match=r"\[0, 0\.18\]"):
        session.set_gains(kp_rollpitch=2.0)
    with pytest.raises(OptionRangeError, match="one of mahony, observer, vqf"):
        session.select_filter("kalman")


def test_file_values_outside_are_replaced_by_factory_with_a_warning(tmp_path):
    path = tmp_path / "options.toml"
    path.write_text("[filter]\nkp_rollpitch = 2.0\nkp_yaw = 3.0\nvqf_tau_acc_s = 0.0\n")
    options = load_options(path)
    assert options.filter.kp_rollpitch == FilterOptions().kp_rollpitch  # factory
    assert options.filter.vqf_tau_acc_s == FilterOptions().vqf_tau_acc_s
    assert options.filter.kp_yaw == 3.0  # the good value is kept
    text = [str(p) for p in options.problems]
    assert len(text) == 2
    assert any("filter.kp_rollpitch" in t and "[0, 0.18]" in t and "factory value 0.02" in t
               and "\n" not in t for t in text)


def test_the_kp_bound_is_where_the_filter_stops_converging(rec):
    # The documented bound: the roll/pitch error shrinks by 1 - kp*Gravity*dt per step, so
    # beyond 2/(Gravity*dt) ≈ 0.37 the correction overshoots more than it corrects and the
    # filters diverge (caught by the state guard), while the top of the range stays calm.
    def events(kp: float) -> int:
        proc = BodyPoseProcessor()
        proc.bank.set_gains(kp_rollpitch=kp)  # straight into the bank, past the check
        return int(proc.process(rec.raw, rec.errors).reinit_count.sum())

    assert events(VALID_RANGES["filter"]["kp_rollpitch"].hi) == 0
    assert events(0.5) > 0
    assert events(2.0) > 0


def test_switching_filter_and_back_keeps_each_filters_values(rec):
    raw, errors = rec.raw, rec.errors
    proc = BodyPoseProcessor()
    proc.process(raw[:100], errors[:100])
    proc.set_gains(kp_yaw=2.5, ki_rollpitch=0.0001)
    proc.select_filter("observer")
    proc.set_gains(observer_k_incl=1.5)
    proc.process(raw[100:200], errors[100:200])
    proc.select_filter("mahony")
    assert proc.options.filter.kp_yaw == 2.5 and proc.options.filter.ki_rollpitch == 0.0001
    back = proc.process(raw[200:400], errors[200:400])
    # the same as a fresh Mahony bank with the typed gains, started at frame 200
    typed = dataclasses.replace(FilterOptions(), kp_yaw=2.5, ki_rollpitch=0.0001)
    fresh = make_bank(proc.sensor_calibration.gravity, typed)
    acc, mag, gyr = proc.calibrate(raw[200:400])
    np.testing.assert_array_equal(back.euler, fresh.process(acc, mag, gyr, errors[200:400]).euler)
    proc.select_filter("observer")
    assert proc.bank.options.observer_k_incl == 1.5


def test_live_session_switch_and_back_through_the_queue(rec, tmp_path):
    path = rec.save_raw(tmp_path / "Raw_switch_1.bpmsraw")
    session = LiveSession(ReplaySource(read_raw(path), speed=None))
    session.set_gains(kp_yaw=2.5)
    session.select_filter("observer")
    session.set_gains(observer_k_head=0.7)
    session.select_filter("mahony")
    # nothing applied yet: the processing thread owns the processor
    assert session.processor.options.filter.kp_yaw == 1.2
    with session:
        assert wait_until(lambda: session.status().processed > 10, 30)
    f = session.processor.options.filter
    assert (f.algorithm, f.kp_yaw, f.observer_k_head) == ("mahony", 2.5, 0.7)
    assert session.processor.bank.params[2] == 2.5  # the bank runs with it


def test_gui_facing_options_object_is_not_written_by_the_processor():
    options = Options()
    proc = BodyPoseProcessor(options=options)
    proc.set_gains(kp_yaw=3.0)
    assert options.filter.kp_yaw == 1.2 and proc.options.filter.kp_yaw == 3.0


def test_algorithm_settings_cover_the_filter_section():
    grouped = {k for keys in ALGORITHM_SETTINGS.values() for k in keys}
    filter_keys = {f.name for f in dataclasses.fields(FilterOptions)}
    assert grouped <= filter_keys
    assert filter_keys - grouped == {"algorithm", "dt", "failed_sensor", "heading"}


def test_body_height_scales_lengths_not_given_one_by_one():
    options = options_from_dict({"body": {"height": 1.9, "arm": 0.30}})
    factory = Options().body
    assert options.body.arm == 0.30  # given one by one: kept
    assert options.body.thigh == pytest.approx(factory.thigh * 1.9 / 1.73)
    assert options.body.height == 1.9
    # and the stick figure grows with it: standing height of the model (head top to feet)
    tall = BodyPoseProcessor(options=options_from_dict({"body": {"height": 1.9}}))
    short = BodyPoseProcessor(options=options_from_dict({"body": {"height": 1.6}}))
    eye = np.tile(np.eye(3), (1, 18, 1, 1))
    from bpms.filter.pose import body_outputs

    def stature(body):
        z = body_outputs(eye, body)[1][0, :, 2]
        return z.max() - z.min()

    assert stature(tall.options.body) / stature(short.options.body) == pytest.approx(1.9 / 1.6)


def test_the_documented_range_table_is_the_code_s():
    from pathlib import Path

    from bpms.io.options import ranges_markdown

    doc = (Path(__file__).resolve().parents[1] / "docs" / "configuration.md").read_text()
    assert ranges_markdown() in doc


def _outside(rng) -> list[float]:
    """Values a file may not hold for a numeric range: beyond each bound, absurd, non-finite."""
    values = [float("nan"), float("inf"), 1e308, -1e308]
    if rng.lo is not None:
        values.append(rng.lo - max(abs(rng.lo), 1.0))
        if rng.lo > 0:
            values.append(0.0)  # e.g. a body segment of length 0
    if rng.hi is not None:
        values.append(rng.hi + max(abs(rng.hi), 1.0))
    return values


@pytest.mark.parametrize("section", sorted(VALID_RANGES))
def test_every_option_family_refuses_values_outside_its_range(section):
    """Each family (filter, sensors, display, serial, udp, logging, pose, body, track, joints,
    lsl): every value outside its range — or absurd, or non-finite — in a file gives one
    warning naming the key and the factory value, never an exception."""
    from bpms.io.options import options_from_dict

    factory = getattr(Options(), section)
    for key, rng in VALID_RANGES[section].items():
        wrong = ["no-such-choice"] if rng.choices is not None else _outside(rng)
        for value in wrong:
            if isinstance(getattr(factory, key), int) and isinstance(value, float) \
                    and math.isfinite(value) and value == int(value):
                value = int(value)
            options = options_from_dict({section: {key: value}}, "test.toml")
            assert getattr(getattr(options, section), key) == getattr(factory, key), (key, value)
            text = [str(p) for p in options.problems]
            assert len(text) == 1 and f"{section}.{key}" in text[0] and "factory" in text[0], \
                (key, value, text)
