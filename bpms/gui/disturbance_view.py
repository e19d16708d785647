"""How a disturbance flag is shown: its kind and since when it has been up.

The flags come from the detector (:mod:`bpms.filter.disturbance`, per IMU and frame:
magnetometer ``mag`` — the field's norm or dip away from what was learnt at rest — and
acceleration ``acc`` — far from 1 g for long) through ``PoseSample.mag_disturbed`` /
``acc_disturbed``. :class:`FlagAges` remembers the frame at which each flag went up, so a
reader can tell a blip from a lasting disturbance: ``mag 12 s``. Times are stream time (frame
index × 20 ms), so a paused or sped-up playback reads the same as live.
"""

from __future__ import annotations

import numpy as np

from bpms.io.frames import FRAME_PERIOD_S, N_IMUS

KINDS = ("mag", "acc")
MEANINGS = {"mag": "magnetometer disturbed: the field's norm or dip is away from the one "
                   "learnt while the IMU was still (iron, a magnet nearby); the heading is "
                   "then less reliable",
            "acc": "acceleration far from 1 g for long: the accelerometer is no gravity "
                   "reference then (fast motion, impacts)"}


def duration_text(seconds: float) -> str:
    """"0.4 s", "12 s", "3 min", "2 h" (never wider than "59 min")."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes = int(seconds // 60)
    return f"{minutes} min" if minutes < 60 else f"{minutes // 60} h"


class FlagAges:
    """Per IMU and kind, the stream frame at which the flag went up (−1: down)."""

    def __init__(self) -> None:
        self.up_since = np.full((N_IMUS, len(KINDS)), -1, np.int64)
        self.index = 0

    def update(self, index: int, mag: np.ndarray | None, acc: np.ndarray | None) -> None:
        """The flags of frame ``index`` (None: not computed, all down). A step back in time
        (a seek) counts flags still up from that frame."""
        if index < self.index:
            self.up_since[:] = -1
        self.index = index
        for k, flags in enumerate((mag, acc)):
            up = np.zeros(N_IMUS, bool) if flags is None else np.asarray(flags, bool)
            rising = up & (self.up_since[:, k] < 0)
            self.up_since[rising, k] = index
            self.up_since[~up, k] = -1

    def seconds(self, imu: int, kind: int) -> float | None:
        """How long flag ``kind`` of ``imu`` has been up, s (None: down)."""
        since = self.up_since[imu, kind]
        return None if since < 0 else (self.index - since + 1) * FRAME_PERIOD_S

    def text(self, imu: int) -> str:
        """"", "mag 12 s", "acc 0.4 s" or "mag 12 s, acc 3.0 s"."""
        parts = []
        for k, kind in enumerate(KINDS):
            age = self.seconds(imu, k)
            if age is not None:
                parts.append(f"{kind} {duration_text(age)}")
        return ", ".join(parts)

    def tooltip(self, imu: int) -> str:
        """What each flag of ``imu`` that is up means, and since when."""
        lines = []
        for k, kind in enumerate(KINDS):
            age = self.seconds(imu, k)
            if age is not None:
                lines.append(f"{kind}: up for {duration_text(age)} — {MEANINGS[kind]}")
        return "\n".join(lines)

    def longest(self, kind: int) -> float | None:
        """The longest time any IMU's flag ``kind`` has been up, s (None: none up)."""
        up = self.up_since[:, kind]
        return None if (up < 0).all() else (self.index - up[up >= 0].min() + 1) * FRAME_PERIOD_S
