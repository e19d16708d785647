"""PNG figures (matplotlib, Agg backend: no display, no Qt)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bpms.analysis.rom import RomTable, joint_groups
from bpms.analysis.track import Track
from bpms.filter.joints import JOINT_ANGLE_NAMES


def _pyplot():
    from bpms.extras import require

    matplotlib = require(
        "matplotlib", "or leave the figures out (rom --no-figures, track --no-figure)")
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def rom_figures(tables: list[RomTable], directory: str | Path, stem: str) -> list[Path]:
    """One PNG per joint group: a horizontal min–max bar per joint angle and trial, degrees.
    Returns the paths written (``<stem>_<group>.png``)."""
    plt = _pyplot()
    paths = []
    height = 0.8 / max(1, len(tables))
    for group, idx in joint_groups().items():
        fig, ax = plt.subplots(figsize=(7, 0.6 + 0.45 * len(idx) * max(1, len(tables)) ** 0.5))
        for j, tab in enumerate(tables):
            y = np.arange(len(idx)) + j * height
            ax.barh(y, tab.range[idx], left=tab.minimum[idx], height=height * 0.9,
                    label=tab.label)
        ax.set_yticks(np.arange(len(idx)) + height * (len(tables) - 1) / 2)
        ax.set_yticklabels([JOINT_ANGLE_NAMES[k] for k in idx])
        ax.axvline(0.0, color="0.6", linewidth=0.8)
        ax.set_xlabel("angle, deg (bar = min to max)")
        ax.set_title(f"Range of motion: {group}")
        if len(tables) > 1:
            ax.legend(fontsize="small")
        fig.tight_layout()
        path = Path(directory) / f"{stem}_{group}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def track_figure(track: Track, path: str | Path, title: str = "Walked path") -> Path:
    """Plan view of the path (east to the right, north up) and its height profile (height
    against distance walked), metres, heel strikes marked."""
    plt = _pyplot()
    fig, (ax, prof) = plt.subplots(2, 1, figsize=(6, 8), height_ratios=(3, 1))
    pos = np.vstack([np.zeros(3), track.positions]) if len(track.positions) else np.zeros((1, 3))
    ax.plot(pos[:, 1], pos[:, 0], "-", color="0.4")
    for side, marker in (("right", "o"), ("left", "s")):
        sel = [k + 1 for k, s in enumerate(track.sides) if s == side]
        ax.plot(pos[sel, 1], pos[sel, 0], marker, linestyle="none", label=f"{side} heel strike")
    ax.set_xlabel("east, m")
    ax.set_ylabel("north (true), m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{title}: {len(track.times)} steps, {track.length_m:.2f} m")
    ax.legend(fontsize="small")
    walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos[:, :2], axis=0),
                                                             axis=1))])
    prof.plot(walked, -pos[:, 2], "-o", markersize=3)
    prof.set_xlabel("distance walked, m")
    prof.set_ylabel("height, m")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)
