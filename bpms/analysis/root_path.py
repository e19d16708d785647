"""The figure's root (pelvis) trajectory for animation exports: the body model's pelvis height
plus the walked path (heel-strike dead reckoning, :func:`bpms.analysis.track.walked_path`)
when the recording holds the foot accelerometers."""

from __future__ import annotations

import numpy as np

from bpms.analysis.track import FOOT_IMUS, GyroTrackAccumulator, Track, TrackAccumulator


def root_trajectory(t: np.ndarray, pelvis: np.ndarray, step_times: np.ndarray,
                    step_positions: np.ndarray) -> np.ndarray:
    """``[N, 3]`` m NED: ``pelvis[N, 3]`` (the body model's, over the origin) plus the walked
    position, moved linearly from one heel strike (``step_times[K]`` s, running positions
    ``step_positions[K, 3]``) to the next (0 before the first)."""
    out = np.where(np.isfinite(pelvis), pelvis, 0.0).astype(np.float64)
    if len(step_times) == 0:
        return out
    times = np.concatenate([[step_times[0] - 0.5], step_times])
    pos = np.concatenate([np.zeros((1, 3)), step_positions])
    for axis in (0, 1):  # horizontal only: the height comes from the body model
        out[:, axis] += np.interp(t, times, pos[:, axis])
    return out


class StrikeFinder:
    """The heel strikes of ``bpms track`` (its default detector: the foot accelerometers, or
    the shank gyroscopes when the recording's accelerometer range clips the threshold,
    :func:`bpms.analysis.gait_events.accel_detector_usable`), found chunk by chunk in constant
    memory: :meth:`add` each :class:`bpms.filter.door.Chunk` of a raw recording, then
    :meth:`track`. ``detector``: ``auto``, ``accel`` or ``gyro``; ``threshold_g``,
    ``min_interval_s``, ``declination_deg``: overrides of the options' ``[track]`` (None: the
    options'); ``include_hips``: feet measured from the pelvis centre."""

    def __init__(self, processor, header: dict | None, detector: str = "auto", *,
                 threshold_g: float | None = None, min_interval_s: float | None = None,
                 declination_deg: float | None = None, include_hips: bool = False) -> None:
        from bpms.analysis.gait_events import accel_detector_usable, accel_range_g

        self.proc = processor
        opts = processor.options.track
        self.threshold_g = opts.heel_strike_g if threshold_g is None else threshold_g
        self.min_interval_s = (opts.min_step_interval_s if min_interval_s is None
                               else min_interval_s)
        self.declination_deg = (opts.declination_deg if declination_deg is None
                                else declination_deg)
        self.range_g = accel_range_g(header)
        if detector == "auto":
            usable = accel_detector_usable(self.range_g, self.threshold_g)
            detector = "accel" if usable else "gyro"
        self.detector = detector
        self.gravity = processor.sensor_calibration.gravity
        self._acc: TrackAccumulator | GyroTrackAccumulator = (
            GyroTrackAccumulator(self.min_interval_s, self.declination_deg, include_hips)
            if detector == "gyro" else
            TrackAccumulator(self.threshold_g, self.min_interval_s, self.declination_deg,
                             include_hips))

    def add(self, chunk, window: np.ndarray | None = None) -> None:
        """The next chunk (``chunk.raw`` counts and ``chunk.result``); ``window[N]`` bool:
        the frames searched (None: all), the others read as no impact."""
        from bpms.analysis.gait_events import SHANK_IMUS, lateral_gyro_rate

        res = chunk.result
        acc, _, gyr = self.proc.calibrate(chunk.raw)
        if self.detector == "gyro":  # per side: the shank's swing rate, else the foot's |a| in g
            per_side = {side: lateral_gyro_rate(res.C[:, i], res.R[:, i], gyr[:, i])
                        for side, i in SHANK_IMUS.items()}
        else:
            per_side = {side: np.linalg.norm(acc[:, i], axis=-1) / self.gravity[i]
                        for side, i in FOOT_IMUS.items()}
        if window is not None:
            per_side = {side: np.where(window, x, 0.0) for side, x in per_side.items()}
        self._acc.add(res.t, per_side, res.joint_positions)

    def track(self) -> Track:
        return self._acc.track()


def walked_track(opened, zero_at_s=(), detector: str = "auto") -> Track:
    """The :class:`~bpms.analysis.track.Track` (heel strikes with their sides, the walked
    path) of a recording opened through the one door, streamed chunk by chunk in constant
    memory; no strike for a filtered file (no raw sensors)."""
    if not opened.has_raw:
        return Track(np.zeros(0), [], np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    finder = StrikeFinder(opened.processor, opened.header, detector)
    for chunk in opened.chunks(zero_at_s):
        finder.add(chunk)
    return finder.track()


def walked_steps(opened, zero_at_s=()) -> tuple[np.ndarray, np.ndarray]:
    """Heel-strike times ``[K]`` s and running positions ``[K, 3]`` m of a recording opened
    through the one door (:func:`bpms.filter.door.open_for_processing`), streamed chunk by
    chunk in constant memory (the accelerometer detector); empty for a filtered file (no
    accelerometers)."""
    track = walked_track(opened, zero_at_s, "accel")
    return np.asarray(track.times, dtype=np.float64), np.asarray(track.positions,
                                                                 dtype=np.float64).reshape(-1, 3)


def walked_offset(t: np.ndarray, track: Track) -> np.ndarray:
    """``[N, 3]`` m NED: the horizontal walked position at times ``t`` (s), moved linearly
    from one heel strike to the next (:func:`root_trajectory` without the pelvis)."""
    return root_trajectory(t, np.zeros((len(t), 3)), np.asarray(track.times, np.float64),
                           np.asarray(track.positions, np.float64).reshape(-1, 3))
