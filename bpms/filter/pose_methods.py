"""Which pose calibration a recording is filtered with: ``--pose-calibration reset-zero|posture|
functional`` (docs/pose-calibration.md), for ``bpms filter``, ``export``, ``rom`` and the API.

- ``reset-zero`` (the default): Reset Zero as chosen by ``--reset-zero``; nothing changes.
- ``posture``: the still window of the first Reset Zero capture (recorded or automatic) is
  taken in the declared posture (``--posture``: a preset or measured joint angles,
  :mod:`bpms.filter.posture_calibration`).
- ``functional``: the sensor-to-segment rotations come from the still window of the first
  capture and the movements in the ``functional_s`` seconds after it
  (:mod:`bpms.filter.functional_calibration`).

Both are computed from a first pass over the recording (the filter's DCMs and the calibrated
sensors, Reset Zero as chosen) and applied as a ``reset_zero`` event (``adopt``, source
``posture`` or ``functional``) one frame after that capture, with the method's details and
quality in the event's data; a later Reset Zero in the recording replaces it, as any capture.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bpms.filter.functional_calibration import functional_calibration, sensor_values
from bpms.filter.posture_calibration import parse_posture, posture_zero
from bpms.io.event_types import ResetZero
from bpms.io.session_events import SessionEvent

METHODS = ("reset-zero", "posture", "functional")


@dataclass(frozen=True)
class PoseCalibrationChoice:
    """``method`` (:data:`METHODS`); ``posture`` the declared joint angles (degrees, ISB
    names) for ``posture``; ``functional_s`` seconds of movements used after the still
    window."""

    method: str = "reset-zero"
    posture: dict = field(default_factory=dict)
    posture_text: str = "neutral"
    functional_s: float = 60.0

    @classmethod
    def parse(cls, method: str | PoseCalibrationChoice | None, posture: str | dict | None = None,
              functional_s: float = 60.0) -> PoseCalibrationChoice:
        """Raises ValueError naming the choices."""
        if isinstance(method, PoseCalibrationChoice):
            return method
        name = "reset-zero" if method is None else str(method).strip().lower()
        if name not in METHODS:
            raise ValueError(f"--pose-calibration: '{method}' is not one of {', '.join(METHODS)}")
        if posture is not None and name != "posture":
            raise ValueError("--posture goes with --pose-calibration posture")
        if not 5.0 <= functional_s <= 600.0:
            raise ValueError("the functional movements' span must be 5 .. 600 s")
        text = posture if isinstance(posture, str) else ("given" if posture else "neutral")
        return cls(name, parse_posture(posture), text, float(functional_s))

    @property
    def default(self) -> bool:
        return self.method == "reset-zero"

    def describe(self) -> str:
        if self.method == "posture":
            return f"declared posture ({self.posture_text})"
        return {"reset-zero": "Reset Zero", "functional": "functional calibration"}[self.method]


def calibration_event(opened: Any, choice: PoseCalibrationChoice
                      ) -> tuple[int, SessionEvent]:
    """(slot, event): the pose calibration of ``opened`` (a raw recording opened by
    :func:`bpms.filter.door.open_for_processing`, not imported here), from a first pass
    over it. Raises ValueError when it cannot be made (a filtered file, no still window)."""
    if not opened.has_raw:
        raise ValueError(f"{opened.path}: {choice.describe()} needs a raw recording")
    proc = opened.processor
    dt = proc.options.filter.dt
    span = round(choice.functional_s / dt)
    R_parts, raw_parts, error_parts, zero = [], [], [], None
    held = 0
    for chunk in opened.chunks():
        R_parts.append(chunk.result.R)
        raw_parts.append(chunk.raw)
        error_parts.append(chunk.errors)
        held += len(chunk)
        if zero is None:
            zero = next((z for z in chunk.result.zeros if z.source != "provisional"), None)
        if zero is not None and (choice.method == "posture" or held > zero.frame + span):
            break
    if zero is None:
        raise ValueError(f"{opened.path}: no Reset Zero capture (no still window) for the "
                         f"{choice.describe()}")
    lo = max(zero.frame - zero.window + 1, 0)
    data = {"adopt": True, "window": int(zero.window), "heading": "mean",
            "still": [lo, int(zero.frame)]}
    if choice.method == "posture":
        R0, yaw0 = posture_zero(zero.R0, choice.posture)
        data |= {"source": "posture", "posture": dict(choice.posture)}
    else:
        R = np.concatenate(R_parts)
        acc, gyr = sensor_values(proc.sensor_calibration, np.concatenate(raw_parts),
                                 np.concatenate(error_parts))
        moves = slice(zero.frame, min(zero.frame + span, len(R)))
        R0, yaw0, report = functional_calibration(R, acc, gyr, slice(lo, zero.frame + 1), moves,
                                                  dt)
        data |= {"source": "functional", "heading": report.heading,
                 "moves": [moves.start, moves.stop - 1], "quality": report.as_dict()}
        opened.pose_report = report
    data |= {"R0": R0.tolist(), "yaw0": float(yaw0)}
    slot = int(zero.frame) + 1
    return slot, SessionEvent.of(ResetZero.from_data(data), slot)
