"""The headless processor (the original "IMU class"): raw counts → orientations, joint angles
and a stick figure, for batches (whole recordings) and live frames. No Qt, no real-time pacing.

Example::

    from bpms.filter.processor import BodyPoseProcessor

    proc = BodyPoseProcessor(calibration="Calib.cfg", options="options.toml")
    result = proc.process_file("Raw_trial_001.bpmsraw")   # or proc.process(raw[N, 18, 9])
    result.euler            # [N, 18, 3] roll, pitch, yaw of every IMU, rad
    result.joint_angles     # [N, 28] rad, names in bpms.filter.joints.JOINT_ANGLE_NAMES
    result.joint_positions  # [N, 21, 3] m, NED, names in bpms.filter.body_model.POINT_NAMES

    live = BodyPoseProcessor()
    for raw, errors in frames:                   # raw [18, 9] int16, errors [18, 3] bool
        frame = live.step(raw, errors)           # a Result with N = 1
        if operator_pressed_reset_zero:
            live.reset_zero()                    # captured at the next frame

What happens, frame by frame (details in docs/filter.md):

- raw counts → calibrated filter units (:class:`bpms.filter.calibration.SensorCalibration`);
- 18 attitude filters of the kind ``Options.filter.algorithm`` selects
  (:mod:`bpms.filter.algorithms`; default the DCM Mahony :class:`bpms.filter.bank.FilterBank`):
  the first frame of a stream only initialises; failed sensors hold their last good value;
- Reset Zero (:class:`bpms.filter.pose.PoseCalibrator`): a provisional one-frame capture on the
  first frame where all 18 IMUs are initialised, the automatic capture 1.0 s into the stream
  (0.5 s settling + the ``Options.pose.reset_window_s`` window, averaged), and one on each
  request; segment orientations ``C = R R0^T Rz(ψ0)``;
- joint angles and stick-figure joint positions (per-subject lengths ``Options.body``).

The first frame given after construction or :meth:`BodyPoseProcessor.restart` is the first
frame of the stream: dropping the stale first frame after a pause (SPEC §3) is the job of the
acquisition layer, which does not record it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from bpms.filter.algorithms import make_bank
from bpms.filter.calibration import GYRO_RAD_S_PER_COUNT, SensorCalibration
from bpms.filter.mahony import calibrate_batch
from bpms.filter.pose import PoseCalibrator, Zero, body_outputs
from bpms.filter.rotations import dcm_to_quaternion
from bpms.io.calib_file import CalibrationTable, load_calibration
from bpms.io.frames import N_CHANNELS, N_IMUS
from bpms.io.options import BodyOptions, Options, load_options
from bpms.io.timebase import stream_times

#: Seconds the filters settle after the stream starts before the automatic Reset Zero window.
SETTLE_S = 0.5


@dataclass
class Result:
    """Outputs of N frames. Angles in radians, lengths in metres, frames as SPEC §5/§6.

    t: ``[N]`` s since the stream started, on the fixed filter clock (frame index × dt);
    R: ``[N, 18, 3, 3]`` DCM filter frame → NED; euler: ``[N, 18, 3]`` (roll, pitch, yaw);
    C: ``[N, 18, 3, 3]`` segment orientations after Reset Zero (NaN before the first capture);
    joint_angles: ``[N, 28]``; joint_positions: ``[N, 21, 3]``; NaN where an IMU involved is
    not initialised. held_count: ``[18, 3]`` filter steps so far that used a held value.
    calibration_source / options_source: which calibration and options were used (whole
    recordings opened through :mod:`bpms.filter.door`).
    """

    t: np.ndarray
    R: np.ndarray
    euler: np.ndarray
    C: np.ndarray
    body: BodyOptions = field(repr=False, default_factory=BodyOptions)
    held_count: np.ndarray = field(default_factory=lambda: np.zeros((N_IMUS, 3), np.int64))
    zeros: list[Zero] = field(default_factory=list, repr=False)
    problems: list[str] = field(default_factory=list)
    #: Where the calibration / options came from (set by the one door, bpms.filter.door).
    calibration_source: str = field(default="", repr=False)
    options_source: str = field(default="", repr=False)

    def __len__(self) -> int:
        return len(self.t)

    @cached_property
    def _body(self) -> tuple[np.ndarray, np.ndarray]:
        return body_outputs(self.C, self.body)

    @property
    def joint_angles(self) -> np.ndarray:
        """``[N, 28]`` rad, order :data:`bpms.filter.joints.JOINT_ANGLE_NAMES`."""
        return self._body[0]

    @property
    def joint_positions(self) -> np.ndarray:
        """``[N, 21, 3]`` m, order :data:`bpms.filter.body_model.POINT_NAMES`."""
        return self._body[1]

    @cached_property
    def quaternions(self) -> np.ndarray:
        """``[N, 18, 4]`` (w, x, y, z) of the filter DCMs ``R``."""
        return _quaternions(self.R)

    @cached_property
    def segment_quaternions(self) -> np.ndarray:
        """``[N, 18, 4]`` (w, x, y, z) of the segment orientations ``C``."""
        return _quaternions(self.C)


def _quaternions(R: np.ndarray) -> np.ndarray:
    ok = np.isfinite(R).all(axis=(-1, -2))
    out = np.full((*R.shape[:-2], 4), np.nan)
    if ok.any():
        out[ok] = dcm_to_quaternion(R[ok])
    return out


def _load_table(calibration: str | Path | CalibrationTable | None) -> CalibrationTable:
    if isinstance(calibration, CalibrationTable):
        return calibration
    return load_calibration(calibration)


def _load_options(options: str | Path | Options | None) -> Options:
    if isinstance(options, Options):
        return options
    return load_options(options)


class BodyPoseProcessor:
    """Raw frames in, orientations / joint angles / joint positions out.

    calibration: None (factory table), a ``Calib.cfg`` path or a CalibrationTable.
    options: None (factory options), an options-file path or an Options object.
    auto_zero: run the provisional and automatic Reset Zero at the start of the stream.
    Problems with the files are in ``.problems`` (never raised).
    """

    def __init__(self, calibration: str | Path | CalibrationTable | None = None,
                 options: str | Path | Options | None = None, auto_zero: bool = True) -> None:
        # What the caller chose (None = not given): process_file's precedence starts here.
        self._given = (calibration, options)
        self.table = _load_table(calibration)
        self.options = _load_options(options)
        ellipsoids = {}
        if isinstance(calibration, str | Path):
            # A magnetometer ellipsoid fit in the modern companion file (Calib.json beside
            # Calib.cfg, docs/calibration.md) is used for the IMUs whose numbers agree.
            from bpms.io.calib_modern import ellipsoids_beside

            ellipsoids, _, problems = ellipsoids_beside(calibration, self.table)
            self.table.problems.extend(problems)
        self.sensor_calibration = SensorCalibration.from_table(self.table, self.options.sensors,
                                                               ellipsoids or None)
        # options.filter.algorithm: 'mahony' (FilterBank, the original) or another filter
        self.bank = make_bank(self.sensor_calibration.gravity, self.options.filter)
        cal = self.sensor_calibration
        self._cal_params = tuple(np.ascontiguousarray(v, dtype=np.float64) for v in (
            cal.accel_offset, cal.accel_scale * cal.accel_signs, cal.mag_offset,
            cal.mag_scale * cal.mag_signs, cal.gyro_avg,
            np.broadcast_to(GYRO_RAD_S_PER_COUNT * cal.gyro_signs, (N_IMUS, 3)),
            cal.pre_rotations))
        dt = self.options.filter.dt
        self.pose = PoseCalibrator(window=round(self.options.pose.reset_window_s / dt),
                                   settle=round(SETTLE_S / dt), auto=auto_zero,
                                   heading=self.options.pose.heading_reference)
        self.frames = 0
        self.problems = [str(p) for p in (*self.table.problems, *self.options.problems)]

    # -- controls -----------------------------------------------------------------------
    def restart(self) -> None:
        """A new stream: every filter re-initialises on its next valid frame, Reset Zero
        forgets its capture and the automatic captures run again."""
        self.bank.reset()
        self.pose.restart()
        self.frames = 0

    def reset_filter(self, imu: int | None = None) -> None:
        """Re-initialise one IMU's filter (all when None) at its next valid frame."""
        self.bank.reset(imu)

    def reset_zero(self) -> None:
        """Reset Zero: capture at the next frame, averaged over the window ending there."""
        self.pose.request()

    def set_gains(self, **gains: float) -> None:
        """Change ``kp_rollpitch``, ``ki_rollpitch``, ``kp_yaw``, ``ki_yaw``, ``dt`` (s)
        from the next frame on (Mahony); the other filters take their
        :class:`bpms.io.options.FilterOptions` names (``observer_k_incl``, ``vqf_tau_acc_s``,
        ...)."""
        self.bank.set_gains(**gains)

    def select_filter(self, algorithm: str) -> None:
        """Switch all 18 IMUs to another attitude filter (``FilterOptions.algorithm``
        choices); the new filters align on their next valid frame, Reset Zero is kept.
        Raises ValueError for an unknown name, ``VqfMissingError`` without the vqf package."""
        from dataclasses import replace

        options = replace(self.options.filter, algorithm=algorithm)
        self.bank = make_bank(self.sensor_calibration.gravity, options)
        self.options.filter = options

    # -- running ------------------------------------------------------------------------
    def calibrate(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw ``[N, 18, 9]`` counts → filter inputs (accel, mag, gyro) ``[N, 18, 3]``: the
        numbers of ``SensorCalibration.calibrate`` (same formula and parameters), computed in
        one compiled pass."""
        raw = np.asarray(raw)
        if raw.dtype != np.int16 or not raw.flags.c_contiguous:
            raw = np.ascontiguousarray(raw, dtype=np.float64)
        outs = tuple(np.empty((raw.shape[0], N_IMUS, 3)) for _ in range(3))
        calibrate_batch(raw, *self._cal_params, *outs)
        if self.sensor_calibration.mag_correction() is not None:
            outs[1][:] = self.sensor_calibration.correct_mag(outs[1])
        return outs
    def _result(self, n: int, R: np.ndarray, euler: np.ndarray, C: np.ndarray,
                captures_before: int) -> Result:
        t = stream_times(self.frames, n, self.options.filter.dt)
        self.frames += n
        return Result(t=t, R=R, euler=euler, C=C, body=self.options.body,
                      held_count=self.bank.held_count, zeros=self.pose.captures[captures_before:])

    def process(self, raw: np.ndarray, errors: np.ndarray | None = None,
                zero_at: list[int] | tuple[int, ...] = ()) -> Result:
        """Filter N frames (``raw[N, 18, 9]`` counts, ``errors[N, 18, 3]`` bool) in one pass,
        continuing the stream of earlier calls. ``zero_at``: frame indices (into this batch)
        where Reset Zero captures happen, e.g. to re-zero replayed data."""
        raw = np.asarray(raw)
        if raw.ndim != 3 or raw.shape[1:] != (N_IMUS, N_CHANNELS):
            raise ValueError(f"raw must be [N, {N_IMUS}, {N_CHANNELS}], got {raw.shape}")
        acc, mag, gyr = self.calibrate(raw)
        out = self.bank.process(acc, mag, gyr, errors=errors)
        before = len(self.pose.captures)
        C = self.pose.apply(out.R, zero_at)
        return self._result(len(raw), out.R, out.euler, C, before)

    def step(self, raw: np.ndarray, errors: np.ndarray | None = None) -> Result:
        """Filter one live frame (``raw[18, 9]``, ``errors[18, 3]``); a Result with N = 1."""
        acc, mag, gyr = self.calibrate(np.asarray(raw)[None])
        out = self.bank.step(acc[0], mag[0], gyr[0], errors)
        before = len(self.pose.captures)
        C = self.pose.apply(out.R[None])
        return self._result(1, out.R[None], out.euler[None], C, before)

    def process_file(self, path: str | Path, zero_at: list[int] | tuple[int, ...] = ()) -> Result:
        """Filter a whole recording (native raw, legacy pickled raw, or a filtered CSV) as one
        new stream, through the one door (:func:`bpms.filter.door.open_for_processing`): the
        calibration and options given to this processor's constructor, else the recording's
        header, else the user's default, else factory. The result says which in
        ``calibration_source`` / ``options_source``; this processor becomes the one the door
        built (its state continues that stream). Raises
        :class:`bpms.io.rawfile.RawFileError` for an unreadable file."""
        from bpms.filter.door import open_for_processing

        opened = open_for_processing(path, *self._given, auto_zero=self.pose.auto)
        result = opened.result(zero_at_frames=zero_at)
        given = self._given
        self.__dict__.update(opened.processor.__dict__)
        self._given = given
        return result
