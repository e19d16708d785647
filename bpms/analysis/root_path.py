"""The figure's root (pelvis) trajectory for animation exports: the body model's pelvis height
plus the walked path (heel-strike dead reckoning, :func:`bpms.analysis.track.walked_path`)
when the recording holds the foot accelerometers."""

from __future__ import annotations

import numpy as np

from bpms.analysis.track import FOOT_IMUS, TrackAccumulator


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


def walked_steps(opened, zero_at_s=()) -> tuple[np.ndarray, np.ndarray]:
    """Heel-strike times ``[K]`` s and running positions ``[K, 3]`` m of a recording opened
    through the one door (:func:`bpms.filter.door.open_for_processing`), streamed chunk by
    chunk in constant memory; empty for a filtered file (no accelerometers)."""
    if not opened.has_raw:
        return np.zeros(0), np.zeros((0, 3))
    proc = opened.processor
    opts = proc.options.track
    gravity = proc.sensor_calibration.gravity
    acc_track = TrackAccumulator(opts.heel_strike_g, opts.min_step_interval_s,
                                 opts.declination_deg)
    for chunk in opened.chunks(zero_at_s):
        acc, _, _ = proc.calibrate(chunk.raw)
        accel_g = {side: np.linalg.norm(acc[:, i], axis=-1) / gravity[i]
                   for side, i in FOOT_IMUS.items()}
        acc_track.add(chunk.result.t, accel_g, chunk.result.joint_positions)
    track = acc_track.track()
    return np.asarray(track.times, dtype=np.float64), np.asarray(track.positions,
                                                                 dtype=np.float64).reshape(-1, 3)
