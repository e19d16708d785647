"""Range of motion (docs/body-model.md): min, max and range of every joint angle
over a time window, for one or several trials side by side."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpms.filter.joints import JOINT_ANGLE_NAMES


@dataclass
class RomTable:
    """One trial's range of motion, degrees, order :data:`JOINT_ANGLE_NAMES`; ``t0``, ``t1``
    the window actually used, s."""

    label: str
    t0: float
    t1: float
    minimum: np.ndarray
    maximum: np.ndarray

    @property
    def range(self) -> np.ndarray:
        return self.maximum - self.minimum


def range_of_motion(label: str, t: np.ndarray, joint_angles: np.ndarray,
                    t0: float | None = None, t1: float | None = None) -> RomTable:
    """Min/max (deg) of ``joint_angles[N, 28]`` (rad) over ``t0 <= t <= t1`` (s); NaN rows
    (before the first Reset Zero) are ignored. Raises ValueError for an empty window."""
    lo = t[0] if t0 is None else t0
    hi = t[-1] if t1 is None else t1
    mask = (t >= lo - 1e-9) & (t <= hi + 1e-9) & np.isfinite(joint_angles).all(axis=1)
    if not mask.any():
        raise ValueError(f"{label}: no filtered frame between {lo:.2f} s and {hi:.2f} s "
                         f"(the recording spans 0–{t[-1] if len(t) else 0:.2f} s)")
    deg = np.degrees(joint_angles[mask])
    return RomTable(label, float(t[mask][0]), float(t[mask][-1]), deg.min(axis=0),
                    deg.max(axis=0))


def joint_groups() -> dict[str, list[int]]:
    """Joint group (``elbow``, ``knee``, ``shoulder``, ``hip``, ``ankle``, ``torso``,
    ``head``) → indices into :data:`JOINT_ANGLE_NAMES`."""
    groups: dict[str, list[int]] = {}
    for k, name in enumerate(JOINT_ANGLE_NAMES):
        groups.setdefault(name.split(".")[0].split("_")[0], []).append(k)
    return groups


def write_csv(path: str | Path, tables: list[RomTable]) -> None:
    """One row per joint angle; per trial ``<label>_min_deg, _max_deg, _range_deg``."""
    cols = ["joint_angle"]
    for tab in tables:
        cols += [f"{tab.label}_{c}_deg" for c in ("min", "max", "range")]
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(cols) + "\n")
        for k, name in enumerate(JOINT_ANGLE_NAMES):
            cells = [name]
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
        rows.append(f"| {name} | " + " | ".join(
            f"{t.minimum[k]:.1f} / {t.maximum[k]:.1f} / {t.range[k]:.1f}" for t in tables)
            + " |")
    return "\n".join(rows) + "\n"
