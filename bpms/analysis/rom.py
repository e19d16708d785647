"""Range of motion (docs/body-model.md): min, max and range of every joint angle
over a time window, for one or several trials side by side."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.io.names import JOINT_ANGLE_NAMES, joint_column


@dataclass
class RomTable:
    """One trial's range of motion, degrees, order :data:`JOINT_ANGLE_NAMES`; ``t0``, ``t1``
    the window actually used, s; stamp: the recording's UTC start and joint-angle convention
    (:class:`bpms.analysis.stamp.Stamp`), when known."""

    label: str
    t0: float
    t1: float
    minimum: np.ndarray
    maximum: np.ndarray
    stamp: object | None = field(default=None, compare=False)

    @property
    def range(self) -> np.ndarray:
        return self.maximum - self.minimum


def range_of_motion(label: str, t: np.ndarray, joint_angles: np.ndarray,
                    t0: float | None = None, t1: float | None = None) -> RomTable:
    """Min/max (deg) of ``joint_angles[N, 28]`` (rad) over ``t0 <= t <= t1`` (s); NaN rows
    (before the first Reset Zero) are ignored. Raises ValueError for an empty window."""
    acc = RomAccumulator(label, t0, t1)
    acc.add(np.asarray(t), np.asarray(joint_angles))
    return acc.table()


class RomAccumulator:
    """:func:`range_of_motion` reduced on the fly, chunk by chunk (constant memory): feed
    ``add(t[N], joint_angles[N, 28])`` in time order, then :meth:`table`. Gives the same
    numbers as :func:`range_of_motion` over the whole arrays."""

    def __init__(self, label: str, t0: float | None = None, t1: float | None = None) -> None:
        self.label, self.t0, self.t1 = label, t0, t1
        n = len(JOINT_ANGLE_NAMES)
        self._min = np.full(n, np.inf)
        self._max = np.full(n, -np.inf)
        self._first: float | None = None
        self._last: float | None = None
        self._t_start: float | None = None
        self._t_end = 0.0

    def add(self, t: np.ndarray, joint_angles: np.ndarray) -> None:
        if not len(t):
            return
        if self._t_start is None:
            self._t_start = float(t[0])
        self._t_end = float(t[-1])
        lo = -np.inf if self.t0 is None else self.t0
        hi = np.inf if self.t1 is None else self.t1
        mask = (t >= lo - 1e-9) & (t <= hi + 1e-9) & np.isfinite(joint_angles).all(axis=1)
        if not mask.any():
            return
        deg = np.degrees(joint_angles[mask])
        np.minimum(self._min, deg.min(axis=0), out=self._min)
        np.maximum(self._max, deg.max(axis=0), out=self._max)
        tm = t[mask]
        if self._first is None:
            self._first = float(tm[0])
        self._last = float(tm[-1])

    def table(self) -> RomTable:
        """The trial's table. Raises ValueError for an empty window."""
        if self._first is None or self._last is None:
            lo = self._t_start if self.t0 is None else self.t0
            hi = self._t_end if self.t1 is None else self.t1
            raise ValueError(f"{self.label}: no filtered frame between {lo or 0.0:.2f} s and "
                             f"{hi:.2f} s (the recording spans 0–{self._t_end:.2f} s)")
        return RomTable(self.label, self._first, self._last, self._min.copy(),
                        self._max.copy())


def joint_groups() -> dict[str, list[int]]:
    """Joint group (``elbow``, ``knee``, ``shoulder``, ``hip``, ``ankle``, ``torso``,
    ``head``) → indices into :data:`JOINT_ANGLE_NAMES`."""
    groups: dict[str, list[int]] = {}
    for k, name in enumerate(JOINT_ANGLE_NAMES):
        groups.setdefault(name.split(".")[0].split("_")[0], []).append(k)
    return groups


def write_csv(path: str | Path, tables: list[RomTable]) -> None:
    """One row per joint angle (named as its columns elsewhere, without the unit:
    ``joint_knee_r_flexion``); per trial ``<label>_min_deg, _max_deg, _range_deg``. Lines
    ``# <label>: utc_start ...; joint_angle_convention ...`` before the column row state each
    trial's recording start (UTC) and joint-angle convention."""
    cols = ["joint_angle"]
    for tab in tables:
        cols += [f"{tab.label}_{c}_deg" for c in ("min", "max", "range")]
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        for tab in tables:
            if tab.stamp is not None:
                f.write(f"# {tab.label}: " + "; ".join(f"{k} {v}" for k, v in tab.stamp.items())
                        + "\n")
        f.write(",".join(cols) + "\n")
        for k, name in enumerate(JOINT_ANGLE_NAMES):
            cells = [joint_column(name)]
            for tab in tables:
                cells += [f"{v:.2f}" for v in (tab.minimum[k], tab.maximum[k], tab.range[k])]
            f.write(",".join(cells) + "\n")


def markdown(tables: list[RomTable]) -> str:
    """A Markdown table: one row per joint angle, per trial ``min / max / range`` in degrees."""
    head = "| joint angle | " + " | ".join(
        f"{t.label} ({t.t0:.1f}–{t.t1:.1f} s): min / max / range, deg" for t in tables) + " |"
    rule = "|---|" + "---|" * len(tables)
    rows = [head, rule]
    for k, name in enumerate(JOINT_ANGLE_NAMES):
        rows.append(f"| {joint_column(name)} | " + " | ".join(
            f"{t.minimum[k]:.1f} / {t.maximum[k]:.1f} / {t.range[k]:.1f}" for t in tables)
            + " |")
    notes = [f"- {t.label}: {t.stamp.line()}" for t in tables if t.stamp is not None]
    return "\n".join(rows + (["", *notes] if notes else [])) + "\n"
