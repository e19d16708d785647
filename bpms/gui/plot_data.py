"""What a live plot draws, without Qt: one display tick's samples as arrays
(:class:`TickBlock`, built once per tick and shared by every plot), the fixed-capacity history
(:class:`RingBuffer`: ``Options.display.plot_history_s`` × 50 Hz rows, the newest ``n`` always
one contiguous numpy view), the curves (label, unit, how to take their values) and the
peak-keeping decimation to the plot's width."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from bpms.filter.calibration import SensorCalibration
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.gui.columns import COLUMNS, calibrated, column_values, human_joint_name, shown_angles
from bpms.io.frames import FRAME_PERIOD_S, IMU_NAMES
from bpms.io.timebase import stream_time_of
from bpms.pipeline.session import PoseSample


@dataclass
class TickBlock:
    """One tick's samples as arrays: t ``[n]`` s (frame index × 20 ms), raw ``[n, 18, 9]``
    counts, cal ``[n, 18, 9]`` (m/s², gauss, rad/s), euler ``[n, 18, 3]`` rad,
    joint_angles ``[n, 28]`` rad."""

    t: np.ndarray
    raw: np.ndarray
    cal: np.ndarray
    euler: np.ndarray
    joint_angles: np.ndarray
    est: np.ndarray | None = None  # [n, 18, 6] gyro bias rad/s, body acceleration m/s²

    @classmethod
    def from_samples(cls, samples: Sequence[PoseSample], calibration: SensorCalibration,
                     output: bool = True, euler: np.ndarray | None = None) -> TickBlock:
        """``output``: Euler columns hold the output angles (after Reset Zero, the default)
        rather than the sensor angles (:func:`bpms.gui.columns.shown_angles`); ``euler
        [n, 18, 3]`` rad: the angles to use instead (the continuous readout of those,
        :mod:`bpms.gui.angle_readout`)."""
        raw = np.array([s.raw for s in samples])
        return cls(
            t=stream_time_of(np.array([s.index for s in samples]), FRAME_PERIOD_S),
            raw=raw,
            cal=calibrated(calibration, raw),
            euler=np.array([shown_angles(s, output)[0] for s in samples]) if euler is None
            else np.asarray(euler, np.float64),
            joint_angles=np.array([s.joint_angles for s in samples]),
            est=np.array([np.full((18, 6), np.nan) if s.estimates is None else s.estimates
                          for s in samples]),
        )


class RingBuffer:
    """The newest ``capacity`` rows of ``width`` float64 values.

    Every row is written twice (at ``i`` and ``i + capacity``) so :meth:`view` is a contiguous
    slice, oldest first, without copying.
    """

    def __init__(self, capacity: int, width: int) -> None:
        if capacity < 1:
            raise ValueError("capacity must be ≥ 1")
        self.capacity = capacity
        self._data = np.full((2 * capacity, width), np.nan)
        self._head = 0  # next write position in [0, capacity)
        self._count = 0

    def __len__(self) -> int:
        return self._count

    def clear(self) -> None:
        self._head = 0
        self._count = 0

    def extend(self, rows: np.ndarray) -> None:
        """Append ``rows [n, width]`` (only the newest ``capacity`` are kept)."""
        rows = np.asarray(rows, np.float64)[-self.capacity:]
        n = len(rows)
        if n == 0:
            return
        cap = self.capacity
        first = min(n, cap - self._head)
        for offset in (0, cap):
            self._data[self._head + offset:self._head + offset + first] = rows[:first]
            self._data[offset:offset + n - first] = rows[first:]
        self._head = (self._head + n) % cap
        self._count = min(cap, self._count + n)

    def view(self) -> np.ndarray:
        """``[len, width]`` rows, oldest first (a view: copy it to keep it)."""
        end = self._head + self.capacity
        return self._data[end - self._count:end]


class BlockHistory:
    """The last ``capacity`` frames of what plots draw (time, raw counts, angles, joint angles,
    estimates), so that a plot opened — or re-created by a layout — starts with the history
    instead of an empty axis. Calibrated values are recomputed from the raw counts on
    :meth:`block`. A step back in time (a seek, a new stream) starts it again."""

    _PARTS = (("raw", (18, 9)), ("euler", (18, 3)), ("joint_angles", (28,)), ("est", (18, 6)))

    def __init__(self, capacity: int) -> None:
        self._sizes = [int(np.prod(shape)) for _, shape in self._PARTS]
        self.buffer = RingBuffer(capacity, 1 + sum(self._sizes))

    def __len__(self) -> int:
        return len(self.buffer)

    def extend(self, block: TickBlock) -> None:
        n = len(block.t)
        if n == 0:
            return
        if len(self.buffer) and block.t[0] < self.buffer.view()[-1, 0]:
            self.buffer.clear()
        est = block.est if block.est is not None else np.full((n, 18, 6), np.nan)
        parts = [block.t[:, None], block.raw.reshape(n, -1), block.euler.reshape(n, -1),
                 block.joint_angles.reshape(n, -1), est.reshape(n, -1)]
        self.buffer.extend(np.concatenate(parts, axis=1))

    def block(self, calibration: SensorCalibration) -> TickBlock | None:
        """Everything kept, oldest first (None when empty)."""
        rows = self.buffer.view()
        if len(rows) == 0:
            return None
        n, out, start = len(rows), {}, 1
        for (name, shape), size in zip(self._PARTS, self._sizes, strict=True):
            out[name] = rows[:, start:start + size].reshape(n, *shape)
            start += size
        raw = out["raw"].astype(np.int16)
        return TickBlock(t=rows[:, 0].copy(), raw=raw, cal=calibrated(calibration, raw),
                         euler=out["euler"].copy(), joint_angles=out["joint_angles"].copy(),
                         est=out["est"].copy())


@dataclass(frozen=True)
class CurveSpec:
    """A curve: its legend label (with unit) and how to take its values from a block."""

    label: str
    values: Callable[[TickBlock], np.ndarray]
    unit: str = ""
    cell: tuple[int, int] | None = None  # (IMU, column) for a table cell
    joint: int | None = None  # index into JOINT_ANGLE_NAMES for a joint angle


def cell_curve(imu: int, col: int, angle_unit: str = "deg") -> CurveSpec:
    """The curve of table cell (IMU ``imu``, column ``col``)."""
    column = COLUMNS[col]
    degrees = angle_unit == "deg"
    unit = angle_unit if column.group == "euler" else column.unit
    label = f"{IMU_NAMES[imu]} {column.name} [{unit}]"
    return CurveSpec(label, lambda b: column_values(column, b.raw, b.cal, b.euler,
                                                    degrees, b.est)[:, imu], unit, (imu, col))


def joint_curve(k: int, angle_unit: str = "deg") -> CurveSpec:
    """The curve of joint angle ``k`` (``JOINT_ANGLE_NAMES`` order)."""
    degrees = angle_unit == "deg"
    unit = "deg" if degrees else "rad"
    return CurveSpec(f"{human_joint_name(JOINT_ANGLE_NAMES[k])} [{unit}]",
                     lambda b: np.degrees(b.joint_angles[:, k]) if degrees
                     else b.joint_angles[:, k], unit, joint=k)


#: Groups of the joint-angle plot: (title, name prefixes).
JOINT_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Elbows, knees", ("elbow_", "knee_")),
    ("Shoulders", ("shoulder_",)),
    ("Hips", ("hip_",)),
    ("Ankles", ("ankle_",)),
    ("Torso, head", ("torso.", "head.")),
)


def joint_angle_groups(angle_unit: str = "deg") -> list[tuple[str, list[CurveSpec]]]:
    """The 28 joint angles of ``JOINT_ANGLE_NAMES`` in :data:`JOINT_GROUPS`."""
    return [(title, [joint_curve(k, angle_unit) for k, name in enumerate(JOINT_ANGLE_NAMES)
                     if name.startswith(prefixes)])
            for title, prefixes in JOINT_GROUPS]


def peak_decimate(data: np.ndarray, pixels: int) -> np.ndarray:
    """Rows ``[n, 1 + k]`` (time, k values) → at most ``2 × pixels`` rows keeping each bin's
    minimum and maximum (a curve drawn from them looks the same at that width; NaN gaps stay
    gaps). Bins end at the newest row, so the newest data are never merged away."""
    n = len(data)
    if pixels < 1 or n <= 2 * pixels:
        return data
    factor = -(-n // pixels)
    m = (n // factor) * factor
    head, body = data[:n - m], data[n - m:]
    bins = body.reshape(-1, factor, data.shape[1])
    out = np.empty((2 * len(bins), data.shape[1]))
    out[0::2, 0] = bins[:, 0, 0]
    out[1::2, 0] = bins[:, -1, 0]
    out[0::2, 1:] = np.fmin.reduce(bins[:, :, 1:], axis=1)
    out[1::2, 1:] = np.fmax.reduce(bins[:, :, 1:], axis=1)
    return np.concatenate([head, out]) if len(head) else out


def group_by_unit(specs: Sequence[CurveSpec]) -> list[tuple[str, list[CurveSpec]]]:
    """One group per unit (one y axis per unit), in order of first appearance."""
    groups: dict[str, list[CurveSpec]] = {}
    for spec in specs:
        groups.setdefault(spec.unit, []).append(spec)
    return [("", specs) for specs in groups.values()]
