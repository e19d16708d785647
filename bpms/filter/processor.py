"""The headless processor (the original "IMU class"): raw counts → orientations, joint angles
and a stick figure, for batches (whole recordings) and live frames. No Qt, no real-time pacing.

Example::

    from bpms.filter.processor import BodyPoseProcessor

    proc = BodyPoseProcessor(calibration="Calib.cfg", options="options.toml")
    result = proc.process(raw)   # raw [N, 18, 9] int16 counts (whole recordings:
                                 # bpms.filter.door.process_file)
    result.euler            # [N, 18, 3] roll, pitch, yaw of every IMU, rad
    result.joint_angles     # [N, 28] rad, names in bpms.filter.joints.JOINT_ANGLE_NAMES
    result.joint_positions  # [N, 21, 3] m, NED, names in bpms.filter.body_model.POINT_NAMES

    live = BodyPoseProcessor()
    for raw, errors in frames:                   # raw [18, 9] int16, errors [18, 3] bool
        frame = live.step(raw, errors)           # = live.process(raw[None], errors[None])
        if operator_pressed_reset_zero:
            live.reset_zero()                    # captured at the next frame

One orchestration: :meth:`BodyPoseProcessor.process` turns N frames into a :class:`Result`,
and a live frame is N = 1 of the same call (:meth:`~BodyPoseProcessor.step`,
:meth:`~BodyPoseProcessor.step_wire`).

What happens, frame by frame (details in docs/filter.md):

- raw counts → calibrated filter units (:class:`bpms.filter.calibration.SensorCalibration`);
- the disturbance flags (:mod:`bpms.filter.disturbance`), from the calibrated sensors alone;
  the observer's and the adaptive observer's heading gain drops to
  :data:`MAG_TRUST_FLAGGED` of itself while an IMU's magnetometer is flagged;
- 18 attitude filters of the kind ``Options.filter.algorithm`` selects
  (:mod:`bpms.filter.algorithms`; default the DCM Mahony :class:`bpms.filter.bank.MahonyBank`):
  the first frame of a stream only initialises; failed sensors hold their last good value;
- Reset Zero (:class:`bpms.filter.pose.PoseCalibrator`): a provisional one-frame capture on the
  first frame where all 18 IMUs are initialised, the automatic capture 1.0 s into the stream
  (0.5 s settling + the ``Options.pose.reset_window_s`` window, averaged), and one on each
  request; segment orientations ``C = R R0^T Rz(ψ0)``;
- the knees' and elbows' heading constraint (:mod:`bpms.filter.hinge`): a segment whose
  heading is uncertain (its magnetometer flagged, or the 6D mode) is turned about the
  vertical to agree with its hinge partner (``R`` and ``C`` alike);
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
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bpms.filter.algorithms import ObserverBank, make_bank
from bpms.filter.bank import MahonyBank
from bpms.filter.calibration import SensorCalibration
from bpms.filter.disturbance import Disturbance, DisturbanceTracker
from bpms.filter.guard import StateGuard, failed_inputs, guarded_process
from bpms.filter.hinge import HingeConstraint
from bpms.filter.pose import PoseCalibrator
from bpms.filter.result import Result
from bpms.filter.warmup import ensure_kernels, kernels_ready
from bpms.io.calib_file import CalibrationTable, as_table, checked, load_calibration
from bpms.io.event_types import (
    ADOPTED_SOURCES,
    Alignment,
    Change,
    FilterChoice,
    Filters,
    Gains,
    ResetZero,
)
from bpms.io.frames import N_CHANNELS, N_IMUS, decode_frames
from bpms.io.options import Options, load_options
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import stream_times

#: Seconds the filters settle after the stream starts before the automatic Reset Zero window.
SETTLE_S = 0.5
#: The observer's and the adaptive observer's heading gain (and the heading's share of their
#: bias update) while an IMU's magnetometer is flagged, as a fraction of their own: a short
#: disturbance costs a tenth of the heading error it would, a steady new field is still
#: followed, ten times slower (docs/filters.md). The original Mahony filter is left as it was;
#: VQF has its own magnetic rejection.
MAG_TRUST_FLAGGED = 0.1


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
        # None: the user's default when one is saved (read as a path, so its ellipsoid fits
        # come along), else the factory table
        user_default = False
        if calibration is None:
            from bpms.io.userdirs import default_calibration_path

            user_default = default_calibration_path().is_file()
            if user_default:
                calibration = default_calibration_path()
        if not isinstance(calibration, str | Path | None):  # a table: checked at the door
            self.table = checked(as_table(calibration))
        else:
            self.table = load_calibration(calibration)
        if user_default and not self.table.problems:
            self.table.source = f"user default ({calibration})"
        self.options = _load_options(options)
        ellipsoids: dict[int, Any] = {}
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
        dt = self.options.filter.dt
        self.pose = PoseCalibrator(window=round(self.options.pose.reset_window_s / dt),
                                   settle=round(SETTLE_S / dt), auto=auto_zero,
                                   heading=self.options.pose.heading_reference)
        self.frames = 0
        self.disturbance = DisturbanceTracker(self.sensor_calibration.gravity, dt)
        #: the knees' and elbows' heading constraint (bpms.filter.hinge), after Reset Zero
        #: (None: off, to compare with and without it)
        self.hinge: HingeConstraint | None = HingeConstraint(dt)
        self.guard = StateGuard(N_IMUS)
        self.corrected_output = self.options.pose.corrected_output
        self.problems = [str(p) for p in (*self.table.problems, *self.options.problems)]
        #: Where the calibration and the options in force came from (the labels beside the
        #: numbers; the door names the recording's header when it used it).
        self.calibration_source = str(self.table.source or "factory")
        self.options_source = str(getattr(self.options, "source", "") or "factory")

    @property
    def reinit_count(self) -> np.ndarray:
        """``[18]`` re-initialisations by the state guard so far (a copy)."""
        return self.guard.count.copy()

    # -- controls -----------------------------------------------------------------------
    def restart(self, keep_time: bool = False) -> None:
        """A new stream: every filter re-initialises on its next valid frame, Reset Zero
        forgets its capture and the automatic captures run again. ``keep_time``: the stream
        time goes on (a restart replayed inside a recording), else it starts again at 0."""
        self.reinitialise()
        if not keep_time:
            self.frames = 0
        self.pose.restart(self.frames)

    def reinitialise(self) -> None:
        """The stream resumes after a gap (a reconnection, Start Data, a seek): every filter
        re-initialises on its next valid frame and the disturbance indicators learn afresh;
        Reset Zero is kept."""
        self.bank.reset()
        self.guard.forget()
        self.disturbance.reset()
        if self.hinge is not None:
            self.hinge.reset()

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

    def reset_zero(self, source: str = "manual") -> None:
        """Reset Zero: capture at the next frame, averaged over the window ending there;
        ``source``: who asked (:data:`bpms.io.session_events.ZERO_SOURCES`)."""
        self.pose.request(source)

    def apply_event(self, event: SessionEvent | Change,
                    on_error: Callable[[str], None] | None = None) -> SessionEvent | None:
        """Apply one change before the next frame: the one road of every change, live (a
        :class:`bpms.io.event_types.Change` that :class:`bpms.pipeline.settings_queue.
        SettingsQueue` queued, checked when it was made) or recorded (a
        :class:`bpms.io.session_events.SessionEvent` on replay and re-analysis). A Reset Zero
        captures over its window when this stream holds it, else its recorded zero is
        adopted; alignment (None toggles), filter, gains, filters re-initialised or
        restarted; other kinds change nothing. Returns the event as applied (a toggle
        resolved to its new state), or None when it cannot be applied: the reason goes to
        ``on_error``, else into :attr:`problems`."""
        if isinstance(event, SessionEvent) and not event.changes_numbers:
            return event
        try:
            change = event if isinstance(event, Change) else event.change
            applied = self._apply(change)
        except Exception as exc:  # a change that fails never stops the frames
            if isinstance(event, Change):
                problem = f"setting {event.KIND} not applied: {exc}"
            else:
                problem = f"{event.describe(self.options.filter.dt)}: not applied ({exc})"
            if on_error is not None:
                on_error(problem)
            elif problem not in self.problems:
                self.problems.append(problem)
            return None
        if isinstance(event, Change):
            return SessionEvent.of(applied)
        return event if applied is change else SessionEvent.of(applied, event.frame, event.time)

    def _apply(self, change: Change) -> Change:
        if isinstance(change, ResetZero):
            self._reset_zero(change)
        elif isinstance(change, Alignment):
            return Alignment(self.set_corrected_output(change.on), change.source)
        elif isinstance(change, FilterChoice):
            self.select_filter(change.algorithm)
        elif isinstance(change, Gains):
            self._use_filter_options(change.values)
        elif isinstance(change, Filters):
            if change.action == "restart":
                self.restart(keep_time=True)
            else:
                self.reinitialise()
        return change

    def _reset_zero(self, z: ResetZero) -> None:
        if z.fallback:  # the recorded capture is lost: the automatic one instead
            self.pose.fall_back()
            return
        window = self.pose.window if z.window is None else z.window
        stored = z.zero
        adopt = z.adopted or self.pose.frames < window - 1  # its window is not in this stream
        if adopt and stored is not None:
            motion = (z.motion_deg or 0.0, -1 if z.motion_imu is None else z.motion_imu)
            self.pose.adopt(stored[0], stored[1], z.source, window, motion)
        elif adopt and z.source in ADOPTED_SOURCES:
            raise ValueError("no zero stored")
        else:
            self.pose.request(z.source, window)

    def set_gains(self, **gains: float) -> None:
        """Change ``kp_rollpitch``, ``ki_rollpitch``, ``kp_yaw``, ``ki_yaw``, ``dt`` (s)
        from the next frame on (Mahony); the other filters take their
        :class:`bpms.io.options.FilterOptions` names (``observer_k_incl``, ``vqf_tau_acc_s``,
        ...). Every value is checked first (:class:`bpms.io.event_types.Gains`, against
        :data:`bpms.io.options.VALID_RANGES`): one outside raises
        :class:`bpms.io.options.OptionRangeError` (a ValueError naming the range) and nothing
        changes. Each filter's values are kept in ``options.filter``, so switching filter and
        back (:meth:`select_filter`) keeps them."""
        self._use_filter_options(Gains(gains).values)

    def _use_filter_options(self, checked: Mapping[str, Any]) -> None:
        """Run with these checked ``[filter]`` values from the next frame on."""
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
        if self.hinge is not None:
            self.hinge.reset()
        self.options.filter = options

    # -- running ------------------------------------------------------------------------
    def load_kernels(self) -> float:
        """Compile (first run on a machine, with a notice) or load this filter's kernels now;
        s taken. A live session calls it before accepting the first frame
        (:mod:`bpms.filter.warmup`)."""
        return ensure_kernels(self.options.filter.algorithm)

    def calibrate(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw ``[N, 18, 9]`` counts → filter inputs (accel, mag, gyro) ``[N, 18, 3]``
        (:meth:`bpms.filter.calibration.SensorCalibration.calibrate`)."""
        return self.sensor_calibration.calibrate(raw)

    def process(self, raw: np.ndarray, errors: np.ndarray | None = None,
                events: Sequence[tuple[int, SessionEvent]] = ()) -> Result:
        """Filter N frames (``raw[N, 18, 9]`` counts, ``errors[N, 18, 3]`` bool), continuing
        the stream of earlier calls: calibration, the 18 filters with the state guard, Reset
        Zero, the disturbance flags (computed first: the observer's heading trusts a flagged
        field less), the knees' and elbows' heading constraint; the body's numbers follow from
        the Result when read.
        ``events``: ``(k, SessionEvent)``, each applied (:meth:`apply_event`) just before
        frame k of this batch (k ≥ N: after the last), e.g. a recording's events on replay.
        A live frame is N = 1."""
        if not events:
            return self._process(raw, errors)
        raw = np.asarray(raw)
        errors = None if errors is None else np.asarray(errors)
        parts = []
        lo = 0
        for k, event in sorted(events, key=lambda item: item[0]):
            k = min(max(int(k), 0), len(raw))
            if k > lo:
                parts.append(self._process(raw[lo:k], None if errors is None else errors[lo:k]))
                lo = k
            self.apply_event(event)
        if lo < len(raw) or not parts:
            parts.append(self._process(raw[lo:], None if errors is None else errors[lo:]))
        return Result.concat(parts)

    def _process(self, raw: np.ndarray, errors: np.ndarray | None) -> Result:
        raw = np.asarray(raw)
        if raw.ndim != 3 or raw.shape[1:] != (N_IMUS, N_CHANNELS):
            raise ValueError(f"raw must be [N, {N_IMUS}, {N_CHANNELS}], got {raw.shape}")
        if not kernels_ready(self.options.filter.algorithm):  # once per process and filter
            ensure_kernels(self.options.filter.algorithm)
        acc, mag, gyr = self.sensor_calibration.calibrate(raw)
        if errors is not None:
            errors = np.asarray(errors, dtype=np.bool_)
        if raw.dtype.kind == "f":  # integer counts always calibrate to finite values
            errors = failed_inputs(acc, mag, gyr, errors)
        # the disturbance flags come from the sensors alone, before the filters use them
        disturbance = self.disturbance.update(acc, mag, gyr, errors)
        terms: dict[str, Any]
        if isinstance(self.bank, MahonyBank):
            terms = {"store_terms": True}
        elif isinstance(self.bank, ObserverBank):  # the heading trusts a flagged field less
            terms = {"mag_trust": np.where(disturbance.mag, MAG_TRUST_FLAGGED, 1.0)}
        else:
            terms = {}
        out, reinitialised = guarded_process(self.bank, self.guard, acc, mag, gyr, errors,
                                             **terms)
        before = len(self.pose.captures)
        C = self.pose.apply(out.R)
        R, C = self._hinge(out.R, C, gyr, disturbance)
        n = len(raw)
        t = stream_times(self.frames, n, self.options.filter.dt)
        self.frames += n
        bias = out.gyro_bias
        if bias is None and out.w_i is not None:
            bias = -out.w_i  # the Mahony integral term is −bias
        corrected = np.zeros(n, np.bool_)  # from the first Reset Zero capture on
        if self.corrected_output:
            corrected[self.pose.zeroed_from:] = True
        # the Euler angles follow from the final R (after the hinge turned it) when read
        return Result(t=t, R=R, C=C, body=self.options.body,
                      held_count=self.bank.held_count, zeros=self.pose.captures[before:],
                      gyro_bias=bias, body_acc=out.body_acc,
                      disturbance=disturbance,
                      reinitialised=reinitialised, reinit_count=self.guard.count,
                      corrected=corrected, convention=self.options.joints.convention)

    def _hinge(self, R: np.ndarray, C: np.ndarray, gyr: np.ndarray,
               disturbance: Disturbance) -> tuple[np.ndarray, np.ndarray]:
        """The knees' and elbows' heading constraint: (R, C) with the segments it turns
        turned about the vertical. A segment's heading is uncertain while its magnetometer is
        flagged, by as much as this filter follows a flagged field (its heading gain, or the
        gyro's drift for the observers, which coast); in the 6D mode every heading is, by its
        drift alone."""
        f = self.options.filter
        if self.hinge is None:
            return R, C
        if f.heading == "relative":
            flagged, deviation = np.ones_like(disturbance.mag), np.zeros(disturbance.mag.shape)
            rate = 0.0
        else:
            flagged, deviation = disturbance.mag, disturbance.mag_heading_deg
            # the original and VQF turn with a flagged field at their heading gain; the
            # observers coast on the gyro (a tenth of their gain, and their own rejection)
            rate = {"mahony": f.kp_yaw, "vqf": 1.0 / f.vqf_tau_mag_s}.get(f.algorithm, 0.0)
        self.hinge.set_follow_rate(rate)
        # R (the bank's) and C (Reset Zero's) are this batch's own arrays
        self.hinge.apply_in_place(R, C, gyr, flagged, deviation)
        return R, C

    def step(self, raw: np.ndarray, errors: np.ndarray | None = None) -> Result:
        """Filter one live frame (``raw[18, 9]``, ``errors[18, 3]``): :meth:`process` of a
        batch of one; a Result with N = 1."""
        return self.process(np.asarray(raw)[None],
                            None if errors is None else np.asarray(errors)[None])

    def step_wire(self, frame: bytes, events: Sequence[tuple[int, SessionEvent]] = ()
                  ) -> tuple[Result, np.ndarray, np.ndarray]:
        """Decode (:func:`bpms.io.frames.decode_frames`) and filter (:meth:`process`) live
        340-byte frames as they came off the wire: (a Result, raw ``[N, 18, 9]`` int16 counts,
        errors ``[N, 18, 3]`` bool). Raises :class:`bpms.io.frames.FrameError` for a frame
        without its markers."""
        decoded = decode_frames(frame)
        return self.process(decoded.raw, decoded.errors, events), decoded.raw, decoded.errors


__all__ = ["MAG_TRUST_FLAGGED", "SETTLE_S", "BodyPoseProcessor", "Result"]
