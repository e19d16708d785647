"""One live frame of the default (Mahony) filter in a single compiled call.

A live frame runs the same kernels as a whole recording, one after the other: calibration
(:func:`bpms.filter.mahony.calibrate_batch`), the filter step
(:func:`bpms.filter.mahony.step_frame`), the state guard (:mod:`bpms.filter.guard`), the
disturbance indicators (:mod:`bpms.filter.disturbance`), Reset Zero
(:func:`bpms.filter.mahony.right_multiply`) and the body's numbers
(:mod:`bpms.filter.body_kernels`). Called from Python one by one, each call and the arrays
around it cost a few microseconds, and at 50 frames/s that glue was most of the recorder's
CPU. :func:`mahony_live_frame` calls the same compiled kernels from compiled code, so a
frame gives the same numbers bit for bit either way (tests/test_live_frame.py compares
them), and the Python side only handles what is rare: a Reset Zero capture, a state-guard
re-initialisation, the first frames of a stream, an ellipsoid magnetometer correction, float
input through the API and the other filters all take the general path
(:meth:`bpms.filter.processor.BodyPoseProcessor.step`).
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from bpms.filter.bank import MahonyBank
from bpms.filter.body_kernels import joint_angle_frames, joint_position_frames, segment_euler
from bpms.filter.body_model import position_tables
from bpms.filter.disturbance import Disturbance, run_disturbance
from bpms.filter.guard import SO3_TOLERANCE, _reinit, renorm_allowance
from bpms.filter.guard import _check as guard_check
from bpms.filter.joints import angle_tables
from bpms.filter.kernels import kernel, twins_active
from bpms.filter.mahony import calibrate_batch, right_multiply, step_frame
from bpms.io.frames import (
    CLUSTER_SIZE,
    IMUS_PER_CLUSTER,
    N_CHANNELS,
    N_CLUSTERS,
    N_IMUS,
    N_SENSORS,
)

if TYPE_CHECKING:
    from bpms.filter.processor import BodyPoseProcessor, Result


@kernel
def mahony_live_frame(raw, errors, acc_off, acc_gain, mag_off, mag_gain, gyr_off, gyr_gain,
                      rot, resets, params, gravity, R, w_i, w_p, euler, trig, initialised,
                      held, seen, held_count, c4, expected, tol, dist_gravity, dist_params,
                      dist_state, mag_count, acc_count, offset, ring, ring_slot,
                      corrected_output, frame_index, dt, hinge, hinge_axes, ball, signs, imus,
                      parents, vectors, feet):
    """One frame: ``raw[1, 18, 9]`` int16 counts and ``errors[18, 3]`` failed-sensor flags in,
    the other arguments those of the kernels it calls (filter, guard and disturbance state
    updated in place; ``ring[ring_slot]`` takes this frame's DCMs for Reset Zero's window
    unless ``ring_slot`` < 0). Returns the frame's outputs, each a batch of one frame:
    (t, R, euler, gyro bias = −ωI, guard bad, mag disturbed, acc disturbed, norm ratio, dip
    deviation (deg), acc deviation, C, segment Euler angles, output Euler angles, joint angles,
    joint positions, held count (a copy), corrected, number of bad IMUs, Result.estimates)."""
    n = raw.shape[1]
    acc = np.empty((1, n, 3))
    mag = np.empty((1, n, 3))
    gyr = np.empty((1, n, 3))
    calibrate_batch(raw, acc_off, acc_gain, mag_off, mag_gain, gyr_off, gyr_gain, rot,
                    acc, mag, gyr)
    out_R = np.empty((1, n, 3, 3))
    out_euler = np.empty((1, n, 3))
    out_wi = np.empty((n, 3))
    out_wp = np.empty((n, 3))
    step_frame(acc[0], mag[0], gyr[0], errors, resets, params, gravity, R, w_i, w_p, euler,
               trig, initialised, held, seen, held_count, out_R[0], out_euler[0], out_wi,
               out_wp)
    bad = np.empty((1, n), np.bool_)
    guard_seen = np.empty(n, np.bool_)
    guard_check(out_R, gyr, c4, expected, tol, bad, guard_seen)
    nan = np.nan
    n_bad = 0
    valid = np.empty((1, n), np.bool_)
    bias = np.empty((1, n, 3))
    estimates = np.full((1, n, 6), np.nan)  # Result.estimates: bias, no body acceleration
    for i in range(n):
        resets[i] = False  # taken by this step (bank.step)
        expected[i] = guard_seen[i]
        if bad[0, i]:  # no rotation any more: NaN for this frame (guarded_step)
            n_bad += 1
            for a in range(3):
                out_euler[0, i, a] = nan
                for b in range(3):
                    out_R[0, i, a, b] = nan
        valid[0, i] = not (errors[i, 0] or errors[i, 1] or errors[i, 2])
        for a in range(3):
            bias[0, i, a] = -out_wi[i, a]
            estimates[0, i, a] = bias[0, i, a]
    mag_dist = np.zeros((1, n), np.bool_)
    acc_dist = np.zeros((1, n), np.bool_)
    norm_ratio = np.empty((1, n))
    dip = np.empty((1, n))
    acc_mean = np.empty((1, n))
    run_disturbance(acc, mag, gyr, out_R, dist_gravity, valid, dist_params, dist_state,
                    mag_dist, acc_dist, norm_ratio, dip, acc_mean)
    for i in range(n):
        dip[0, i] = dip[0, i] * (180.0 / math.pi)  # np.degrees, the same product
        mag_count[i] += mag_dist[0, i]
        acc_count[i] += acc_dist[0, i]
    if ring_slot >= 0:
        for i in range(n):
            for a in range(3):
                for b in range(3):
                    ring[ring_slot, i, a, b] = out_R[0, i, a, b]
    C = np.empty((1, n, 3, 3))
    right_multiply(out_R, offset, C)
    euler_segment = np.empty((1, n, 3))
    segment_euler(C, euler_segment)
    angles = np.empty((1, signs.shape[0]))
    joint_angle_frames(C, hinge, hinge_axes, ball, signs, angles)
    positions = np.empty((1, imus.shape[0] + 1, 3))
    joint_position_frames(C, imus, parents, vectors, feet, True, positions)
    # corrected from the first capture on: some IMU's segment orientation is finite
    n_finite = 0
    for i in range(n):
        finite = True
        for a in range(3):
            for b in range(3):
                if not math.isfinite(C[0, i, a, b]):
                    finite = False
        if finite:
            n_finite += 1
    corrected = np.empty(1, np.bool_)
    corrected[0] = corrected_output and n_finite > 0
    euler_output = euler_segment.copy() if corrected[0] else out_euler.copy()
    t = np.empty(1)
    t[0] = float(frame_index) * dt  # bpms.io.timebase.stream_times
    return (t, out_R, out_euler, bias, bad, mag_dist, acc_dist, norm_ratio, dip, acc_mean, C,
            euler_segment, euler_output, angles, positions, held_count.copy(), corrected, n_bad,
            estimates)


@kernel
def mahony_live_wire(frame, *args):
    """:func:`mahony_live_frame` of one 340-byte frame as it came off the wire (``frame``
    uint8 ``[340]``, markers already checked): decoded as :func:`bpms.io.frames.decode_frames`
    does (big-endian counts, error bit ``3·slot + sensor`` of each cluster's word). Returns
    (raw ``[1, 18, 9]`` int16, errors ``[1, 18, 3]`` bool, the outputs of
    :func:`mahony_live_frame`)."""
    raw = np.empty((1, N_IMUS, N_CHANNELS), np.int16)
    errors = np.empty((1, N_IMUS, N_SENSORS), np.bool_)
    for c in range(N_CLUSTERS):
        base = 2 + c * CLUSTER_SIZE
        for slot in range(IMUS_PER_CLUSTER):
            imu = c * IMUS_PER_CLUSTER + slot
            for ch in range(N_CHANNELS):
                at = base + 2 * (slot * N_CHANNELS + ch)
                value = int(frame[at]) * 256 + int(frame[at + 1])
                raw[0, imu, ch] = value - 65536 if value >= 32768 else value
        word = int(frame[base + CLUSTER_SIZE - 2]) * 256 + int(frame[base + CLUSTER_SIZE - 1])
        for slot in range(IMUS_PER_CLUSTER):
            for s in range(N_SENSORS):
                errors[0, c * IMUS_PER_CLUSTER + slot, s] = (word >> (3 * slot + s)) & 1 == 1
    return raw, errors, mahony_live_frame(raw, errors[0], *args)


class LiveFrame:
    """The single-call live path of a processor: :meth:`usable` says whether a frame may take
    it, :meth:`step` and :meth:`step_wire` run it. Holds nothing but the joint and body tables
    (rebuilt when the processor's body options object or joint convention changes)."""

    def __init__(self) -> None:
        self._tables_for: tuple[object, str] | None = None
        self._tables: tuple[np.ndarray, ...] = ()
        self._no_ring = np.empty((1, N_IMUS, 3, 3))

    def _body_tables(self, proc: BodyPoseProcessor) -> tuple[np.ndarray, ...]:
        options = proc.options
        key = (options.body, options.joints.convention)
        if self._tables_for is None or key[0] is not self._tables_for[0] \
                or key[1] != self._tables_for[1]:
            self._tables = (*angle_tables(key[1]), *position_tables(key[0]))
            self._tables_for = key
        return self._tables

    def usable(self, proc: BodyPoseProcessor, raw: np.ndarray | None = None,
               errors: np.ndarray | None = None) -> bool:
        """True when the next frame of ``proc`` needs nothing the single call leaves out
        (``raw``/``errors``: the frame given as arrays; None: a wire frame)."""
        return (type(proc.bank) is MahonyBank and proc.frames > 0
                and proc.pose.plain_next_frame()
                and (raw is None or (raw.dtype == np.int16
                                     and raw.shape == (N_IMUS, N_CHANNELS)))
                and (errors is None or (errors.dtype == np.bool_
                                        and errors.shape == (N_IMUS, 3)))
                and proc.sensor_calibration.mag_correction() is None and not twins_active())

    def _arguments(self, proc: BodyPoseProcessor) -> tuple:
        """Every argument of :func:`mahony_live_frame` after ``raw`` and ``errors``."""
        bank, guard, pose, dist = proc.bank, proc.guard, proc.pose, proc.disturbance
        ring, slot = pose.ring_slot()
        return (*proc._cal_params, bank._pending_reset, bank.params, bank.gravity,
                *bank.state.arrays(), renorm_allowance(bank),
                guard.expected, SO3_TOLERANCE, dist.gravity, dist.params, dist.state,
                dist.mag_count, dist.acc_count, pose.zero.offset,
                self._no_ring if ring is None else ring, slot, bool(proc.corrected_output),
                proc.frames, float(proc.options.filter.dt), *self._body_tables(proc))

    def step(self, proc: BodyPoseProcessor, raw: np.ndarray, errors: np.ndarray | None
             ) -> Result:
        """Filter one frame of ``proc`` (``usable`` must be True); a Result with N = 1, the
        numbers of the general path."""
        err = proc.bank._no_errors if errors is None else np.ascontiguousarray(errors)
        outputs = mahony_live_frame(np.ascontiguousarray(raw)[None], err,
                                    *self._arguments(proc))
        return self._result(proc, outputs)

    def step_wire(self, proc: BodyPoseProcessor, frame: bytes
                  ) -> tuple[Result, np.ndarray, np.ndarray]:
        """Decode and filter one 340-byte wire frame (markers checked by the caller, ``usable``
        True): (Result with N = 1, raw ``[1, 18, 9]``, errors ``[1, 18, 3]``)."""
        raw, errors, outputs = mahony_live_wire(np.frombuffer(frame, np.uint8),
                                                *self._arguments(proc))
        return self._result(proc, outputs), raw, errors

    def _result(self, proc: BodyPoseProcessor, outputs: tuple) -> Result:
        (t, R, euler, bias, bad, mag_dist, acc_dist, norm_ratio, dip, acc_mean, C,
         euler_segment, euler_output, angles, positions, held_count, corrected, n_bad,
         estimates) = outputs
        proc.pose.plain_frame_done()  # the kernel wrote this frame's DCMs at its ring slot
        proc.frames += 1
        if n_bad:
            _reinit(proc.bank, proc.guard, bad[0])
        result = _result_class()(
            t=t, R=R, euler=euler, C=C, body=proc.options.body, held_count=held_count,
            zeros=[], gyro_bias=bias, body_acc=None,
            disturbance=Disturbance(mag_dist, acc_dist, norm_ratio, dip, acc_mean),
            reinitialised=bad, reinit_count=proc.guard.count.copy(), corrected=corrected,
            convention=proc.options.joints.convention)
        # the kernel computed the lazy fields already
        result.__dict__.update(euler_segment=euler_segment, euler_output=euler_output,
                               estimates=estimates, _body=(angles, positions))
        return result


@functools.cache
def _result_class() -> type[Result]:
    """:class:`bpms.filter.processor.Result` (imported at the first live frame: the processor
    module imports this one)."""
    from bpms.filter.processor import Result

    return Result
