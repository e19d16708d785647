"""When Reset Zero captures and what it averages (bpms.filter.pose.PoseCalibrator), against
frame numbers and angles worked out by hand on a scripted stream (docs/body-model.md): the
provisional capture at the first frame, the automatic one at the first still 0.5 s window
after the 0.5 s settle, a manual one over the window ending at the next frame — the same in one
batch, in chunks and frame by frame (the live path)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bpms.filter.pose import PoseCalibrator
from bpms.filter.rotations import rot_x, rot_z

N = 520
STILL_FROM = 400  # IMU 3 waves until frame 399, then every IMU holds still
HIP = 6


def _stream() -> np.ndarray:
    """[N, 18, 3, 3]: IMU i at rot_z(0.01 i); IMU 3 waving ±0.5 rad about x (period ≈ 19
    frames: more than 5° within any 25-frame window) until STILL_FROM; IMU 0 turning
    1 mrad a frame about z from frame 440 to 460 (a slow drift, still by the 5° rule)."""
    R = np.empty((N, 18, 3, 3))
    for i in range(18):
        R[:, i] = rot_z(0.01 * i)
    for k in range(STILL_FROM):
        R[k, 3] = rot_z(0.03) @ rot_x(0.5 * math.sin(k / 3.0))
    for k in range(440, N):
        R[k, 0] = rot_z(0.001 * min(k - 440, 20))
    return R


def _run(chunks: list[int], requests: dict[int, dict] | None = None) -> PoseCalibrator:
    cal = PoseCalibrator()
    R = _stream()
    at = 0
    for size in chunks:
        for frame, kw in (requests or {}).items():
            if frame == at:
                cal.request(**kw)
        cal.apply(R[at:at + size])
        at += size
    assert at == N
    return cal


def _schedules():
    return {"one batch": [N], "chunks of 7": [7] * (N // 7) + [N % 7],
            "chunks of 300": [300, N - 300], "frame by frame": [1] * N}


@pytest.mark.parametrize("how", list(_schedules()))
def test_automatic_capture_at_the_first_still_window(how):
    cal = _run(_schedules()[how])
    kinds = [(z.source, z.frame, z.window) for z in cal.captures]
    # provisional at frame 0 (one frame); automatic at the end of the first still 25-frame
    # window: frames 400 … 424
    assert kinds == [("provisional", 0, 1), ("automatic", 424, 25)], kinds
    auto = cal.captures[1]
    assert auto.waited == 424 - (25 + 25 - 1)  # it could have been at frame 49
    assert auto.yaw0 == pytest.approx(0.06, abs=1e-12)  # the hip IMU's yaw
    assert auto.motion_deg == pytest.approx(0.0, abs=1e-5)
    np.testing.assert_allclose(auto.R0[3], rot_z(0.03), atol=1e-12)
    assert cal.state_text() == "automatic at 8.48 s"
    assert cal.waiting is None and not cal.auto_pending


def test_still_from_the_start_captures_after_the_settle():
    cal = PoseCalibrator()
    R = np.broadcast_to(np.stack([rot_z(0.01 * i) for i in range(18)]), (80, 18, 3, 3))
    assert cal.state_text() == "none yet"
    cal.apply(R[:30])
    assert [z.source for z in cal.captures] == ["provisional"]
    cal.apply(R[30:])
    assert [(z.source, z.frame) for z in cal.captures][1] == ("automatic", 49)
    assert cal.captures[1].waited == 0


def test_waiting_names_the_moving_imu():
    cal = PoseCalibrator(provisional=False)
    cal.apply(_stream()[:300])
    assert cal.captures == [] and cal.auto_pending
    deg, imu = cal.waiting
    assert imu == 3 and deg > 5.0
    assert cal.state_text().startswith("waiting for a still pose (moved ")
    assert cal.state_text().endswith(" on IMU 3)")


@pytest.mark.parametrize("how", ["one batch", "frame by frame", "chunks of 7"])
def test_manual_capture_over_the_window_ending_at_the_next_frame(how):
    """Reset Zero pressed before frame 450: captured at frame 450 over the frames before it;
    IMU 0 turned 0 … 10 mrad over frames 440 … 450, so the window's mean yaw is worked out
    here: atan2(Σ sin, Σ cos) of its frames' yaws (the mean of rotations about one axis)."""
    schedule = {"one batch": [450, N - 450], "frame by frame": [1] * N,
                "chunks of 7": [7] * 64 + [2] + [N - 450]}[how]
    cal = _run(schedule, {450: {"window": 5}})
    manual = [z for z in cal.captures if z.source == "manual"]
    assert [(z.frame, z.window) for z in manual] == [(450, 5)]

    def mean_yaw(frames):
        yaws = [0.001 * min(max(k - 440, 0), 20) for k in frames]
        return math.atan2(sum(map(math.sin, yaws)), sum(map(math.cos, yaws)))

    R0 = manual[0].R0[0]
    assert math.atan2(R0[1, 0], R0[0, 0]) == pytest.approx(mean_yaw(range(446, 451)), abs=1e-12)
    # the default window (25) and a window longer than it (capped at 25) are the same
    for kw in ({}, {"window": 100}):
        cal = _run([450, N - 450], {450: kw})
        (zero,) = [z for z in cal.captures if z.source == "manual"]
        assert (zero.frame, zero.window) == (450, 25)
        yaw = math.atan2(zero.R0[0, 1, 0], zero.R0[0, 0, 0])
        assert yaw == pytest.approx(mean_yaw(range(426, 451)), abs=1e-12)


def test_capture_frames_count_from_the_origin_and_adopt_keeps_missing_imus():
    cal = PoseCalibrator(auto=False)
    cal.restart(origin=1000)
    R = _stream()
    cal.apply(R[STILL_FROM:STILL_FROM + 10])
    assert [(z.source, z.frame) for z in cal.captures] == []  # auto off: no provisional
    cal.request("manual")
    cal.apply(R[STILL_FROM + 10:STILL_FROM + 12])
    assert cal.captures[-1].frame == 1010 and cal.captures[-1].window == 11
    R0 = np.stack([rot_z(0.2)] * 18)
    R0[5] = np.nan
    cal.adopt(R0, 0.2)
    cal.apply(R[STILL_FROM + 12:STILL_FROM + 13])
    adopted = cal.captures[-1]
    assert (adopted.source, adopted.frame, adopted.window, adopted.yaw0) == \
        ("network", 1012, 1, 0.2)
    np.testing.assert_allclose(adopted.R0[5], rot_z(0.05), atol=1e-12)  # kept
    np.testing.assert_allclose(adopted.R0[4], rot_z(0.2), atol=1e-12)
    assert cal.state_text(dt=0.01) == "network at 10.12 s"


def test_a_manual_capture_before_the_still_window_cancels_the_automatic_one():
    """Reset Zero pressed while the subject still moves: it stands; no automatic capture comes
    after it (in one batch as frame by frame)."""
    for schedule in ([N], [60, N - 60], [1] * N):
        cal = _run(schedule, {0: {}}) if schedule == [N] else _run(schedule, {60: {}})
        kinds = [z.source for z in cal.captures]
        assert "automatic" not in kinds, (schedule[:2], kinds)
        assert kinds[-1] == "manual"
        assert not cal.auto_pending


def test_re_analysis_captures_at_the_frames_given():
    """``apply(R, zero_at=...)`` (bpms filter --reset-zero at …): a capture at each frame index
    inside the batch, beside one pressed before it; indices outside the batch are ignored."""
    R = _stream()[STILL_FROM:STILL_FROM + 40]
    cal = PoseCalibrator(auto=False)
    cal.request("manual", window=1)
    cal.apply(R, zero_at=[0, 39, 40, -1])
    assert [(z.source, z.frame) for z in cal.captures] == [
        ("manual", 0), ("re-analysis", 0), ("re-analysis", 39)]
    assert [z.window for z in cal.captures] == [1, 1, 25]  # frame 0: only itself back then


@pytest.mark.parametrize("window", [1, 2, 3])
def test_short_windows_across_live_frames(window):
    """A window of 1, 2 or 3 frames, frame by frame: the capture averages exactly the last
    ``window`` frames (worked out here), with the frames before the press remembered."""
    R = np.stack([np.broadcast_to(rot_z(0.01 * k), (18, 3, 3)) for k in range(12)])
    cal = PoseCalibrator(window=window, auto=False)
    for k in range(12):
        if k == 10:
            cal.request()
        cal.apply(R[k:k + 1])
    (zero,) = cal.captures
    assert (zero.frame, zero.window, zero.source) == (10, window, "manual")
    yaws = [0.01 * k for k in range(11 - window, 11)]
    mean = math.atan2(sum(map(math.sin, yaws)), sum(map(math.cos, yaws)))
    assert math.atan2(zero.R0[0, 1, 0], zero.R0[0, 0, 0]) == pytest.approx(mean, abs=1e-12)
    cal.request(window=1)
    cal.apply(R[11:12])
    assert cal.captures[-1].window == 1


def test_adopted_zero_keeps_its_motion_and_the_heading_rule():
    cal = PoseCalibrator(auto=False, heading="mean")
    cal.apply(_stream()[STILL_FROM:STILL_FROM + 3])
    R0 = np.stack([rot_z(0.2)] * 18).tolist()
    R0[5] = [[None] * 3] * 3  # no data for IMU 5, as a network zero may carry
    cal.adopt(R0, 0.2, motion=(3.5, 7), window=25)
    cal.apply(_stream()[STILL_FROM + 3:STILL_FROM + 4])
    zero = cal.captures[-1]
    assert (zero.motion_deg, zero.motion_imu, zero.waited, zero.heading, zero.window) == \
        (3.5, 7, 0, "mean", 25)
    assert np.isnan(zero.R0[5]).all()  # no earlier zero to keep it from


def test_waiting_text_shows_the_motion_in_degrees():
    cal = PoseCalibrator(provisional=False)
    cal.apply(_stream()[:300])
    deg, imu = cal.waiting
    assert cal.state_text() == f"waiting for a still pose (moved {deg:.1f}° on IMU {imu})"
    assert f"{deg:.1f}" != f"{float(imu):.1f}"


def test_missing_imus_keep_their_zero_and_waits_count_from_the_origin():
    """A second capture in a window where IMU 9 has no data keeps IMU 9's first zero; an
    automatic capture's wait counts from the stream's first frame, whatever the origin."""
    still = np.stack([rot_z(0.01 * i) for i in range(18)])
    cal = PoseCalibrator(provisional=False)
    cal.restart(origin=1000)
    cal.apply(np.broadcast_to(still, (60, 18, 3, 3)))
    (auto,) = cal.captures
    assert (auto.frame, auto.waited) == (1049, 0)
    moved = np.broadcast_to(np.stack([rot_z(0.3)] * 18), (30, 18, 3, 3)).copy()
    moved[:, 9] = np.nan
    cal.request(window=1)  # over the new frame alone
    cal.apply(moved)
    second = cal.captures[-1]
    np.testing.assert_allclose(second.R0[9], rot_z(0.09), atol=1e-12)  # the first's
    np.testing.assert_allclose(second.R0[8], rot_z(0.3), atol=1e-12)
