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
  (:mod:`bpms.filter.algorithms`; default the DCM Mahony :class:`bpms.filter.bank.MahonyBank`):
  the first frame of a stream only initialises; failed sensors hold their last good value;
- Reset Zero (:class:`bpms.filter.pose.PoseCalibrator`): a provisional one-frame capture on the
  first frame where all 18 IMUs are initialised, the automatic capture 1.0 s into the stream
  (0.5 s settling + the ``Options.pose.reset_window_s`` window, averaged), and one on each
  request; segment orientations ``C = R R0^T Rz(ψ0)``;
- joint angles and stick-figure joint positions (per-subject lengths ``Options.body``);
- the state guard (:mod:`bpms.filter.guard`): an IMU whose filter state stops being a rotation
  gives NaN for that one frame, is re-initialised from its next valid frame and counted
  (``reinit_count``, ``Result.reinitialised``).

Calibration and options left out (None) are the user's defaults (:mod:`bpms.io.defaults`),
else the factory ones; docs/configuration.md gives the precedence.

The first frame given after construction or :meth:`BodyPoseProcessor.restart` is the first
frame of the stream: dropping the stale first frame after a pause (docs/suit.md) is the job of the
acquisition layer, which does not record it.
"""

from __future__ import annotations

import copy
import dataclasses
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from bpms.filter.algorithms import make_bank
from bpms.filter.bank import BankOutput, MahonyBank
from bpms.filter.calibration import GYRO_RAD_S_PER_COUNT, SensorCalibration
from bpms.filter.disturbance import Disturbance, DisturbanceTracker
from bpms.filter.guard import StateGuard, failed_inputs, guarded_process, guarded_step
from bpms.filter.kernels import claim_twin_frames, load_numba, twins, twins_active
from bpms.filter.live_frame import LiveFrame
from bpms.filter.mahony import calibrate_batch
from bpms.filter.pose import PoseCalibrator, Zero, body_outputs, segment_angles
from bpms.filter.rotations import dcm_to_quaternion
from bpms.filter.warmup import PATHS, TWIN_FILTERS, ensure_kernels
from bpms.io.calib_file import CalibrationTable, checked, load_calibration
from bpms.io.frames import N_CHANNELS, N_IMUS, decode_frames, is_frame
from bpms.io.options import BodyOptions, Options, check_option, load_options
from bpms.io.timebase import stream_times

#: Seconds the filters settle after the stream starts before the automatic Reset Zero window.
SETTLE_S = 0.5


_BANK_FIELDS = tuple(f.name for f in dataclasses.fields(BankOutput))

#: Result fields that are running totals (the last part's value stands for the whole stream).
_RUNNING_FIELDS = frozenset({"held_count", "reinit_count"})


@dataclass
class Result:
    """Outputs of N frames. Angles in radians, lengths in metres, frames: docs/units.md.

    t: ``[N]`` s since the stream started, on the fixed filter clock (frame index × dt);
    R: ``[N, 18, 3, 3]`` DCM filter frame → NED; euler (= :attr:`euler_sensor`):
    ``[N, 18, 3]`` (roll, pitch, yaw) of R, the uncorrected sensor angles;
    C: ``[N, 18, 3, 3]`` segment orientations after Reset Zero (NaN before the first capture);
    :attr:`euler_segment` their Euler angles; :attr:`euler_output` the per-IMU angles to show,
    write and stream (segment angles when ``corrected``, docs/filter.md);
    joint_angles: ``[N, 28]``; joint_positions: ``[N, 21, 3]``; NaN where an IMU involved is
    not initialised. held_count: ``[18, 3]`` filter steps so far that used a held value.
    reinitialised: ``[N, 18]`` bool, the state guard re-initialised that IMU at that frame
    (its outputs are NaN in that frame only); reinit_count: ``[18]`` re-initialisations so far.
    corrected: ``[N]`` bool, :attr:`euler_output` holds segment angles at that frame (the
    corrected output is switched on and a Reset Zero capture exists).
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
    #: ``[N, 18, 3]`` rad/s gyro-bias estimate in body (filter-frame) axes: observer,
    #: adaptive and vqf their bias estimate, mahony minus its integral term ωI
    gyro_bias: np.ndarray | None = field(default=None, repr=False)
    #: ``[N, 18, 3]`` m/s² body-acceleration estimate (NED) of observer/adaptive, else None
    body_acc: np.ndarray | None = field(default=None, repr=False)
    #: per-frame disturbance indicators (:class:`bpms.filter.disturbance.Disturbance`)
    disturbance: Disturbance | None = field(default=None, repr=False)
    reinitialised: np.ndarray | None = field(default=None, repr=False)
    reinit_count: np.ndarray = field(default_factory=lambda: np.zeros(N_IMUS, np.int64))
    corrected: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        n = len(self.t)
        if self.reinitialised is None:
            self.reinitialised = np.zeros((n, N_IMUS), dtype=np.bool_)
        if self.corrected is None:
            self.corrected = np.zeros(n, dtype=np.bool_)
    convention: str = "isb"  # joint-angle signs, bpms.filter.joints.CONVENTIONS
    #: Where the calibration / options came from (set by the one door, bpms.filter.door).
    calibration_source: str = field(default="", repr=False)
    options_source: str = field(default="", repr=False)

    def __len__(self) -> int:
        return len(self.t)

    @staticmethod
    def concat(parts: list[Result]) -> Result:
        """One Result of consecutive parts of a stream: per-frame arrays (and the disturbance
        record's) joined, running counters and single values from the last part, lists of
        every part (zeros, problems)."""
        if len(parts) == 1:
            return parts[0]
        last = parts[-1]
        values = {}
        for f in dataclasses.fields(Result):
            items = [getattr(p, f.name) for p in parts]
            if f.name in _RUNNING_FIELDS or not isinstance(items[0], np.ndarray | list
                                                             | Disturbance):
                values[f.name] = getattr(last, f.name)
            elif any(v is None for v in items):
                values[f.name] = None
            elif isinstance(items[0], list):
                values[f.name] = [x for v in items for x in v]
            elif isinstance(items[0], Disturbance):
                values[f.name] = dataclasses.replace(items[0], **{
                    g.name: np.concatenate([getattr(v, g.name) for v in items])
                    for g in dataclasses.fields(items[0])})
            else:
                values[f.name] = np.concatenate(items)
        return Result(**values)

    @property
    def euler_sensor(self) -> np.ndarray:
        """``[N, 18, 3]`` rad: roll, pitch, yaw of each IMU's filter DCM ``R`` (sensor frame
        → NED), uncorrected by Reset Zero. The same array as :attr:`euler`."""
        return self.euler

    @cached_property
    def euler_segment(self) -> np.ndarray:
        """``[N, 18, 3]`` rad: roll, pitch, yaw of the segment orientations ``C`` (relative to
        the calibration pose, heading as ``pose.heading_reference``); NaN before Reset Zero."""
        return segment_angles(self.C)

    @cached_property
    def euler_output(self) -> np.ndarray:
        """``[N, 18, 3]`` rad: the per-IMU angles the table, plots, filtered file and streams
        give: :attr:`euler_segment` at frames where ``corrected``, else :attr:`euler_sensor`."""
        return np.where(self.corrected[:, None, None], self.euler_segment, self.euler)

    @cached_property
    def estimates(self) -> np.ndarray:
        """``[N, 18, 6]``: the filter's gyro-bias estimate x, y, z (rad/s, body axes) then its
        body-acceleration estimate north, east, down (m/s²); NaN for what the filter does not
        estimate."""
        out = np.full((len(self), N_IMUS, 6), np.nan)
        if self.gyro_bias is not None:
            out[..., :3] = self.gyro_bias
        if self.body_acc is not None:
            out[..., 3:] = self.body_acc
        return out

    @cached_property
    def _body(self) -> tuple[np.ndarray, np.ndarray]:
        return body_outputs(self.C, self.body, self.convention)

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


def _default_path() -> Path:
    from bpms.io.userdirs import default_calibration_path

    return default_calibration_path()


def _load_table(calibration: str | Path | CalibrationTable | None) -> CalibrationTable:
    if isinstance(calibration, CalibrationTable):  # checked at the door, whatever its origin
        return checked(calibration)
    return load_calibration(calibration)


def _load_options(options: str | Path | Options | None) -> Options:
    if isinstance(options, Options):
        # the processor's own copy: nothing outside (a GUI form, another thread) writes it
        return copy.deepcopy(options)
    if options is None:
        from bpms.io.defaults import default_options

        return default_options(announce=False)
    return load_options(options)


class BodyPoseProcessor:
    """Raw frames in, orientations / joint angles / joint positions out.

    calibration: None (the user's default, else the factory table), a ``Calib.cfg`` path or a
    CalibrationTable.
    options: None (the user's default, else factory options), an options-file path or an
    Options object (copied: later changes go through :meth:`set_gains` and friends).
    auto_zero: run the provisional and automatic Reset Zero at the start of the stream.
    Problems with the files are in ``.problems`` (never raised).
    """

    def __init__(self, calibration: str | Path | CalibrationTable | None = None,
                 options: str | Path | Options | None = None, auto_zero: bool = True) -> None:
        # What the caller chose (None = not given): process_file's precedence starts here.
        self._given = (calibration, options)
        # None: the user's default when one is saved (read as a path, so its ellipsoid fits
        # come along), else the factory table
        user_default = calibration is None and _default_path().is_file()
        if user_default:
            calibration = _default_path()
        self.table = _load_table(calibration)
        if user_default and not self.table.problems:
            self.table.source = f"user default ({calibration})"
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
        # options.filter.algorithm: 'mahony' (MahonyBank, the original) or another filter
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
        self.disturbance = DisturbanceTracker(self.sensor_calibration.gravity, dt)
        self.guard = StateGuard(N_IMUS)
        self.corrected_output = self.options.pose.corrected_output
        self._twins: bool | None = None  # plan(): how this stream's kernels run
        self._live_frame = LiveFrame()
        self.problems = [str(p) for p in (*self.table.problems, *self.options.problems)]

    @property
    def reinit_count(self) -> np.ndarray:
        """``[18]`` re-initialisations by the state guard so far (a copy)."""
        return self.guard.count.copy()

    # -- controls -----------------------------------------------------------------------
    def restart(self) -> None:
        """A new stream: every filter re-initialises on its next valid frame, Reset Zero
        forgets its capture and the automatic captures run again."""
        self.bank.reset()
        self.guard.forget()
        self.pose.restart()
        self.disturbance.reset()
        self.frames = 0
        self._twins = None

    def plan(self, frames: int | None) -> None:
        """A stream of ``frames`` frames (a whole recording) follows: decide once, by its
        length, whether its kernels run as numpy twins (short: numba is never imported) or
        compiled (:mod:`bpms.filter.kernels`). The numbers are the same either way. None
        ends the plan (the door does when the recording is done): later calls decide by
        their own length."""
        self._twins = None if frames is None else self._twins_for(frames)

    def _twins_for(self, frames: int) -> bool:
        return (self.options.filter.algorithm in TWIN_FILTERS
                and claim_twin_frames(frames))  # False once numba is loaded

    def kernels_for(self, frames: int, filter_kernels: bool = True
                    ) -> AbstractContextManager[None]:
        """The context in which to run ``frames`` frames' kernels: numpy twins when this
        stream was planned so (:meth:`plan`) or, unplanned, when ``frames`` is short and numba
        is not loaded; otherwise the compiled kernels, with this filter's made ready here
        (compiled with a notice on the very first run; ``filter_kernels=False``: only numba
        is loaded, for Reset Zero on stored angles). Inside a caller's own
        :func:`bpms.filter.kernels.twins` block, twins."""
        if twins_active():
            return twins(True)
        use = self._twins if self._twins is not None else self._twins_for(frames)
        if not use:
            if filter_kernels:
                # the common case costs a set lookup; the first call compiles or loads
                ensure_kernels(self.options.filter.algorithm, ("batch",))
            else:
                load_numba()
        return twins(use)

    def reset_filter(self, imu: int | None = None) -> None:
        """Re-initialise one IMU's filter (all when None) at its next valid frame."""
        self.bank.reset(imu)
        self.guard.forget(imu)

    def set_corrected_output(self, on: bool | None = None) -> bool:
        """Per-IMU output angles corrected by Reset Zero (True) or the sensor angles (False);
        None toggles (the original's ``v`` key). Applies from the next frame; returns the new
        state."""
        self.corrected_output = (not self.corrected_output) if on is None else bool(on)
        return self.corrected_output

    def reset_zero(self) -> None:
        """Reset Zero: capture at the next frame, averaged over the window ending there."""
        self.pose.request()

    def set_gains(self, **gains: float) -> None:
        """Change ``kp_rollpitch``, ``ki_rollpitch``, ``kp_yaw``, ``ki_yaw``, ``dt`` (s)
        from the next frame on (Mahony); the other filters take their
        :class:`bpms.io.options.FilterOptions` names (``observer_k_incl``, ``vqf_tau_acc_s``,
        ...). Every value is checked first against :data:`bpms.io.options.VALID_RANGES`:
        one outside raises :class:`bpms.io.options.OptionRangeError` (a ValueError naming the
        range) and nothing changes. Each filter's values are kept in ``options.filter``, so
        switching filter and back (:meth:`select_filter`) keeps them."""
        checked = {name: check_option("filter", name, value) for name, value in gains.items()}
        if "algorithm" in checked:
            raise ValueError("use select_filter() to change the attitude filter")
        options = dataclasses.replace(self.options.filter, **checked)
        self.bank.set_options(options)
        self.options.filter = options

    def select_filter(self, algorithm: str) -> None:
        """Switch all 18 IMUs to another attitude filter (``FilterOptions.algorithm``
        choices); the new filters align on their next valid frame, Reset Zero is kept, and
        the new filter starts from its own values in ``options.filter`` (run-time changes
        included). Raises ValueError for an unknown name, ``VqfMissingError`` without the vqf
        package."""
        options = dataclasses.replace(self.options.filter, algorithm=algorithm)
        self.bank = make_bank(self.sensor_calibration.gravity, options)
        self.guard.forget()
        self.options.filter = options
        self._twins = None

    # -- running ------------------------------------------------------------------------
    def load_kernels(self, live: bool = True) -> float:
        """Compile (first run on a machine, with a notice) or load this filter's kernels now,
        for whole recordings and, with ``live``, frame by frame; s taken. A live session
        calls it before accepting the first frame (:mod:`bpms.filter.warmup`)."""
        return ensure_kernels(self.options.filter.algorithm, PATHS if live else ("batch",))

    def calibrate(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw ``[N, 18, 9]`` counts → filter inputs (accel, mag, gyro) ``[N, 18, 3]``: the
        numbers of ``SensorCalibration.calibrate`` (same formula and parameters), computed in
        one compiled pass (or its numpy twin for a short stream, :meth:`kernels_for`)."""
        with self.kernels_for(np.shape(raw)[0]):
            return self._calibrate(raw)

    def _calibrate(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raw = np.asarray(raw)
        if raw.dtype != np.int16 or not raw.flags.c_contiguous:
            raw = np.ascontiguousarray(raw, dtype=np.float64)
        outs = tuple(np.empty((raw.shape[0], N_IMUS, 3)) for _ in range(3))
        calibrate_batch(raw, *self._cal_params, *outs)
        if self.sensor_calibration.mag_correction() is not None:
            outs[1][:] = self.sensor_calibration.correct_mag(outs[1])
        return outs

    def _result(self, n: int, out: BankOutput, C: np.ndarray, captures_before: int,
                acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                errors: np.ndarray | None, reinitialised: np.ndarray) -> Result:
        t = stream_times(self.frames, n, self.options.filter.dt)
        self.frames += n
        bias = out.gyro_bias
        if bias is None and out.w_i is not None:
            bias = -out.w_i.reshape(out.euler.shape)  # the Mahony integral term is −bias
        # corrected from the first Reset Zero capture on (C is all NaN before it)
        corrected = self.corrected_output & np.isfinite(C).all(axis=(-1, -2)).any(axis=1)
        return Result(t=t, R=out.R, euler=out.euler, C=C, body=self.options.body,
                      held_count=self.bank.held_count, zeros=self.pose.captures[captures_before:],
                      gyro_bias=bias, body_acc=out.body_acc,
                      disturbance=self.disturbance.update(acc, mag, gyr, out.R, errors),
                      reinitialised=reinitialised, reinit_count=self.guard.count.copy(),
                      corrected=corrected, convention=self.options.joints.convention)

    def process(self, raw: np.ndarray, errors: np.ndarray | None = None,
                zero_at: list[int] | tuple[int, ...] = ()) -> Result:
        """Filter N frames (``raw[N, 18, 9]`` counts, ``errors[N, 18, 3]`` bool) in one pass,
        continuing the stream of earlier calls. ``zero_at``: frame indices (into this batch)
        where Reset Zero captures happen, e.g. to re-zero replayed data."""
        raw = np.asarray(raw)
        if raw.ndim != 3 or raw.shape[1:] != (N_IMUS, N_CHANNELS):
            raise ValueError(f"raw must be [N, {N_IMUS}, {N_CHANNELS}], got {raw.shape}")
        with self.kernels_for(len(raw)):
            acc, mag, gyr = self._calibrate(raw)
            if raw.dtype.kind == "f":  # integer counts always calibrate to finite values
                errors = failed_inputs(acc, mag, gyr, errors)
            terms = {"store_terms": True} if isinstance(self.bank, MahonyBank) else {}
            out, reinit = guarded_process(self.bank, self.guard, acc, mag, gyr, errors,
                                          **terms)
            before = len(self.pose.captures)
            C = self.pose.apply(out.R, zero_at)
            return self._result(len(raw), out, C, before, acc, mag, gyr, errors, reinit)

    def step(self, raw: np.ndarray, errors: np.ndarray | None = None) -> Result:
        """Filter one live frame (``raw[18, 9]``, ``errors[18, 3]``); a Result with N = 1."""
        ensure_kernels(self.options.filter.algorithm, ("live",))  # ~0.6 µs once loaded
        raw = np.asarray(raw)
        if errors is not None:
            errors = np.asarray(errors)
        if self._live_frame.usable(self, raw, errors):  # most frames: one compiled call
            return self._live_frame.step(self, raw, errors)
        acc, mag, gyr = self._calibrate(raw[None])  # live: the compiled kernels
        if raw.dtype.kind == "f":  # integer counts always calibrate to finite values
            errors = failed_inputs(acc[0], mag[0], gyr[0], errors)
        out, reinit = guarded_step(self.bank, self.guard, acc[0], mag[0], gyr[0], errors)
        before = len(self.pose.captures)
        C = self.pose.apply(out.R[None])
        out = BankOutput(*(None if v is None else v[None]
                           for v in (getattr(out, name) for name in _BANK_FIELDS)))
        return self._result(1, out, C, before, acc, mag, gyr,
                            None if errors is None else np.asarray(errors)[None], reinit[None])

    def step_wire(self, frame: bytes) -> tuple[Result, np.ndarray, np.ndarray]:
        """Decode and filter one live 340-byte frame as it came off the wire: (a Result with
        N = 1, raw ``[1, 18, 9]`` int16 counts, errors ``[1, 18, 3]`` bool). The numbers of
        :func:`bpms.io.frames.decode_frames` and :meth:`step`; most frames take one compiled
        call for all of it (:mod:`bpms.filter.live_frame`). Raises
        :class:`bpms.io.frames.FrameError` for a frame without its markers."""
        ensure_kernels(self.options.filter.algorithm, ("live",))
        if is_frame(frame) and self._live_frame.usable(self):
            return self._live_frame.step_wire(self, frame)
        decoded = decode_frames(frame)
        return self.step(decoded.raw[0], decoded.errors[0]), decoded.raw, decoded.errors

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
