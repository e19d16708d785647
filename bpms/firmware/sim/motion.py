"""Scripted body motion for the simulated suit: exact segment orientations and positions.

The script is a list of moves between poses. A pose is a set of joint degrees of freedom
(:data:`DOFS`, radians, 0 = the calibration pose); each move goes from the current pose to a
target pose with a minimum-jerk profile, so velocities and accelerations start and end at 0.
A walk section drives the legs analytically (alternating steps, heel strikes at known times).

Segment orientations ``C[N, 18, 3, 3]`` (segment axes → world NED) are built by composing joint
rotations down the chain (pelvis heading and tilt, then ``child = parent @ joint``), so the
true joint angles are the script's own degrees of freedom (:func:`true_joint_angles`), not a
computation from ``C``. Positions come from the simulated skeleton (:mod:`.body`) plus a
pelvis trajectory; the IMUs sit at the middle of their segments. Nothing here comes from
the filter package: the simulated suit is the independent truth the filter is tested against.

Joint signs (``zyx(roll, pitch, yaw)`` of the joint, so the truth angles equal them):
shoulder/hip ``flex`` > 0 swings the limb forward; right shoulder ``abd`` < 0 and left > 0 raise
the arm sideways; elbow/knee flexion are positive angles; ``torso_flex`` < 0 bends forward;
``ankle`` > 0 lifts the toes; ``head_turn`` > 0 turns the head to the right (yaw).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bpms.firmware.sim.body import POINT, SubjectDimensions, imu_positions, point_positions
from bpms.firmware.sim.geometry import zyx
from bpms.io.frames import FRAME_PERIOD_S, N_IMUS

DT = FRAME_PERIOD_S  # s, sample k is at t = k * DT

#: Degrees of freedom of the scripted body, radians.
DOFS: tuple[str, ...] = (
    "pelvis_turn", "pelvis_tilt", "pelvis_roll",
    "torso_flex", "torso_lat", "torso_rot",
    "neck_flex", "head_nod", "head_turn",
    "sh_r_flex", "sh_r_abd", "sh_r_rot", "elbow_r", "wrist_r",
    "sh_l_flex", "sh_l_abd", "sh_l_rot", "elbow_l", "wrist_l",
    "hip_r_flex", "hip_r_abd", "knee_r", "ankle_r",
    "hip_l_flex", "hip_l_abd", "knee_l", "ankle_l",
)
DOF_INDEX = {name: i for i, name in enumerate(DOFS)}
_D = np.pi / 180.0


def min_jerk(tau: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile 0 → 1 for ``tau`` in [0, 1] (clipped outside)."""
    tau = np.clip(tau, 0.0, 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


@dataclass(frozen=True)
class Move:
    """Go to ``target`` (DOF → degrees; unnamed DOFs return to 0) over ``duration`` s, then
    hold for ``hold`` s. ``keep`` leaves unnamed DOFs where they are instead."""

    name: str
    duration: float
    target: dict[str, float] = field(default_factory=dict)
    hold: float = 0.0
    keep: bool = False


@dataclass(frozen=True)
class Walk:
    """Walk straight ahead along the pelvis heading for ``steps`` steps of ``step_period`` s.

    Hip flexion swings ±``hip_amp_deg`` (opposite legs), the swing knee bends up to
    ``knee_deg``, the arms swing ±``arm_deg``. The first and last step ramp the amplitude in
    and out (minimum jerk), so the walk starts and ends still in the calibration pose.
    """

    name: str = "walk"
    steps: int = 10
    step_period: float = 0.9
    hip_amp_deg: float = 12.0
    knee_deg: float = 15.0
    arm_deg: float = 6.0


@dataclass(frozen=True)
class Still:
    """Stay still in the calibration pose for ``duration`` s."""

    name: str
    duration: float


Step = Move | Walk | Still


def default_script() -> list[Step]:
    """The standard trial: still, arm raises, elbows, trunk, squats, head, walk, still."""
    return [
        Still("still (start)", 3.0),
        Move("right arm forward raise", 2.0, {"sh_r_flex": 60}, hold=0.5),
        Move("right arm down", 2.0, hold=0.3),
        Move("left arm forward raise", 2.0, {"sh_l_flex": 60}, hold=0.5),
        Move("left arm down", 2.0, hold=0.3),
        Move("both arms side raise", 2.0, {"sh_r_abd": -80, "sh_l_abd": 80}, hold=0.5),
        Move("both arms down", 2.0, hold=0.3),
        Move("elbow flexion", 1.5, {"elbow_r": 100, "elbow_l": 100}, hold=0.5),
        Move("elbows extended", 1.5, hold=0.3),
        Move("shoulder rotation + elbows", 1.5,
             {"elbow_r": 90, "elbow_l": 90, "sh_r_rot": 40, "sh_l_rot": -40}, hold=0.3),
        Move("arms relaxed", 1.5, hold=0.3),
        Move("trunk bend forward", 2.0, {"torso_flex": -40, "neck_flex": -10}, hold=0.5),
        Move("trunk upright", 2.0, hold=0.3),
        Move("trunk bend right", 2.0, {"torso_lat": 20}, hold=0.3),
        Move("trunk bend left", 2.0, {"torso_lat": -20}, hold=0.3),
        Move("trunk twist", 2.0, {"torso_rot": 30}, hold=0.3),
        Move("trunk neutral", 2.0, hold=0.5),
        *_squat(1), *_squat(2),
        Move("head turn left", 1.5, {"head_turn": -60}, hold=0.3),
        Move("head turn right", 2.0, {"head_turn": 60}, hold=0.3),
        Move("head nod", 1.5, {"head_nod": -30, "neck_flex": -10}, hold=0.3),
        Move("head neutral", 1.5, hold=0.3),
        Move("turn to walk", 2.0, {"pelvis_turn": -30}, hold=0.5),
        Walk(),
        Move("turn back", 2.0, hold=0.0),
        Still("still (end)", 3.0),
    ]


def _squat(k: int) -> list[Move]:
    # Thigh 40° forward of vertical, shank 30° back: foot flat (ankle = knee - thigh).
    deep = {"pelvis_tilt": -15, "torso_flex": -10, "hip_r_flex": 55, "hip_l_flex": 55,
            "knee_r": 70, "knee_l": 70, "ankle_r": 30, "ankle_l": 30,
            "sh_r_flex": 45, "sh_l_flex": 45}
    return [Move(f"squat {k} down", 2.0, deep, hold=0.5), Move(f"squat {k} up", 2.0, hold=0.5)]


@dataclass
class Motion:
    """Sampled ground truth of a script: N samples at ``t = k * DT``.

    C: ``[N, 18, 3, 3]`` segment orientations (segment axes → world NED);
    dofs: ``[N, len(DOFS)]`` rad; pelvis: ``[N, 3]`` m NED; imu_pos: ``[N, 18, 3]`` m NED;
    imu_acc: ``[N, 18, 3]`` m/s² world linear acceleration of each IMU (second differences);
    heel_strikes: (time s, "left"/"right"); phases: (t0, t1, name);
    still_windows: (t0, t1) still in the calibration pose.
    """

    t: np.ndarray
    C: np.ndarray
    dofs: np.ndarray
    pelvis: np.ndarray
    imu_pos: np.ndarray
    imu_acc: np.ndarray
    heel_strikes: list[tuple[float, str]]
    phases: list[tuple[float, float, str]]
    still_windows: list[tuple[float, float]]


def script_duration(script: list[Step]) -> float:
    """Length of a script, s."""
    total = 0.0
    for step in script:
        if isinstance(step, Walk):
            total += (step.steps + 1) * step.step_period
        elif isinstance(step, Move):
            total += step.duration + step.hold
        else:
            total += step.duration
    return total


def _dof_track(script: list[Step], t: np.ndarray, heading0: float, body: SubjectDimensions):
    """DOFs ``[N, D]`` rad, pelvis walk offset ``[N, 3]``, heel strikes, phases."""
    n = len(t)
    dofs = np.zeros((n, len(DOFS)))
    walk_xy = np.zeros((n, 2))  # forward distance walked, m, in the heading direction
    walk_mask = np.zeros(n, dtype=bool)
    walk_z = np.zeros(n)  # pelvis drop below its upright height in the walk, m (z down)
    strikes: list[tuple[float, str]] = []
    phases: list[tuple[float, float, str]] = []
    current = np.zeros(len(DOFS))
    walked = np.zeros(2)
    t0 = 0.0
    leg = body.thigh + body.shank
    for step in script:
        if isinstance(step, Walk):
            t1 = t0 + (step.steps + 1) * step.step_period
        else:
            t1 = t0 + step.duration + (step.hold if isinstance(step, Move) else 0.0)
        sel = (t >= t0) & (t < t1)
        phases.append((t0, t1, step.name))
        if isinstance(step, Still):
            dofs[sel] = current
            walk_xy[sel] = walked
        elif isinstance(step, Move):
            target = current.copy() if step.keep else np.zeros(len(DOFS))
            for name, deg in step.target.items():
                target[DOF_INDEX[name]] = deg * _D
            s = min_jerk((t[sel] - t0) / step.duration)
            dofs[sel] = current + s[:, None] * (target - current)
            walk_xy[sel] = walked
            current = target
        else:
            if not sel.any():  # the recording ends before the walk
                t0 = t1
                continue
            tt = t[sel] - t0
            period = step.step_period
            omega = np.pi / period  # hip angle = A sin(omega (t - t0)): one step per half cycle
            ramp_in = min_jerk(tt / period)
            ramp_out = min_jerk((t1 - t0 - tt) / period)
            env = ramp_in * ramp_out
            amp = step.hip_amp_deg * _D
            hip_r = amp * env * np.sin(omega * tt)
            # Swing knee: a sin² bump during the leg's swing (its hip angle rising), zero at
            # the heel strikes (hip angle extremes), so the landing leg is straight.
            phase = np.mod(omega * tt, 2 * np.pi)
            knee_amp = step.knee_deg * _D * env
            swing_r = (phase >= 3 * np.pi / 2) | (phase < np.pi / 2)
            bump = np.sin(np.mod(phase + np.pi / 2, np.pi)) ** 2
            base = current.copy()
            d = dofs[sel]
            d[:] = base
            d[:, DOF_INDEX["hip_r_flex"]] = hip_r
            d[:, DOF_INDEX["hip_l_flex"]] = -hip_r
            d[:, DOF_INDEX["knee_r"]] = np.where(swing_r, knee_amp * bump, 0.0)
            d[:, DOF_INDEX["knee_l"]] = np.where(~swing_r, knee_amp * bump, 0.0)
            d[:, DOF_INDEX["sh_r_flex"]] = -step.arm_deg * _D * env * np.sin(omega * tt)
            d[:, DOF_INDEX["sh_l_flex"]] = step.arm_deg * _D * env * np.sin(omega * tt)
            dofs[sel] = d
            # Heel strikes: hip angle extremes, the leading leg straight. Pelvis speed matches
            # the step length there (the distance between the ankles along the heading).
            speed = 2.0 * leg * np.sin(amp * env) / period
            dist = np.cumsum(speed) * DT - speed[0] * DT
            heading = heading0 + current[DOF_INDEX["pelvis_turn"]]
            direction = np.array([np.cos(heading), np.sin(heading)])
            walk_xy[sel] = walked + dist[:, None] * direction
            walk_mask[sel] = True
            walk_z[sel] = leg * (1.0 - np.cos(hip_r))  # stance leg straight, ankle on ground
            for k in range(1, step.steps + 1):
                ts = round(t0 + (k - 0.5) * period, 6)
                strikes.append((ts, "right" if k % 2 == 1 else "left"))
            walked = walked + (dist[-1] + speed[-1] * DT) * direction
            current = base
        t0 = t1
    after = t >= t0
    dofs[after] = current
    walk_xy[after] = walked
    return dofs, walk_xy, walk_z, walk_mask, strikes, phases


def segment_orientations(dofs: np.ndarray, heading0: float) -> np.ndarray:
    """``[N, 18, 3, 3]`` segment orientations from DOFs ``[N, D]`` (rad)."""
    n = len(dofs)

    def q(name: str) -> np.ndarray:
        return dofs[:, DOF_INDEX[name]]

    # each joint is zyx(roll, pitch, yaw) of its DOFs (0 where it has none: broadcast)
    C = np.empty((n, N_IMUS, 3, 3))
    pelvis = zyx(q("pelvis_roll"), q("pelvis_tilt"), heading0 + q("pelvis_turn"))
    spine = pelvis @ zyx(q("torso_lat"), q("torso_flex"), q("torso_rot"))
    neck = spine @ zyx(0.0, q("neck_flex"), 0.0)
    head = neck @ zyx(0.0, q("head_nod"), q("head_turn"))
    C[:, 6], C[:, 8], C[:, 7], C[:, 17] = pelvis, spine, neck, head
    for side, sh, arm, fore, hand in (("r", 15, 4, 5, 3), ("l", 16, 10, 11, 9)):
        C[:, sh] = spine
        C[:, arm] = spine @ zyx(q(f"sh_{side}_abd"), q(f"sh_{side}_flex"), q(f"sh_{side}_rot"))
        C[:, fore] = C[:, arm] @ zyx(0.0, q(f"elbow_{side}"), 0.0)
        C[:, hand] = C[:, fore] @ zyx(0.0, q(f"wrist_{side}"), 0.0)
    for side, thigh, shank, foot in (("r", 0, 2, 1), ("l", 12, 14, 13)):
        C[:, thigh] = pelvis @ zyx(q(f"hip_{side}_abd"), q(f"hip_{side}_flex"), 0.0)
        C[:, shank] = C[:, thigh] @ zyx(0.0, -q(f"knee_{side}"), 0.0)
        C[:, foot] = C[:, shank] @ zyx(0.0, q(f"ankle_{side}"), 0.0)
    return C


def _still_windows(dofs: np.ndarray, pelvis: np.ndarray, t: np.ndarray,
                   min_s: float = 1.0, rest: np.ndarray | None = None,
                   ) -> list[tuple[float, float]]:
    """Windows ≥ ``min_s`` where every DOF except the heading is at the calibration posture
    ``rest`` (default 0: the neutral pose) and nothing moves."""
    off = dofs if rest is None else dofs - rest
    posture = np.abs(np.delete(off, DOF_INDEX["pelvis_turn"], axis=1)).max(axis=1) < 1e-9
    moving = np.zeros(len(t), dtype=bool)
    moving[1:] |= np.abs(np.diff(dofs, axis=0)).max(axis=1) > 1e-12
    moving[1:] |= np.abs(np.diff(pelvis, axis=0)).max(axis=1) > 1e-12
    moving[:-1] |= moving[1:].copy()
    ok = posture & ~moving
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))  # run starts, ends (past)
    return [(float(t[a]), float(t[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)
            if t[b - 1] - t[a] >= min_s]


def generate_motion(n_samples: int | None = None, *, script: list[Step] | None = None,
                    heading_deg: float = 30.0, body: SubjectDimensions | None = None,
                    posture: dict[str, float] | None = None) -> Motion:
    """Sample the script at 50 Hz. ``n_samples`` None = the whole script; beyond its end the
    final pose is held. ``heading_deg`` is the subject's initial magnetic heading (yaw).
    ``posture``: the calibration posture (DOF → degrees, :mod:`.subject`), added to every
    DOF of the script: the script's 0 (its still windows, "arms down") is this posture."""
    script = default_script() if script is None else script
    body = body or SubjectDimensions()
    if n_samples is None:
        n_samples = round(script_duration(script) / DT)
    t = np.arange(n_samples) * DT
    heading0 = heading_deg * _D
    dofs, walk_xy, walk_z, walk_mask, strikes, phases = _dof_track(script, t, heading0, body)
    rest = None
    if posture:
        rest = np.zeros(len(DOFS))
        for name, deg in posture.items():
            rest[DOF_INDEX[name]] = deg * _D
        dofs = dofs + rest
    C = segment_orientations(dofs, heading0)
    pts = point_positions(C, body)  # [N, 21, 3], pelvis at the origin
    ankles = pts[:, [POINT["ankle_r"], POINT["ankle_l"]]]
    # Off the walk, the ankles' midpoint stays on its spot on the ground (z = 0), which moves
    # the pelvis in squats; in the walk, the pelvis travels at the step speed and rides the
    # straight stance leg (its ankle on the ground).
    pelvis = np.zeros((n_samples, 3))
    pelvis[:, :2] = walk_xy - ankles[:, :, :2].mean(axis=1) * ~walk_mask[:, None]
    leg = body.thigh + body.shank
    if rest is None:
        pelvis[:, 2] = np.where(walk_mask, -leg + walk_z, -ankles[:, :, 2].mean(axis=1))
    else:  # bent legs: the lower ankle on the ground in the walk (no jump where it starts)
        pelvis[:, 2] = np.where(walk_mask, -ankles[:, :, 2].max(axis=1),
                                -ankles[:, :, 2].mean(axis=1))
    imu_pos = pelvis[:, None, :] + imu_positions(pts)
    imu_acc = np.zeros_like(imu_pos)
    if n_samples >= 3:
        imu_acc[1:-1] = (imu_pos[2:] - 2 * imu_pos[1:-1] + imu_pos[:-2]) / DT**2
    end = float(n_samples * DT)
    return Motion(
        t=t, C=C, dofs=dofs, pelvis=pelvis, imu_pos=imu_pos, imu_acc=imu_acc,
        heel_strikes=[s for s in strikes if s[0] < end],
        phases=[(a, min(b, end), name) for a, b, name in phases if a < end],
        still_windows=_still_windows(dofs, pelvis, t, rest=rest),
    )


#: Names of :func:`true_joint_angles`' columns: the four hinges' flexion, then roll, pitch and
#: yaw (abduction, flexion, rotation) of ``C_staticᵀ C_dynamic`` of the eight ball joints.
TRUE_JOINT_NAMES: tuple[str, ...] = (
    "elbow_r.flexion", "elbow_l.flexion", "knee_r.flexion", "knee_l.flexion",
    *(f"{j}.{c}" for j in ("shoulder_r", "shoulder_l", "hip_r", "hip_l", "ankle_r", "ankle_l",
                           "torso", "head")
      for c in ("abduction", "flexion", "rotation")),
)

#: Each column of :data:`TRUE_JOINT_NAMES` as (sign, DOF) of the script, or None (always 0).
#: The chain builds every joint as ``zyx(roll, pitch, yaw)`` of its DOFs, so its Euler angles
#: are those DOFs; the hinge angle between the two long axes is the DOF's magnitude.
_JOINT_DOFS: tuple[str | None, ...] = (
    "elbow_r", "elbow_l", "knee_r", "knee_l",
    "sh_r_abd", "sh_r_flex", "sh_r_rot",
    "sh_l_abd", "sh_l_flex", "sh_l_rot",
    "hip_r_abd", "hip_r_flex", None,
    "hip_l_abd", "hip_l_flex", None,
    None, "ankle_r", None,
    None, "ankle_l", None,
    "torso_lat", "torso_flex", "torso_rot",
    None, "head_nod", "head_turn",
)


#: The clinical (ISB) sense of each column, from anatomy and the segment axes (X forward,
#: Y right, Z down in the calibration pose), worked out here on its own:
#:
#: - a sideways raise turns a hanging limb (+Z) towards +Y on the right (a negative roll) and
#:   towards −Y on the left (a positive roll): abduction = −roll on the right, +roll on the left;
#: - a positive pitch swings a hanging limb forward (+Z towards +X) and the toes up (+X towards
#:   −Z): flexion and dorsiflexion = +pitch on both sides;
#: - with the elbow bent, a positive yaw turns the forearm (+X) towards +Y: lateral for the
#:   right arm, medial for the left: external rotation = +yaw right, −yaw left;
#: - the trunk and head point up (−Z): a positive roll tips them to the right (lateral bending to
#:   the right, positive in ISB), a positive pitch tips them backward (forward flexion = −pitch),
#:   a positive yaw turns them to the right (axial rotation to the left = −yaw).
_ISB_SENSE: dict[str, float] = {
    "shoulder_r.abduction": -1.0, "shoulder_l.abduction": 1.0,
    "hip_r.abduction": -1.0, "hip_l.abduction": 1.0,
    "ankle_r.abduction": -1.0, "ankle_l.abduction": 1.0,
    "shoulder_r.rotation": 1.0, "shoulder_l.rotation": -1.0,
    "hip_r.rotation": 1.0, "hip_l.rotation": -1.0,
    "ankle_r.rotation": 1.0, "ankle_l.rotation": -1.0,
    "torso.flexion": -1.0, "torso.rotation": -1.0,
    "head.flexion": -1.0, "head.rotation": -1.0,
}


def true_joint_angles(dofs: np.ndarray, convention: str = "isb") -> np.ndarray:
    """``[N, 28]`` rad, columns :data:`TRUE_JOINT_NAMES`, straight from the script's DOFs
    ``[N, len(DOFS)]``: hinge flexions are ``|DOF|``; ball joints are (roll, pitch, yaw) of
    ``C_staticᵀ C_dynamic`` (valid while every joint pitch stays within ±90°, as in every
    script here), in the clinical sense (``convention="isb"``, :data:`_ISB_SENSE`) or as raw
    Euler angles (``"original"``)."""
    dofs = np.asarray(dofs, dtype=np.float64)
    out = np.zeros((len(dofs), len(TRUE_JOINT_NAMES)))
    for col, name in enumerate(_JOINT_DOFS):
        if name is not None:
            out[:, col] = dofs[:, DOF_INDEX[name]]
    out[:, :4] = np.abs(out[:, :4])
    if convention == "isb":
        out *= np.array([_ISB_SENSE.get(name, 1.0) for name in TRUE_JOINT_NAMES])
    elif convention != "original":
        raise ValueError(f"convention must be 'isb' or 'original', not {convention!r}")
    return out
