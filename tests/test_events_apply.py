"""Session events applied at their frames (issue 25): inside one batch they give what the
live processor gives when the same calls are made between its frames; the automatic Reset
Zero waits for a still window (the frame worked out here from the motion); an adopted zero is
used exactly; the re-analysis choices; where the live writer's events land in the file; what a
seek carries."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.cli import main
from bpms.filter.pose import PoseCalibrator, capture_zero, segment_orientations
from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.rotations import rot_z
from bpms.filter.zero_choice import ResetZeroChoice
from bpms.firmware.sim.session import simulate
from bpms.io.replay import state_before
from bpms.io.session_events import SessionEvent
from bpms.pipeline.raw_logger import SlotMap


def _turning(n: int = 160, until: int = 80, deg: float = 30.0) -> np.ndarray:
    """18 IMUs still, except IMU 2 turning at a constant rate about z until frame ``until``."""
    angle = np.radians(deg) * np.minimum(np.arange(n), until) / until
    R = np.tile(np.eye(3), (n, 18, 1, 1))
    R[:, 2] = rot_z(angle)
    return R


def test_the_automatic_reset_zero_waits_for_a_still_window():
    """Window 25, settle 25: the capture could come at frame 49, but IMU 2 turns 0.375° per
    frame until frame 80. A window from s to s + 24 moves 0.375 × (min(s + 24, 80) − s)°,
    at most 5° first for s = 67: the capture is at frame 91, 42 frames late, with 4.875°."""
    R = _turning()
    batch = PoseCalibrator(window=25, settle=25)
    C = batch.apply(R)
    auto = [z for z in batch.captures if z.source == "automatic"]
    assert [(z.frame, z.waited) for z in auto] == [(91, 42)]
    assert auto[0].motion_deg == pytest.approx(0.375 * 13, abs=1e-9) and auto[0].motion_imu == 2
    np.testing.assert_allclose(auto[0].R0, capture_zero(R[67:92]).R0, atol=1e-15)
    live = PoseCalibrator(window=25, settle=25)
    waiting = []
    frames = []
    for k in range(len(R)):
        frames.append(live.apply(R[k:k + 1])[0])
        waiting.append(live.waiting)
    np.testing.assert_array_equal(np.array(frames), C)
    assert all(w is None for w in waiting[:49]) and all(w is not None for w in waiting[49:91])
    assert waiting[49] == pytest.approx((9.0, 2), abs=1e-9) and waiting[91] is None


def test_a_reset_zero_pressed_first_cancels_the_automatic_one():
    pose = PoseCalibrator(window=25, settle=25)
    pose.apply(_turning()[:60])
    pose.request("manual")
    pose.apply(_turning()[60:])
    assert [z.source for z in pose.captures] == ["provisional", "manual"]
    assert not pose.auto_pending and pose.waiting is None


@pytest.fixture(scope="module")
def rec():
    return simulate(duration_s=10.0, seed=8)


EVENTS = [(150, SessionEvent("gains", data={"values": {"kp_yaw": 0.3, "ki_yaw": 0.001}})),
          (200, SessionEvent("alignment", data={"on": False})),
          (230, SessionEvent("marker", data={"text": "nothing changes"})),
          (250, SessionEvent("reset_zero", data={"source": "manual", "window": 25})),
          (270, SessionEvent("alignment", data={"on": True})),
          (300, SessionEvent("filter", data={"algorithm": "observer"})),
          (350, SessionEvent("filters", data={"action": "reinit"}))]


def _live(rec) -> list:
    """The live processor: one frame at a time, the calls a session makes between frames."""
    proc = BodyPoseProcessor(rec.calibration)
    calls = {150: lambda: proc.set_gains(kp_yaw=0.3, ki_yaw=0.001),
             200: lambda: proc.set_corrected_output(False), 250: proc.reset_zero,
             270: lambda: proc.set_corrected_output(True),
             300: lambda: proc.select_filter("observer"), 350: proc.reinitialise}
    out = []
    for k in range(len(rec.raw)):
        if k in calls:
            calls[k]()
        out.append(proc.step(rec.raw[k], rec.errors[k]))
    return out


def test_events_inside_a_batch_equal_the_live_calls_between_frames(rec):
    live = _live(rec)
    batch = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors, EVENTS)
    chunked = BodyPoseProcessor(rec.calibration)
    parts = []
    for lo in range(0, len(rec.raw), 97):
        hi = min(lo + 97, len(rec.raw))
        inside = [(k - lo, e) for k, e in EVENTS if lo <= k < hi]
        parts.append(chunked.process(rec.raw[lo:hi], rec.errors[lo:hi], inside))
    for name in ("R", "C", "euler_output", "joint_angles", "corrected"):
        want = np.concatenate([getattr(f, name) for f in live])
        np.testing.assert_array_equal(getattr(batch, name), want, err_msg=name)
        np.testing.assert_array_equal(np.concatenate([getattr(p, name) for p in parts]), want,
                                      err_msg=name)
    assert [(z.source, z.frame) for z in batch.zeros][-1] == ("manual", 250)
    assert not batch.corrected[200:270].any() and batch.corrected[270:].all()


def test_an_adopted_zero_is_used_exactly(rec):
    proc = BodyPoseProcessor(rec.calibration)
    R0 = np.array([rot_z(0.01 * i) for i in range(18)])
    zero = SessionEvent("reset_zero", data={"source": "network", "window": 25,
                                            "R0": R0.tolist(), "yaw0": 0.4})
    out = proc.process(rec.raw[:100], rec.errors[:100], [(60, zero)])
    assert out.zeros[-1].source == "network" and out.zeros[-1].frame == 60
    np.testing.assert_array_equal(out.C[60:], segment_orientations(out.R[60:], out.zeros[-1]))
    np.testing.assert_allclose(out.zeros[-1].offset, np.swapaxes(R0, -1, -2) @ rot_z(0.4),
                               atol=1e-15)


def test_a_bad_recorded_event_is_a_problem_not_an_error(rec):
    proc = BodyPoseProcessor(rec.calibration)
    bad = [(10, SessionEvent("gains", data={"values": {"kp_yaw": -5.0}})),
           (20, SessionEvent("filter", data={"algorithm": "nonsense"}))]
    out = proc.process(rec.raw[:50], rec.errors[:50], bad)
    assert len(out) == 50 and len(proc.problems) == 2
    assert proc.options.filter.kp_yaw != -5.0


@pytest.mark.parametrize(("text", "mode", "times"), [
    ("events", "events", ()), ("auto", "auto", ()), ("none", "none", ()),
    ("at 12.5", "at", (12.5,)), ("at 3,7.5", "at", (3.0, 7.5)), ("AT=4", "at", (4.0,))])
def test_the_reset_zero_choices(text, mode, times):
    choice = ResetZeroChoice.parse(text)
    assert (choice.mode, choice.times) == (mode, times)


@pytest.mark.parametrize("text", ["sometimes", "at", "at -1", "at x", "auto 3"])
def test_a_bad_reset_zero_choice_is_refused_in_one_line(text, tmp_path, capsys):
    with pytest.raises(ValueError, match="events, auto, none"):
        ResetZeroChoice.parse(text)
    with pytest.raises(SystemExit) as stop:
        main(["filter", str(tmp_path / "x.bpmsraw"), "--reset-zero", text])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "--reset-zero" in err[-1] and "Traceback" not in "".join(err)


def test_the_raw_logger_maps_source_frames_to_file_slots():
    slots = SlotMap()
    for index in [*range(500, 600), *range(650, 700)]:  # a gap in the source's numbers
        slots.add(index)
    assert slots.slot_of(499) == 0  # before the recording: its first slot
    assert slots.slot_of(550) == 50 and slots.slot_of(650) == 100
    assert slots.slot_of(620) == 100  # a frame never received: the next one written
    for index in range(10, 20):  # a seek back (playback)
        slots.add(index)
    assert slots.slot_of(15) == 155  # the newest run holding it


def test_a_seek_carries_the_state_the_events_left_in_force():
    zero = SessionEvent("reset_zero", 100, 5.0, {"source": "manual", "R0": [], "yaw0": 0.1})
    events = [(0, SessionEvent("gains", data={"values": {"kp_yaw": 1.2, "ki_yaw": 0.0}})),
              (100, zero),
              (150, SessionEvent("gains", data={"values": {"kp_yaw": 0.5}})),
              (200, SessionEvent("alignment", data={"on": False})),
              (400, SessionEvent("alignment", data={"on": True}))]
    carried = {e.kind: e for e in state_before(events, 300)}
    assert carried["gains"].data["values"] == {"kp_yaw": 0.5, "ki_yaw": 0.0}
    assert carried["alignment"].data["on"] is False
    assert carried["reset_zero"].data["adopt"] is True and carried["reset_zero"].frame == 300
    assert {e.kind for e in state_before(events, 50)} == {"gains"}
