"""Functional pose calibration live (docs/pose-calibration.md): ``bpms record``'s field
command ``f [SECONDS]``.

From the command on, the session keeps the filter's DCMs and the calibrated sensors: the first
``still`` frames are the still window (the subject stands still in whatever posture), the
next ``moves`` frames the movements (knee and elbow flexions, an arm swing, a few steps).
Then :func:`bpms.filter.functional_calibration.functional_calibration` runs on them, once, and
the session adopts its zero from the next frame on, recorded as a ``reset_zero`` event
(``adopt``, source ``functional``, its ``R0`` and quality), so ``bpms filter`` of the
recording repeats the live numbers.
"""

from __future__ import annotations

import numpy as np

from bpms.filter.functional_calibration import (
    FunctionalReport,
    functional_calibration,
    sensor_values,
)


class FunctionalCollector:
    """Frames for a live functional calibration: :meth:`add` each processed batch; it returns
    ``(R0, yaw0, report, data)`` once ``still + moves`` frames are in, else None."""

    def __init__(self, still: int, moves: int, dt: float) -> None:
        self.still, self.moves, self.dt = int(still), int(moves), float(dt)
        self._R: list[np.ndarray] = []
        self._acc: list[np.ndarray] = []
        self._gyr: list[np.ndarray] = []
        self.frames = 0

    @property
    def needed(self) -> int:
        return self.still + self.moves

    def finish(self) -> bool:
        """End the movements with the frames in so far (the GUI's Stop): the calibration runs
        at the next :meth:`add`. False when no movement frame is in yet (the still window
        not over): nothing to calibrate with."""
        if self.frames <= self.still:
            return False
        self.moves = self.frames - self.still
        return True

    def add(self, R: np.ndarray, raw: np.ndarray, errors: np.ndarray, calibration
            ) -> tuple[np.ndarray, float, FunctionalReport, dict] | None:
        """``R[N, 18, 3, 3]`` the batch's DCMs, ``raw[N, 18, 9]`` its counts and ``errors
        [N, 18, 3]`` its error bits, ``calibration`` the processor's
        :class:`bpms.filter.calibration.SensorCalibration`."""
        take = max(min(len(R), self.needed - self.frames), 0)
        if take:
            acc, gyr = sensor_values(calibration, raw[:take], errors[:take])
            self._R.append(np.array(R[:take]))
            self._acc.append(acc)
            self._gyr.append(gyr)
            self.frames += take
        if self.frames < self.needed:
            return None
        R_all = np.concatenate(self._R)
        R0, yaw0, report = functional_calibration(
            R_all, np.concatenate(self._acc), np.concatenate(self._gyr),
            slice(0, self.still), slice(self.still, self.needed), self.dt)
        data = {"source": "functional", "adopt": True, "window": self.still,
                "heading": report.heading, "quality": report.as_dict(),
                "R0": R0.tolist(), "yaw0": float(yaw0)}
        return R0, yaw0, report, data
