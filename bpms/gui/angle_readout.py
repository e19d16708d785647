"""Continuous Euler angles for the display: roll, pitch, yaw that never jump between frames
because of how the three angles are chosen, only because the segment moved.

The filters give each IMU's attitude as ``R = Rz(yaw) Ry(pitch) Rx(roll)`` with roll and yaw
in (−180°, 180°] and pitch in [−90°, 90°] (docs/units.md). Two things make those ranges jump
on a smooth motion:

- **wrapping**: a yaw passing south goes 179° → −179° (a 358° step);
- **the pitch limit**: a segment whose forward axis passes the vertical (the forearm in elbow
  flexion beyond 90°) is described, past that point, by the *other* triple of the same
  rotation, ``(roll + 180°, 180° − pitch, yaw + 180°)``: roll and yaw flip by 180° in one
  frame.

:class:`ContinuousAngles` removes both. Frame by frame and per IMU it takes, of the two
triples that describe the rotation, the one nearer the previous frame's angles, and unwraps
roll and yaw to within 180° of the previous value. The readout is the same rotation (the same
``R``); pitch may go beyond ±90° and roll and yaw beyond ±180°.

Near pitch ±90° roll and yaw are poorly defined: only their difference (pitch +90°) or sum
(−90°) is, and a segment passing close to the vertical turns both by up to 180° within a few
frames, whichever triple is chosen (the forearm in the simulated elbow flexion passes 3.5°
from it: roll and yaw sweep by 160° in about 0.2 s, at most 26° from one frame to the next).
They sweep, they never jump; :func:`poorly_defined` says where (within
:data:`GIMBAL_MARGIN_DEG` of ±90°), and the table shows those roll and yaw cells greyed, with
the reason in their tooltip. The joint angles (elbow flexion: the angle between the segments'
long axes) read right there. Files, UDP and LSL keep the standard ranges; only the table and
the plots show the continuous readout. It restarts (standard ranges) after a gap or a jump
back in time, and for an IMU whose angles were not finite.
"""

from __future__ import annotations

import numpy as np

#: A gap this long (frames) or a step back in time restarts the readout.
RESTART_GAP_FRAMES = 50
#: Roll and yaw are marked poorly defined within this of pitch ±90°, degrees.
GIMBAL_MARGIN_DEG = 15.0
_TWO_PI = 2.0 * np.pi
_GIMBAL_COS = float(np.sin(np.radians(GIMBAL_MARGIN_DEG)))


def poorly_defined(pitch: np.ndarray) -> np.ndarray:
    """True where ``pitch`` (rad, any branch) is within :data:`GIMBAL_MARGIN_DEG` of ±90°:
    roll and yaw are then poorly defined (only their sum or difference is)."""
    with np.errstate(invalid="ignore"):
        return np.abs(np.cos(np.asarray(pitch, np.float64))) < _GIMBAL_COS


def _near(angle: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``angle`` shifted by whole turns to within half a turn of ``reference`` (rad)."""
    return reference + (angle - reference + np.pi) % _TWO_PI - np.pi


class ContinuousAngles:
    """Per-IMU continuity state for ``[n, 18, 3]`` blocks of (roll, pitch, yaw) in radians,
    fed in frame order (:meth:`feed`)."""

    def __init__(self) -> None:
        self.previous: np.ndarray | None = None  # [18, 3] rad, the last frame's readout
        self.last_index: int | None = None

    def reset(self) -> None:
        self.previous = None
        self.last_index = None

    def feed(self, euler: np.ndarray, indices: np.ndarray | None = None) -> np.ndarray:
        """The continuous readout ``[n, 18, 3]`` (rad) of ``euler [n, 18, 3]`` (the filters'
        standard angles, rad). ``indices [n]``: the frames' indices in the stream; a gap of
        :data:`RESTART_GAP_FRAMES` or a step back restarts the readout at that frame."""
        euler = np.asarray(euler, np.float64)
        out = np.empty_like(euler)
        for k in range(len(euler)):
            if indices is not None:
                index = int(indices[k])
                if self.last_index is not None and not \
                        0 < index - self.last_index < RESTART_GAP_FRAMES:
                    self.previous = None
                self.last_index = index
            out[k] = self._step(euler[k])
        return out

    def _step(self, e: np.ndarray) -> np.ndarray:
        prev = self.previous
        if prev is None:
            self.previous = e.copy()
            return e
        roll, pitch, yaw = e[:, 0], e[:, 1], e[:, 2]
        candidates = np.stack([np.stack([roll, pitch, yaw], axis=1),
                               np.stack([roll + np.pi, np.pi - pitch, yaw + np.pi], axis=1)])
        # unwrap each candidate to the previous frame (pitch too: the other triple's pitch
        # may have to pass ±180° to stay near, after a segment turned over)
        candidates = _near(candidates, prev[None])
        cost = np.sum((candidates - prev[None]) ** 2, axis=2)  # [2, 18]
        pick = np.argmin(np.where(np.isfinite(cost), cost, np.inf), axis=0)
        chosen = candidates[pick, np.arange(len(e))]
        # an IMU without finite angles (or before its first) starts again from its own
        fresh = ~np.isfinite(prev).all(axis=1) | ~np.isfinite(chosen).all(axis=1)
        chosen[fresh] = e[fresh]
        self.previous = chosen.copy()
        return chosen
