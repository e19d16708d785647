"""bench/broad.py on one BROAD trial at reduced length: the table's shape, finite errors."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "broad"
TRIAL = "02_undisturbed_slow_rotation_B"

pytestmark = pytest.mark.skipif(
    not (DATA / f"{TRIAL}.hdf5").is_file(),
    reason=f"BROAD data not found at {DATA} (../shared/data/broad from the repository root)")


def _bench():
    spec = importlib.util.spec_from_file_location("bench_broad", REPO / "bench" / "broad.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_broad_bench_on_one_trial(capsys):
    bench = _bench()
    # movement starts 40 s into this trial: 50 s give 10 s of scored motion
    rows = bench.evaluate(DATA, trials=[TRIAL], max_s=50.0)
    assert [(r.filter, round(r.rate)) for r in rows] == [
        (f, rate) for rate in (286, 50) for f in ("mahony", "observer", "vqf")]
    errs = np.array([[r.total, r.heading, r.inclination] for r in rows])
    assert np.isfinite(errs).all() and (errs >= 0).all()
    assert (errs[:, 0] >= errs[:, 1] - 1e-9).all() and (errs[:, 0] >= errs[:, 2] - 1e-9).all()
    assert errs[:, 0].max() < 30.0  # degrees: a frame or unit mistake would show here

    assert bench.main(["--data", str(DATA), "--trials", TRIAL, "--max-s", "50"]) == 0
    out = capsys.readouterr().out
    table = [line for line in out.splitlines() if line.startswith(f"| {TRIAL}")]
    assert len(table) == 2 and all(line.count(" / ") == 6 for line in table)
    assert "Madgwick" in out and "| **average** |" in out
