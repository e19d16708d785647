"""The outputs of N filtered frames: :class:`Result` (angles rad, lengths m; docs/units.md).

The processor builds every Result (:meth:`bpms.filter.processor.BodyPoseProcessor.process`);
the numbers derived from its arrays (segment Euler angles, joint angles, joint positions,
quaternions, the estimates) are computed when first read, for all N frames at once, by the
vectorised functions of :mod:`bpms.filter.pose`, :mod:`bpms.filter.joints`,
:mod:`bpms.filter.body_model` and :mod:`bpms.filter.rotations` — the same functions for a
live frame (N = 1) and a whole recording.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from bpms.filter.centre_of_mass import centre_of_mass
from bpms.filter.disturbance import Disturbance
from bpms.filter.pose import Zero, body_outputs, segment_angles
from bpms.filter.rotations import dcm_to_euler, finite_dcm_to_quaternion
from bpms.io.frames import N_IMUS
from bpms.io.options import BodyOptions

#: Result fields that are running totals (the last part's value stands for the whole stream).
#: Per-frame estimates some filters make and others do not (NaN where not made).
_ESTIMATE_FIELDS = ("gyro_bias", "body_acc")
_RUNNING_FIELDS = frozenset({"held_count", "reinit_count"})


class _SensorEuler:
    """The field ``Result.euler``: the array given to the constructor, else the Euler angles
    of ``R`` (:func:`bpms.filter.rotations.dcm_to_euler`) computed for the whole batch when
    first read, as every other number derived from a Result is. A live frame whose angles
    nobody reads (the filtered file reads them once a second, for its whole batch) costs no
    Euler call. A data descriptor used as a dataclass field (Python's "descriptor-typed
    fields"): ``Result(..., euler=None)`` or no ``euler`` leaves it to be computed."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = f"_{name}_value"

    def __get__(self, result: Result | None, owner: type | None = None) -> np.ndarray | None:
        if result is None:
            return None  # the dataclass field's default
        value = result.__dict__.get(self.slot)
        if value is None:
            value = result.__dict__[self.slot] = dcm_to_euler(result.R)
        return value

    def __set__(self, result: Result, value: np.ndarray | None) -> None:
        result.__dict__[self.slot] = value

    def known(self, result: Result) -> bool:
        """Whether the value is there without computing it (given, or read before)."""
        return result.__dict__.get(self.slot) is not None


@dataclass
class Result:
    """Outputs of N frames. Angles in radians, lengths in metres, frames: docs/units.md.

    t: ``[N]`` s since the stream started, on the fixed filter clock (frame index × dt);
    R: ``[N, 18, 3, 3]`` DCM filter frame → NED; euler (= :attr:`euler_sensor`):
    ``[N, 18, 3]`` (roll, pitch, yaw) of R, the uncorrected sensor angles (computed from R
    when first read, unless given);
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
    C: np.ndarray
    euler: np.ndarray = _SensorEuler()  # type: ignore[assignment]
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

    convention: str = "isb"  # joint-angle signs, bpms.filter.joints.CONVENTIONS
    #: Where the calibration / options came from (set by the one door, bpms.filter.door).
    calibration_source: str = field(default="", repr=False)
    options_source: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        n = len(self.t)
        if self.reinitialised is None:
            self.reinitialised = np.zeros((n, N_IMUS), dtype=np.bool_)
        if self.corrected is None:
            self.corrected = np.zeros(n, dtype=np.bool_)

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def empty(cls, body: BodyOptions, convention: str) -> Result:
        """A Result of no frames."""
        z = np.zeros((0, N_IMUS, 3, 3))
        return cls(t=np.zeros(0), R=z, C=z.copy(), body=body, convention=convention)

    @classmethod
    def allocate(cls, n: int, like: Result) -> Result:
        """A Result of ``n`` frames with the fields ``like`` carries (per-frame shapes and
        dtypes), its per-frame arrays allocated and not yet filled: :meth:`put` fills them
        part by part, so a whole recording costs its arrays and one part at a time."""
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            v = getattr(like, f.name)
            if isinstance(v, np.ndarray | Disturbance) and f.name not in _RUNNING_FIELDS:
                values[f.name] = _per_frame(lambda a: np.empty((n, *a.shape[1:]), a.dtype), v)
            elif isinstance(v, list):
                values[f.name] = []
            else:
                values[f.name] = v
        return cls(**values)

    def put(self, start: int, part: Result) -> None:
        """Copy ``part``'s frames into frames ``start …`` of this Result (made by
        :meth:`allocate`); running counters from ``part``, its lists appended."""
        stop = start + len(part)
        for f in dataclasses.fields(self):
            mine, theirs = getattr(self, f.name), getattr(part, f.name)
            if f.name in _RUNNING_FIELDS:
                setattr(self, f.name, theirs)
            elif isinstance(mine, np.ndarray | Disturbance):
                _per_frame(lambda a, b: np.copyto(a[start:stop], b, casting="unsafe"), mine,
                           theirs)
            elif isinstance(mine, list):
                mine.extend(theirs)

    def head(self, n: int) -> Result:
        """The first ``n`` frames (views of this Result's arrays)."""
        values: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray | Disturbance) and f.name not in _RUNNING_FIELDS:
                values[f.name] = _per_frame(lambda a: a[:n], v)
            else:
                values[f.name] = v
        return Result(**values)

    @staticmethod
    def concat(parts: list[Result]) -> Result:
        """One Result of consecutive parts of a stream: per-frame arrays (and the disturbance
        record's) joined, running counters and single values from the last part, lists of
        every part (zeros, problems)."""
        if len(parts) == 1:
            return parts[0]
        last = parts[-1]
        values: dict[str, Any] = {}
        for f in dataclasses.fields(Result):
            if f.name == "euler" and not all(_EULER.known(p) for p in parts):
                continue  # computed from the joined R when read, in one call
            items = [getattr(p, f.name) for p in parts]
            # (the first part may lack what a later one has: a filter switched between them)
            known = next((v for v in items if v is not None), None)
            if f.name in _RUNNING_FIELDS or not isinstance(known, np.ndarray | list
                                                           | Disturbance):
                values[f.name] = getattr(last, f.name)
            elif any(v is None for v in items) and isinstance(known, np.ndarray) \
                    and f.name in _ESTIMATE_FIELDS:  # NaN where a filter estimates none
                values[f.name] = np.concatenate([
                    np.full((len(p), *known.shape[1:]), np.nan) if v is None else v
                    for p, v in zip(parts, items, strict=True)])
            elif any(v is None for v in items):
                values[f.name] = None
            elif isinstance(items[0], list):
                values[f.name] = [x for v in items for x in v]
            else:
                values[f.name] = _per_frame(lambda *a: np.concatenate(a), *items)
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
        corrected = np.asarray(self.corrected, dtype=np.bool_)
        return np.where(corrected[:, None, None], self.euler_segment, self.euler)

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
    def centre_of_mass(self) -> np.ndarray:
        """``[N, 3]`` m: the whole body's centre of mass, in the frame of
        :attr:`joint_positions` (:mod:`bpms.filter.centre_of_mass`, docs/subject.md)."""
        return centre_of_mass(self.joint_positions)

    @cached_property
    def quaternions(self) -> np.ndarray:
        """``[N, 18, 4]`` (w, x, y, z) of the filter DCMs ``R``."""
        return finite_dcm_to_quaternion(self.R)

    @cached_property
    def segment_quaternions(self) -> np.ndarray:
        """``[N, 18, 4]`` (w, x, y, z) of the segment orientations ``C``."""
        return finite_dcm_to_quaternion(self.C)


_EULER: _SensorEuler = Result.__dict__["euler"]


def _per_frame(fn: Callable, *values: np.ndarray | Disturbance) -> object:
    """``fn`` of per-frame arrays, or, for disturbance records, a record of ``fn`` of their
    corresponding arrays (one per field)."""
    if isinstance(values[0], Disturbance):
        return Disturbance(**{g.name: fn(*(getattr(v, g.name) for v in values))
                              for g in dataclasses.fields(Disturbance)})
    return fn(*values)

