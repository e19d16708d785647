"""Declared-posture pose calibration (docs/pose-calibration.md): Reset Zero for a subject who
cannot stand in the model's neutral pose.

Reset Zero assumes every segment is in the neutral pose during its still window: upright,
arms down, feet forward (``C_i = Rz(ψ0)``). When the investigator states the posture the
subject holds instead, as joint angles (a named preset of :data:`POSTURES` or measured values),
each segment's orientation in that window is known from the joint angles by the body's chain,
``C_i = Rz(ψ0) P_i`` (:func:`posture_segments`), and the sensor-to-segment rotation that gives
it is ``M_i = R0_iᵀ Rz(ψ0) P_i``, with ``R0_i`` the DCM averaged over the window.

The result is expressed as a Reset Zero (``R0'``, ψ0) whose offset ``R0'ᵀ Rz(ψ0)`` is ``M``:
``R0'_i = Rz(ψ0) P_iᵀ Rz(ψ0)ᵀ R0_i``, so every door that applies a Reset Zero (live, a
recorded event, a network zero) applies it unchanged.

ψ0 (the body's heading) defaults to the circular mean over the IMUs of the yaw of
``R0_i P_iᵀ`` (each is the body heading plus that IMU's mounting error, which averages out);
``"hip"`` takes the hip IMU's alone as Reset Zero does.
"""

from __future__ import annotations

import numpy as np

from bpms.filter.joints import ISB_SIGNS
from bpms.filter.pose import HIP_IMU, body_heading
from bpms.filter.rotations import euler_to_dcm, rot_y, rot_z
from bpms.io.frames import N_IMUS
from bpms.io.names import JOINT_ANGLE_NAMES

#: Named postures: ISB joint angles (docs/joint-angles.md), degrees; unnamed angles are 0.
#: ``suit``: a pressure-suit posture (shoulders abducted 20°, elbows 15°, hips 10° and knees 15°
#: flexed, ankles 5° dorsiflexed so the feet stand flat).
POSTURES: dict[str, dict[str, float]] = {
    "neutral": {},
    "suit": {"shoulder_r.abduction": 20.0, "shoulder_l.abduction": 20.0,
             "elbow_r.flexion": 15.0, "elbow_l.flexion": 15.0,
             "hip_r.flexion": 10.0, "hip_l.flexion": 10.0,
             "knee_r.flexion": 15.0, "knee_l.flexion": 15.0,
             "ankle_r.flexion": 5.0, "ankle_l.flexion": 5.0},
}

HIP, SPINE, NECK, HEAD = HIP_IMU, 8, 7, 17
#: (side, shoulder girdle, arm, forearm, hand) and (side, thigh, shank, foot), IMU ids.
ARMS = (("r", 15, 4, 5, 3), ("l", 16, 10, 11, 9))
LEGS = (("r", 0, 2, 1), ("l", 12, 14, 13))


def parse_posture(text: str | dict | None) -> dict[str, float]:
    """A declared posture: a preset name (:data:`POSTURES`), ``"joint.angle=deg,..."`` (ISB
    names, e.g. ``"elbow_r.flexion=15,knee_l.flexion=12"``) or a dict of them, degrees.
    Raises ValueError naming the choices."""
    if text is None:
        return {}
    if isinstance(text, dict):
        items = {str(k): float(v) for k, v in text.items()}
    elif str(text).strip().lower() in POSTURES:
        return dict(POSTURES[str(text).strip().lower()])
    else:
        items = {}
        for part in str(text).replace(";", ",").split(","):
            name, sep, value = part.partition("=")
            try:
                items[name.strip()] = float(value)
            except ValueError:
                sep = ""
            if not sep:
                raise ValueError(f"posture '{text}' is not one of {', '.join(POSTURES)} nor "
                                 "'joint.angle=deg,...' (e.g. 'elbow_r.flexion=15')") from None
    unknown = sorted(set(items) - set(JOINT_ANGLE_NAMES))
    if unknown:
        raise ValueError(f"posture: unknown joint angle(s) {', '.join(unknown)} "
                         "(names as in docs/joint-angles.md, e.g. knee_r.flexion)")
    bad = [k for k, v in items.items() if not np.isfinite(v) or abs(v) > 180.0]
    if bad:
        raise ValueError(f"posture: {', '.join(bad)} must be finite degrees within ±180")
    return items


def _joint(raw: dict[str, float], name: str) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` of ball joint ``name`` (raw Euler angles, rad)."""
    return euler_to_dcm(raw.get(f"{name}.abduction", 0.0), raw.get(f"{name}.flexion", 0.0),
                        raw.get(f"{name}.rotation", 0.0))


def posture_segments(posture: dict[str, float]) -> np.ndarray:
    """``P[18, 3, 3]``: each segment's orientation in the body-heading frame (pelvis upright,
    facing X) when the joints hold ``posture`` (ISB joint angles, degrees).

    The chain mirrors docs/joint-angles.md: a ball joint's angles are the Euler angles of
    ``C_staticᵀ C_dynamic`` (ISB values turned into raw ones by the sign table), the elbow
    bends the forearm forward and the knee the shank backward about the segments' right axis
    (Y); the shoulder girdles and the neck follow the mid spine, the hands the forearms."""
    signs = dict(zip(JOINT_ANGLE_NAMES, ISB_SIGNS, strict=True))
    raw = {k: np.radians(v) * signs[k] for k, v in posture.items()}
    P = np.tile(np.eye(3), (N_IMUS, 1, 1))
    P[SPINE] = P[HIP] @ _joint(raw, "torso")
    P[NECK] = P[SPINE]
    P[HEAD] = P[NECK] @ _joint(raw, "head")
    for side, girdle, arm, forearm, hand in ARMS:
        P[girdle] = P[SPINE]
        P[arm] = P[girdle] @ _joint(raw, f"shoulder_{side}")
        P[forearm] = P[arm] @ rot_y(raw.get(f"elbow_{side}.flexion", 0.0))
        P[hand] = P[forearm]
    for side, thigh, shank, foot in LEGS:
        P[thigh] = P[HIP] @ _joint(raw, f"hip_{side}")
        P[shank] = P[thigh] @ rot_y(-raw.get(f"knee_{side}.flexion", 0.0))
        P[foot] = P[shank] @ _joint(raw, f"ankle_{side}")
    return P


def posture_heading(R0: np.ndarray, P: np.ndarray, reference: str = "mean") -> float:
    """ψ0 (rad) from the window's DCMs ``R0[18, 3, 3]`` and the posture ``P``: the body's
    heading (:func:`bpms.filter.pose.body_heading`) of ``R0_i P_iᵀ``, the circular mean of
    their yaws over the IMUs with data (``"mean"``), or the hip's (``"hip"``). 0 when none
    has data."""
    heading = body_heading(R0 @ np.swapaxes(P, -1, -2), reference)
    return 0.0 if heading is None else heading


def posture_zero(R0: np.ndarray, posture: dict[str, float], reference: str = "mean"
                 ) -> tuple[np.ndarray, float]:
    """(``R0'[18, 3, 3]``, ψ0): the Reset Zero whose offset gives segment orientations
    ``Rz(ψ0) P_i`` at the window's DCMs ``R0`` (see the module docstring). NaN rows of ``R0``
    stay NaN."""
    R0 = np.asarray(R0, dtype=np.float64)
    P = posture_segments(posture)
    yaw0 = posture_heading(R0, P, reference)
    Rz = rot_z(yaw0)
    return Rz @ np.swapaxes(P, -1, -2) @ Rz.T @ R0, yaw0
