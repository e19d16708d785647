"""Selecting the attitude filter (FilterOptions.algorithm, BodyPoseProcessor, bpms filter
--filter) on simulated-suit recordings; batch and live agree for every filter."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
from waiting import wait_until

from bpms.cli import main
from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.rotations import inclination_error
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.options import FilterOptions, Options, load_options
from bpms.io.rawfile import read_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession

ALGORITHMS = ("mahony", "observer", "vqf", "adaptive")


def _options(algorithm: str) -> Options:
    options = Options()
    options.filter.algorithm = algorithm
    return options


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    rec = simulate(duration_s=8.0, seed=5, error_rate=0.002)
    path = tmp_path_factory.mktemp("raw") / "Raw_select_001.bpmsraw"
    rec.save_raw(path)
    return rec, path


def test_the_choices_are_in_the_option_metadata():
    spec = next(f for f in dataclasses.fields(FilterOptions) if f.name == "algorithm")
    assert tuple(spec.metadata["choices"]) == ALGORITHMS
    assert FilterOptions().algorithm == "mahony"


def test_options_file_selects_the_filter_and_rejects_unknown_names(tmp_path):
    good = tmp_path / "o.toml"
    good.write_text('[filter]\nalgorithm = "observer"\nobserver_k_incl = 0.3\n')
    opts = load_options(good)
    assert opts.filter.algorithm == "observer" and opts.filter.observer_k_incl == 0.3
    assert not opts.problems
    bad = tmp_path / "b.toml"
    bad.write_text('[filter]\nalgorithm = "kalman"\n')
    opts = load_options(bad)
    assert opts.filter.algorithm == "mahony"
    assert any("kalman" in str(p) for p in opts.problems)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_each_filter_gives_the_same_outputs_downstream(recording, algorithm):
    rec, _ = recording
    result = BodyPoseProcessor(rec.calibration, _options(algorithm)).process(rec.raw, rec.errors)
    n = len(rec)
    assert result.R.shape == (n, 18, 3, 3) and result.euler.shape == (n, 18, 3)
    assert result.joint_angles.shape == (n, 28) and result.quaternions.shape == (n, 18, 4)
    assert np.isfinite(result.R).all() and np.isfinite(result.joint_angles[60:]).all()
    incl = np.degrees(inclination_error(result.R[50:], rec.truth.R[50:]))
    assert np.sqrt(np.mean(incl**2)) < 3.0
    if rec.errors.any():
        assert result.held_count.sum() > 0


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_live_step_equals_batch_with_resets(recording, algorithm):
    rec, _ = recording
    n = 150
    batch_proc = BodyPoseProcessor(rec.calibration, _options(algorithm))
    first = batch_proc.process(rec.raw[:100], rec.errors[:100])
    batch_proc.reset_filter(4)
    second = batch_proc.process(rec.raw[100:n], rec.errors[100:n])
    batch = np.concatenate([first.R, second.R])
    live_proc = BodyPoseProcessor(rec.calibration, _options(algorithm))
    live = []
    for k in range(n):
        if k == 100:
            live_proc.reset_filter(4)
        live.append(live_proc.step(rec.raw[k], rec.errors[k]).R[0])
    np.testing.assert_allclose(np.array(live), batch, atol=1e-9, equal_nan=True)


def test_select_filter_at_run_time_and_gains_by_option_name(recording):
    rec, _ = recording
    proc = BodyPoseProcessor(rec.calibration)
    proc.process(rec.raw[:50], rec.errors[:50])
    proc.select_filter("observer")
    assert proc.options.filter.algorithm == "observer"
    proc.set_gains(observer_k_incl=0.8, dt=0.02)
    out = proc.process(rec.raw[50:100], rec.errors[50:100])
    assert np.isfinite(out.R).all()
    with pytest.raises(ValueError, match="unknown attitude filter"):
        proc.select_filter("kalman")


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_bpms_filter_with_filter_option(recording, tmp_path, algorithm):
    rec, path = recording
    out = tmp_path / f"{algorithm}.csv"
    assert main(["filter", str(path), "-o", str(out), "--filter", algorithm]) == 0
    api = BodyPoseProcessor(rec.calibration, _options(algorithm)).process(rec.raw, rec.errors)
    got = read_filtered(out).euler
    np.testing.assert_allclose(got, api.euler_output, rtol=1e-8, atol=1e-9)


def test_vqf_missing_gives_one_line(recording, tmp_path):
    """Without the vqf package (its import made to fail), choosing it is a one-line error."""
    _, path = recording
    code = ("import sys; sys.modules['vqf'] = None; from bpms.cli import main; "
            f"sys.exit(main(['filter', {str(path)!r}, '-o', {str(tmp_path / 'x.csv')!r}, "
            "'--filter', 'vqf']))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "vqf package" in lines[0], proc.stderr


@pytest.mark.parametrize("algorithm", ["observer", "vqf"])
def test_live_session_runs_the_selected_filter(recording, tmp_path, algorithm):
    rec, path = recording
    raw = read_raw(path)
    session = LiveSession(ReplaySource(raw, speed=None), _options(algorithm),
                          recording_dir=tmp_path)
    sub = session.subscribe(maxlen=len(raw))
    session.start()
    try:
        assert wait_until(lambda: session.status().processed == len(raw))
    finally:
        session.stop()
    samples = sub.drain()
    live = np.array([s.R for s in samples])
    api = BodyPoseProcessor(rec.calibration, _options(algorithm)).process(rec.raw, rec.errors)
    np.testing.assert_allclose(live, api.R[[s.index for s in samples]], atol=1e-9)


def test_unknown_filter_name_is_one_line(recording, tmp_path):
    _, path = recording
    proc = subprocess.run([sys.executable, "-m", "bpms", "filter", str(path), "-o",
                           str(tmp_path / "x.csv"), "--filter", "kalman"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "unknown filter 'kalman'" in lines[0], proc.stderr
    assert not (tmp_path / "x.csv").exists()
