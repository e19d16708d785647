"""A processed frame as the live session hands it out: :class:`PoseSample`."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the filter (numba) loads with the first session, not with the GUI window
    from bpms.filter.result import Result
    from bpms.io.options import BodyOptions


class _Row:
    """A PoseSample number: the value given to the constructor, else row ``k`` of the batch's
    :class:`bpms.filter.result.Result` attribute ``name`` (its field ``part``, for the
    disturbance record), computed for the whole batch at once when first read."""

    def __init__(self, name: str, part: str | None = None) -> None:
        self.name = name
        self.part = part

    def __set_name__(self, owner: type, attr: str) -> None:
        self.attr = attr

    def __get__(self, sample: PoseSample | None, owner: type) -> np.ndarray | None:
        if sample is None:
            return self  # type: ignore[return-value]
        given = sample._given.get(self.attr)
        if given is not None or sample._result is None:
            return given
        value = getattr(sample._result, self.name)
        if self.part is not None:
            value = None if value is None else getattr(value, self.part)
        return None if value is None else value[sample._k]


class PoseSample:
    """One processed frame. Angles rad, lengths m, frames as docs/filter.md, docs/body-model.md.

    index: frame index in the source; host_time: s since the epoch (receive time);
    raw ``[18, 9]`` int16 counts; errors ``[18, 3]`` bool; euler ``[18, 3]`` filter roll,
    pitch, yaw; R ``[18, 3, 3]`` filter DCMs; C ``[18, 3, 3]`` segment orientations after Reset
    Zero (NaN before the first); joint_angles ``[28]``; joint_positions ``[21, 3]`` (NED, lowest
    foot on the ground); latency_s: host receive → sample ready; arrival:
    ``time.perf_counter()`` when the host took the frame in; euler_output ``[18, 3]``: the
    per-IMU angles to show / write / stream (segment angles after Reset Zero when the
    corrected output is on, else = ``euler``); reinitialised ``[18]`` bool: the state guard
    re-initialised that IMU in this frame; mag_disturbed / acc_disturbed ``[18]`` bool and
    their strengths (:mod:`bpms.filter.disturbance`): mag_strength ``[18]`` the field's
    distance from the earth's as a fraction of it, mag_heading_deg ``[18]`` ° the heading error
    a filter trusting it would take, acc_strength ``[18]`` g RMS linear acceleration;
    estimates ``[18, 6]``: gyro bias x, y, z (rad/s, sensor
    axes) and body acceleration north, east, down (m/s²), NaN where the filter has none.

    The session's samples are rows of the processed batch's Result (``result``, row ``k``):
    a number nobody reads is never computed, and those that are read are computed for the
    whole batch at once. Given explicitly (a test, a script), the arrays are used as they are.
    """

    __slots__ = (
        "_given",
        "_k",
        "_result",
        "arrival",
        "errors",
        "frame",
        "host_time",
        "index",
        "latency_s",
        "raw",
    )

    euler = _Row("euler")
    R = _Row("R")
    C = _Row("C")
    joint_angles = _Row("joint_angles")
    joint_positions = _Row("joint_positions")
    euler_output = _Row("euler_output")
    reinitialised = _Row("reinitialised")
    mag_disturbed = _Row("disturbance", "mag")
    acc_disturbed = _Row("disturbance", "acc")
    mag_strength = _Row("disturbance", "mag_dev")
    mag_heading_deg = _Row("disturbance", "mag_heading_deg")
    acc_strength = _Row("disturbance", "acc_lin_g")
    estimates = _Row("estimates")

    def __init__(self, index: int, host_time: float, frame: bytes, raw: np.ndarray,
                 errors: np.ndarray, euler: np.ndarray | None = None,
                 R: np.ndarray | None = None, C: np.ndarray | None = None,
                 joint_angles: np.ndarray | None = None,
                 joint_positions: np.ndarray | None = None, latency_s: float = 0.0,
                 euler_output: np.ndarray | None = None,
                 reinitialised: np.ndarray | None = None, arrival: float = 0.0,
                 mag_disturbed: np.ndarray | None = None,
                 acc_disturbed: np.ndarray | None = None,
                 estimates: np.ndarray | None = None, *, result: Result | None = None,
                 k: int = 0, mag_strength: np.ndarray | None = None,
                 mag_heading_deg: np.ndarray | None = None,
                 acc_strength: np.ndarray | None = None) -> None:
        given = {"euler": euler, "R": R, "C": C, "joint_angles": joint_angles,
                 "joint_positions": joint_positions, "euler_output": euler_output,
                 "reinitialised": reinitialised, "mag_disturbed": mag_disturbed,
                 "acc_disturbed": acc_disturbed, "estimates": estimates,
                 "mag_strength": mag_strength, "mag_heading_deg": mag_heading_deg,
                 "acc_strength": acc_strength}
        self._set(index, host_time, frame, raw, errors, latency_s, arrival, result, k,
                  {name: value for name, value in given.items() if value is not None})

    def _set(self, index: int, host_time: float, frame: bytes, raw: np.ndarray,
             errors: np.ndarray, latency_s: float, arrival: float, result: Result | None,
             k: int, given: Mapping[str, np.ndarray] = MappingProxyType({})) -> None:
        """The one place a sample's fields are set (``given``: numbers given by name)."""
        self.index, self.host_time, self.frame = index, host_time, frame
        self.raw, self.errors, self.latency_s, self.arrival = raw, errors, latency_s, arrival
        self._given, self._result, self._k = given, result, k

    @classmethod
    def row(cls, result: Result, k: int, index: int, host_time: float, frame: bytes,
            raw: np.ndarray, errors: np.ndarray, latency_s: float, arrival: float
            ) -> PoseSample:
        """Row ``k`` of a processed batch, every number read from ``result`` (the live
        session's samples): the same sample as the constructor with ``result`` and ``k`` and
        no number given, built without looking at thirteen empty arguments per frame."""
        sample = cls.__new__(cls)
        sample._set(index, host_time, frame, raw, errors, latency_s, arrival, result, k)
        return sample

    def replace(self, **given: np.ndarray) -> PoseSample:
        """A copy with the numbers ``given`` (by their attribute names) in place of its own."""
        other = PoseSample(self.index, self.host_time, self.frame, self.raw, self.errors,
                           latency_s=self.latency_s, arrival=self.arrival, result=self._result,
                           k=self._k)
        unknown = set(given) - set(_ROWS)
        if unknown:
            raise TypeError(f"PoseSample has no number {', '.join(sorted(unknown))}")
        other._given = {**self._given, **given}
        return other

    @property
    def body(self) -> BodyOptions | None:
        """The segment lengths :attr:`joint_positions` were made with (the session's body
        model: the options', or the subject's profile, docs/subject.md); None when the
        sample was given its numbers explicitly."""
        return None if self._result is None else self._result.body

    def __repr__(self) -> str:
        return f"PoseSample(index={self.index}, host_time={self.host_time:.3f})"


_ROWS = tuple(name for name, value in vars(PoseSample).items() if isinstance(value, _Row))
