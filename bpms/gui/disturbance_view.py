"""How a disturbance flag is shown: its kind, since when it has been up, and its strength.

The flags and their strengths come from the detector (:mod:`bpms.filter.disturbance`, per
IMU and frame) through ``PoseSample``: magnetometer ``mag`` (``mag_disturbed``; strength
``mag_strength``, how far the field is from the earth's as a fraction of it, and
``mag_heading_deg``, the heading error a filter trusting it would take) and acceleration
``acc`` (``acc_disturbed``; strength ``acc_strength``, the linear acceleration in g RMS).
:class:`FlagAges` remembers the frame at which each flag went up, so a reader can tell a blip
from a lasting disturbance and weigh it: ``mag 12 s 35 %``, ``acc 0.4 s 0.3 g``. Times are
stream time (frame index × 20 ms), so a paused or sped-up playback reads the same as live.
"""

from __future__ import annotations

import numpy as np

from bpms.io.frames import N_IMUS
from bpms.io.timebase import stream_time

KINDS = ("mag", "acc")
MEANINGS = {"mag": "magnetometer disturbed: the field is more than 10 % of the earth's field "
                   "away from the one learnt while the IMU was still, or turned that much "
                   "(iron, a magnet nearby); the heading is then less reliable",
            "acc": "linear acceleration above 0.2 g RMS: the accelerometer is no gravity "
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
        #: the latest strengths: mag fraction of the earth's field, its heading error in
        #: degrees, acc in g (NaN: not known)
        self.mag_strength = np.full(N_IMUS, np.nan)
        self.mag_heading_deg = np.full(N_IMUS, np.nan)
        self.acc_strength = np.full(N_IMUS, np.nan)

    def update(self, index: int, mag: np.ndarray | None, acc: np.ndarray | None,
               mag_strength: np.ndarray | None = None,
               mag_heading_deg: np.ndarray | None = None,
               acc_strength: np.ndarray | None = None) -> None:
        """The flags of frame ``index`` (None: not computed, all down) and their strengths
        (None: not known). A step back in time (a seek) counts flags still up from that
        frame."""
        if index < self.index:
            self.up_since[:] = -1
        self.index = index
        for mine, given in ((self.mag_strength, mag_strength),
                            (self.mag_heading_deg, mag_heading_deg),
                            (self.acc_strength, acc_strength)):
            mine[:] = np.nan if given is None else given
        for k, flags in enumerate((mag, acc)):
            up = np.zeros(N_IMUS, bool) if flags is None else np.asarray(flags, bool)
            rising = up & (self.up_since[:, k] < 0)
            self.up_since[rising, k] = index
            self.up_since[~up, k] = -1

    def seconds(self, imu: int, kind: int) -> float | None:
        """How long flag ``kind`` of ``imu`` has been up, s (None: down)."""
        since = self.up_since[imu, kind]
        return None if since < 0 else stream_time(self.index - since + 1)

    def strength(self, imu: int, kind: int) -> str:
        """"35 %" (mag, of the earth's field) or "0.3 g" (acc); "" when not known."""
        if kind == 0:
            value = self.mag_strength[imu]
            return "" if value != value else f"{min(100.0 * value, 999.0):.0f} %"
        value = self.acc_strength[imu]
        return "" if value != value else f"{min(value, 9.9):.1f} g"

    def text(self, imu: int) -> str:
        """"", "mag 12 s 35 %", "acc 0.4 s 0.3 g" or both, comma-separated."""
        parts = []
        for k, kind in enumerate(KINDS):
            age = self.seconds(imu, k)
            if age is not None:
                parts.append(" ".join(filter(None, (kind, duration_text(age),
                                                    self.strength(imu, k)))))
        return ", ".join(parts)

    def tooltip(self, imu: int) -> str:
        """What each flag of ``imu`` that is up means, since when, and how strong it is."""
        lines = []
        for k, kind in enumerate(KINDS):
            age = self.seconds(imu, k)
            if age is None:
                continue
            how = ""
            if kind == "mag" and self.strength(imu, 0):
                heading = self.mag_heading_deg[imu]
                how = (f"; the field is {self.strength(imu, 0)} of the earth's field away "
                       f"from it" + ("" if heading != heading
                                     else f", a heading error of {heading:.0f}° if trusted"))
            elif kind == "acc" and self.strength(imu, 1):
                how = f"; linear acceleration {self.strength(imu, 1)} RMS"
            lines.append(f"{kind}: up for {duration_text(age)}{how} — {MEANINGS[kind]}")
        return "\n".join(lines)

    def longest(self, kind: int) -> float | None:
        """The longest time any IMU's flag ``kind`` has been up, s (None: none up)."""
        up = self.up_since[:, kind]
        return None if (up < 0).all() else stream_time(self.index - up[up >= 0].min() + 1)
