"""Euler angles for the display as people read them: the standard ranges, without the jumps
that only come from how the three angles are chosen where those would mislead.

The filters give each IMU's attitude as ``R = Rz(yaw) Ry(pitch) Rx(roll)`` with roll and yaw
in (−180°, 180°] and pitch in [−90°, 90°] (docs/units.md). Two things make those ranges jump
on a smooth motion:

- **wrapping**: a yaw passing south goes 179° → −179° (a 358° step);
- **the pitch limit**: a segment whose forward axis passes the vertical (the forearm in elbow
  flexion beyond 90°) is described, past that point, by the *other* triple of the same
  rotation, ``(roll + 180°, 180° − pitch, yaw + 180°)``: roll and yaw flip by 180° in one
  frame.

:class:`ContinuousAngles` removes both where they would mislead, and never lets the readout
pile up whole turns:

- **away from the singularity** (pitch more than :data:`GIMBAL_MARGIN_DEG` from ±90°) the
  readout is the standard triple: pitch in [−90°, 90°], roll and yaw in (−180°, 180°], except
  that roll or yaw passing ±180° is carried on past it by at most :data:`WRAP_BAND_DEG`
  (no 358° step for a segment turning a little either side of south): outside the standard
  range only while the standard angle is within that band of ±180°, never further;
- **near the singularity** (the forearm in elbow flexion near the vertical) it takes, of the
  two triples that describe the rotation, the one nearer the previous frame's angles, unwrapped
  to within 180° of it: roll and yaw sweep there, they do not jump, and pitch may pass ±90°.
  Leaving that region on the far side (pitch past ±90°), the readout returns to the standard
  triple in one frame: pitch ``180° − pitch``, roll and yaw turned by 180°. There too roll and
  yaw never run more than :data:`WRAP_BAND_DEG` past ±180° (a whole turn is taken off).

So the readout never drifts by whole turns, live, after a seek or after an hour; it is always
the same rotation (the same ``R``) as the filters' angles.

Near pitch ±90° roll and yaw are poorly defined: only their difference (pitch +90°) or sum
(−90°) is, and a segment passing close to the vertical turns both by up to 180° within a few
frames, whichever triple is chosen (the forearm in the simulated elbow flexion passes 3.5°
from it: roll and yaw sweep by 160° in about 0.2 s, at most 26° from one frame to the next).
:func:`poorly_defined` says where (within :data:`GIMBAL_MARGIN_DEG` of ±90°), and the table
shows those roll and yaw cells greyed, with the reason in their tooltip. The joint angles
(elbow flexion: the angle between the segments' long axes) read right there. Files, UDP and
LSL keep the standard ranges; only the table and the plots show this readout. It restarts
(standard ranges) after a gap or a jump back in time, and for an IMU whose angles were not
finite.
"""

from __future__ import annotations

import numpy as np

#: A gap this long (frames) or a step back in time restarts the readout.
RESTART_GAP_FRAMES = 50
#: Roll and yaw are marked poorly defined within this of pitch ±90°, degrees.
GIMBAL_MARGIN_DEG = 15.0
#: Away from the singularity, roll and yaw may run past ±180° by this much (degrees) while a
#: segment turns a little either side of it; further, they are wrapped back.
WRAP_BAND_DEG = 20.0
_BAND = float(np.radians(WRAP_BAND_DEG))
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
        # away from the singularity: the standard triple, roll and yaw carried past ±180° by
        # at most the band (no whole turns pile up, pitch within ±90°)
        away = ~poorly_defined(e[:, 1])
        if away.any():
            same = _near(e, prev)
            same[:, 1] = e[:, 1]
            # carried only while the standard angle is itself within the band of ±180°
            near_south = np.abs(e[:, [0, 2]]) >= np.pi - _BAND
            inside = np.all((np.abs(same[:, [0, 2]]) <= np.pi + _BAND) & near_south
                            | (same[:, [0, 2]] == e[:, [0, 2]]), axis=1)
            standard = np.where(inside[:, None], same, e)
            chosen[away] = standard[away]
        # near it too, roll and yaw never run more than the band past ±180° (whole turns
        # taken off: a step in cells marked poorly defined, never a pile of turns)
        ry = chosen[:, [0, 2]]
        over = np.abs(ry) > np.pi + _BAND
        if over.any():
            chosen[:, [0, 2]] = np.where(over, (ry + np.pi) % _TWO_PI - np.pi, ry)
        # an IMU without finite angles (or before its first) starts again from its own
        fresh = ~np.isfinite(prev).all(axis=1) | ~np.isfinite(chosen).all(axis=1)
        chosen[fresh] = e[fresh]
        self.previous = chosen.copy()
        return chosen
