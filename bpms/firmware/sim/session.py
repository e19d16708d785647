"""Offline generation of a simulated recording with its ground truth.

>>> from bpms.firmware.sim.session import simulate
>>> rec = simulate(seed=1)          # the whole script, raw frames + truth
>>> rec.raw.shape[1:], len(rec.frames) == 340 * len(rec.t)
((18, 9), True)

Sample k is at ``t = k * 0.02`` s. See docs/simulated-suit.md for the script and the model.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from bpms.firmware.sim.body import POINTS, SubjectDimensions, point_positions
from bpms.firmware.sim.motion import (
    DT,
    TRUE_JOINT_NAMES,
    Motion,
    Step,
    generate_motion,
    true_joint_angles,
)
from bpms.firmware.sim.sensors import (
    MagDisturbance,
    SensorModel,
    SensorValues,
    draw_noise,
    heel_strike_spikes,
    ideal_sensors,
    inject_errors,
    magnet_field,
    to_raw,
)
from bpms.firmware.sim.sensors import mounting_errors as make_mounting_errors
from bpms.firmware.sim.subject import functional_script, parse_posture
from bpms.firmware.sim.table import TrueTable, table_2_2
from bpms.io.frames import encode_frames


@dataclass
class Truth:
    """Ground truth, sample by sample (N samples).

    R: ``[N, 18, 3, 3]`` true filter-frame DCM of each IMU (filter frame → world NED);
    C: ``[N, 18, 3, 3]`` segment orientations; E: ``[18, 3, 3]`` mounting errors (R = C E);
    joint_angles: ``[N, 28]`` rad, columns ``joint_names`` (the script's own degrees of
    freedom, raw Euler convention of ``C_staticᵀ C_dynamic``, hinge flexion ≥ 0);
    pelvis_position: ``[N, 3]`` m; imu_position / imu_acceleration: ``[N, 18, 3]`` m and m/s²
    (world, the latter including heel-strike impacts); heel_strikes: (time s, "left"/"right");
    sensors: noise-free physical filter-frame values (accel g, mag ±100 units, gyro rad/s)
    before the chip conversion, rounding and saturation.
    """

    R: np.ndarray
    C: np.ndarray
    E: np.ndarray
    joint_angles: np.ndarray
    pelvis_position: np.ndarray
    imu_position: np.ndarray
    imu_acceleration: np.ndarray
    heel_strikes: list[tuple[float, str]]
    sensors: SensorValues
    joint_names: tuple[str, ...] = TRUE_JOINT_NAMES
    #: ``[N, 21, 3]`` m, world NED: the skeleton's points (``point_names``, the pelvis first)
    #: where the simulated subject's own lengths put them (``dimensions``).
    joint_positions: np.ndarray | None = None
    point_names: tuple[str, ...] = POINTS
    dimensions: SubjectDimensions = field(default_factory=SubjectDimensions)
    #: The calibration posture held in the still windows, DOF → degrees ({}: neutral).
    posture: dict[str, float] = field(default_factory=dict)


@dataclass
class Recording:
    """A simulated recording: what the suit sends, and the truth behind it."""

    t: np.ndarray  # [N] s
    raw: np.ndarray  # int16 [N, 18, 9]
    errors: np.ndarray  # bool [N, 18, 3]
    frames: bytes  # N * 340
    truth: Truth
    still_windows: list[tuple[float, float]]
    phases: list[tuple[float, float, str]]
    calibration: TrueTable  # the true table the counts were made with
    disturbances: list[MagDisturbance] = field(default_factory=list)
    #: The sensor settings the counts were made with (noise, dip, accelerometer range, ...).
    model: SensorModel = field(default_factory=SensorModel)

    def __len__(self) -> int:
        return len(self.t)

    def save_raw(self, path: str | Path, start_time: float = 1.7e9,
                 notes: str = "simulated suit", subject_id: str | None = None) -> Path:
        """Write the frames as a native raw recording (receive time ``start_time + t`` s, the
        true calibration table and the accelerometer range in the header), as a live recording
        of this suit would be. ``subject_id``: also store the simulated subject's measured
        lengths as the header's subject profile (docs/subject.md's ``subject`` table)."""
        # The product's file container (the one writer of the format); no number of the
        # simulated suit goes through product code on the way (pyproject.toml's contract).
        from bpms.io.rawfile import new_header, write_raw

        path = Path(path)
        extra = ({"accel_range_g": float(self.model.accel_range_g)}
                 if getattr(self, "model", None) is not None else {})
        if subject_id is not None:
            dims = self.truth.dimensions
            extra["subject"] = {"id": subject_id, "height_m": float(dims.height),
                                "mass_kg": None, "segments_m": dims.lengths()}
        write_raw(path, start_time + self.t, self.frames,
                  new_header(calibration=self.calibration.values, notes=notes, extra=extra))
        return path


def default_disturbance(motion: Motion) -> MagDisturbance:
    """A magnet beside the right forearm during the elbow-flexion moves."""
    names = [p[2] for p in motion.phases]
    t0 = motion.phases[names.index("elbow flexion")][0] if "elbow flexion" in names else 10.0
    t1 = (motion.phases[names.index("arms relaxed")][1] if "arms relaxed" in names
          else t0 + 8.0)
    return magnet_near(motion, 5, t0, t1)  # the default offset: beside the right forearm


def magnet_near(motion: Motion, imu: int, t0: float, t1: float,
                offset: tuple[float, float, float] = (0.1, 0.15, 0.0), strength: float = 60.0,
                direction: tuple[float, float, float] = (0.0, 1.0, 0.0),
                radius: float = 0.2) -> MagDisturbance:
    """A magnet standing still from ``t0`` to ``t1`` s at ``offset`` (m, world NED) from where
    IMU ``imu`` is at ``t0``: ``strength`` (earth's field = 100) along ``direction`` (world),
    falling off over ``radius`` m (:class:`MagDisturbance`). :func:`default_disturbance` is
    ``magnet_near(motion, 5, <elbow flexion>, <arms relaxed>)``."""
    k = min(max(int(t0 / DT), 0), len(motion.t) - 1)
    pos = motion.imu_pos[k, imu] + np.asarray(offset, dtype=np.float64)
    return MagDisturbance(t0=t0, t1=t1, position=tuple(float(v) for v in pos),
                          strength=strength, radius=radius,
                          direction=tuple(float(v) for v in direction))


def simulate(duration_s: float | None = None, seed: int = 0, *, mag_disturbance: bool = False,
             mounting_errors: bool = True, noise: bool = True, error_rate: float = 0.0,
             calibration: TrueTable | None = None,
             model: SensorModel | None = None, heading_deg: float = 30.0,
             script: list[Step] | None = None,
             disturbances: list[MagDisturbance] | None = None,
             posture: str | dict | None = None, subject: SubjectDimensions | None = None,
             functional: bool = False, mounting_error_deg: float | None = None,
             ) -> Recording:
    """Generate a recording of the scripted motion.

    duration_s: None = the whole script (≈ 75 s); longer holds the final (calibration) pose.
    seed: seeds mounting errors, noise, gyro biases and injected errors (independently).
    mag_disturbance: add :func:`default_disturbance` (or ``disturbances`` when given).
    error_rate: probability per frame, IMU and sensor of a failed reading (error bit set).
    calibration: the suit's *true* calibration table, anything with ``values [18, 16]``
    (default: Table 2.2, read by :func:`.table.table_2_2`).
    model: sensor settings (dip, noise levels, gyro bias, mounting error size, heel strikes,
    the accelerometer's configured range ``accel_range_g``: ±16 g by default, as the firmware).
    heading_deg: the subject's initial magnetic heading (yaw of the pelvis), degrees.
    posture: the calibration posture (:func:`.subject.parse_posture`: ``neutral``, ``suit``,
    ``"dof=deg,..."`` or a dict), held wherever the script is still or at rest.
    subject: the subject's dimensions (default: Table 2.4's, 1.73 m).
    functional: put the functional-calibration movements (:func:`.subject.functional_script`)
    in front of the script.
    mounting_error_deg: rms per axis of the IMUs' mounting misalignment, ° (default: the
    model's, 3°).
    """
    model = model or SensorModel()
    if mounting_error_deg is not None:
        model = replace(model, mounting_error_deg=float(mounting_error_deg))
    rest = parse_posture(posture)
    dims = subject or SubjectDimensions()
    if functional:
        script = functional_script(script)
    table = calibration if calibration is not None else table_2_2()
    n = None if duration_s is None else max(round(duration_s / DT), 1)
    motion = generate_motion(n, script=script, heading_deg=heading_deg, body=dims,
                             posture=rest)
    base = np.random.SeedSequence(seed)
    rng_mount, rng_noise, rng_bias, rng_err = (np.random.default_rng(s) for s in base.spawn(4))
    E = (make_mounting_errors(rng_mount, model.mounting_error_deg) if mounting_errors
         else np.broadcast_to(np.eye(3), (18, 3, 3)).copy())
    R = motion.C @ E
    acc_lin = motion.imu_acc + heel_strike_spikes(motion.t, motion.heel_strikes,
                                                  motion.imu_acc, model, DT)
    dist: list[MagDisturbance] = []
    if mag_disturbance:
        dist = list(disturbances) if disturbances else [default_disturbance(motion)]
    extra = magnet_field(motion.t, motion.imu_pos, dist) if dist else None
    ideal = ideal_sensors(R, acc_lin, model.dip_deg, extra, DT)
    drawn = draw_noise(len(motion.t), model, rng_noise, rng_bias) if noise else None
    raw = to_raw(ideal, table, model, drawn)
    raw, errors = inject_errors(raw, error_rate, rng_err)
    truth = Truth(
        R=R, C=motion.C, E=E, joint_angles=true_joint_angles(motion.dofs),
        pelvis_position=motion.pelvis, imu_position=motion.imu_pos,
        imu_acceleration=acc_lin, heel_strikes=motion.heel_strikes, sensors=ideal,
        joint_positions=point_positions(motion.C, dims) + motion.pelvis[:, None, :],
        dimensions=dims, posture=rest,
    )
    return Recording(
        t=motion.t, raw=raw, errors=errors, frames=encode_frames(raw, errors), truth=truth,
        still_windows=motion.still_windows, phases=motion.phases, calibration=table,
        disturbances=dist, model=model,
    )

