"""Functional pose calibration live (docs/pose-calibration.md, ``bpms record``'s ``f``): a live
session over the simulated suit in the pressure-suit posture with 10° mounting errors, the
calibration asked for before the first frame (still 0.5 s, then the functional movements). The
session's joint angles follow the simulator's own to 3°, and its recorded ``reset_zero`` event,
applied by ``bpms filter``, gives the live numbers again (to 1e-9 rad)."""

from __future__ import annotations

import numpy as np
import pytest
from waiting import wait_until

from bpms.filter.door import open_for_processing
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.recordings import open_replay
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    rec = simulate(seed=3, posture="suit", functional=True, mounting_error_deg=10.0,
                   duration_s=50.0)  # batches of up to 512 frames follow the calibration
    raw = rec.save_raw(tmp_path_factory.mktemp("functional") / "f.raw")
    opened = open_for_processing(raw)
    recording = open_replay(raw)
    source = ReplaySource(recording, speed=None, events=[])
    session = LiveSession(source, opened.processor.options, opened.processor)
    session.calibrate_functional(seconds=28.0)
    sub = session.subscribe(maxlen=5000, lossless=True)
    events = session.events.subscribe(maxlen=1000)
    with session:
        assert wait_until(lambda: session.status().processed == len(rec), 60)
    samples = sub.drain()
    zeros = [e for e in events.drain() if e.kind == "reset_zero"]
    return rec, raw, samples, zeros


def test_live_functional_follows_the_truth(live):
    rec, _, samples, zeros = live
    angles = np.stack([s.joint_angles for s in samples])
    adopted = zeros[-1].frame
    assert zeros[-1].data["source"] == "functional"
    k = np.arange(len(rec)) >= adopted  # after the calibration: the trial's first moves
    err = np.degrees(np.abs(np.angle(np.exp(1j * (angles[k] - rec.truth.joint_angles[k])))))
    rms = np.sqrt(np.mean(err ** 2, axis=0))
    assert rms.max() < 3.0, dict(zip(rec.truth.joint_names, rms.round(2), strict=True))


def test_its_event_repeats_the_live_numbers(live):
    rec, _, samples, zeros = live
    functional = [e for e in zeros if e.data["source"] == "functional"]
    assert len(functional) == 1, [e.data["source"] for e in zeros]
    event = functional[0]
    assert event.data["adopt"] is True and event.data["quality"]["missing"] == []
    assert event.frame >= 25 + 1400  # still 0.5 s + 28 s of movements, then adopted
    # bpms filter of the recording with the recorded events (here: the automatic captures
    # the live session made, then the functional zero)
    recorded = [(e.frame, e) for e in zeros]
    batch = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors, recorded)
    live_angles = np.stack([s.joint_angles for s in samples])
    np.testing.assert_allclose(batch.joint_angles[event.frame:], live_angles[event.frame:],
                               rtol=0, atol=1e-9)
