"""Readers for optical motion-capture exports: one rigid body (or marker) at a time.

Supported layouts (details and examples in ``docs/analysis.md``):

- **Vicon Nexus CSV** ("Export CSV"): blocks separated by a blank line, each
  ``<block name>`` / ``<rate Hz>`` / a row of object names (``Subject:Segment``, in the first
  column of each object's group) / a row of column labels (``Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ``
  for segments, ``X,Y,Z`` for trajectories) / a row of units / data rows. Bodies come from the
  ``Segments`` block (RX, RY, RZ = helical axis × angle, deg; TX, TY, TZ = position, mm);
  markers from ``Trajectories`` (X, Y, Z, mm, no orientation). Empty cells are gaps (NaN).
- **Qualisys QTM TSV, 6DOF export**: ``KEY<TAB>value`` header lines (``NO_OF_FRAMES``,
  ``FREQUENCY``, ``DATA_INCLUDED 6D``, ``BODY_NAMES`` ...), a column-label row starting
  ``Frame<TAB>Time`` (an optional ``SMPTE`` column is skipped), then per body either 16 columns
  (X, Y, Z mm, Roll, Pitch, Yaw deg, Residual, Rot[0..8]) or 7 (without Rot). The first
  label of each body's group holds its name (``Pelvis`` or ``Pelvis X``). ``NaN``/empty = gap.

Anything else raises :class:`MocapFormatError` naming the file, the line and the problem.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import groupby
from pathlib import Path

import numpy as np

from bpms.filter.rotations import dcm_to_quaternion
from bpms.io.paths import require_regular_input


class MocapFormatError(Exception):
    """A file that is not in a supported layout: ``file: line N: problem``."""


class UnknownBodyError(Exception):
    """The requested body is not in the file (the message lists those that are)."""


@dataclass
class BodyTrack:
    """One rigid body (or marker) over time.

    t ``[N]`` s since the first frame; frame ``[N]`` the export's frame numbers;
    position ``[N, 3]`` mm in the capture system's axes; quaternion ``[N, 4]`` (w, x, y, z)
    body → capture frame, None for a marker; euler ``[N, 3]`` deg exactly as exported (Vicon
    helical RX, RY, RZ; Qualisys roll, pitch, yaw), None for a marker; euler_names their names.
    """

    name: str
    t: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray | None = None
    euler: np.ndarray | None = None
    euler_names: tuple[str, str, str] = ("rx", "ry", "rz")


@dataclass
class MocapExport:
    """Every body (and marker) of one export file by name."""

    path: str
    rate_hz: float
    bodies: dict[str, BodyTrack]

    def body(self, name: str) -> BodyTrack:
        """The body called ``name`` (exact, case-insensitive, or the part after
        ``Subject:``); :class:`UnknownBodyError` listing the available names otherwise."""
        if name in self.bodies:
            return self.bodies[name]
        key = name.lower()
        for full, track in self.bodies.items():
            if key in (full.lower(), full.split(":")[-1].lower()):
                return track
        available = ", ".join(self.bodies) or "none"
        raise UnknownBodyError(f"no body {name!r} in {self.path}; available: {available}")


def _number(text: str, path: str, line: int, what: str) -> float:
    text = text.strip()
    if text in ("", "-") or text.lower() == "nan":
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise MocapFormatError(f"{path}: line {line}: {text[:20]!r} is not a number "
                               f"({what})") from None


def helical_to_quaternion(v_deg: np.ndarray) -> np.ndarray:
    """Helical vectors ``[N, 3]`` (axis × angle, deg) → quaternions ``[N, 4]`` (w, x, y, z)."""
    v = np.radians(np.asarray(v_deg, dtype=np.float64))
    angle = np.linalg.norm(v, axis=-1)
    half = angle / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1), 0.5)
    return np.concatenate([np.cos(half)[:, None], v * k[:, None]], axis=1)


def _read_lines(path: Path) -> list[str]:
    try:
        require_regular_input(path)  # a named pipe would block, a device never end
        return path.read_text(encoding="utf-8-sig").splitlines()
    except OSError as exc:
        raise MocapFormatError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise MocapFormatError(f"{path}: cannot be read ({exc})") from None


# -- Vicon Nexus CSV ------------------------------------------------------------------------
def read_vicon(path: str | Path) -> MocapExport:
    """Read a Vicon Nexus CSV export (``Segments`` and ``Trajectories`` blocks; other blocks,
    e.g. ``Devices`` or ``Model Outputs``, are skipped)."""
    path = Path(path)
    lines = _read_lines(path)
    bodies: dict[str, BodyTrack] = {}
    rate = math.nan
    found = False
    # blocks: runs of non-blank lines, the first naming the block
    for filled, run in groupby(range(len(lines)), key=lambda k: bool(lines[k].strip(" ,"))):
        numbers = list(run)
        block = lines[numbers[0]].split(",")[0].strip()
        if filled and block in ("Segments", "Trajectories"):
            found = True
            rate = _vicon_block(path, lines, numbers[0] + 1, numbers[-1] + 1, block, bodies)
    if not found:
        raise MocapFormatError(f"{path}: line 1: no 'Segments' or 'Trajectories' block "
                               "(not a Vicon Nexus CSV export)")
    return MocapExport(str(path), rate, bodies)


def _vicon_block(path: Path, lines: list[str], start: int, end: int, block: str,
                 bodies: dict[str, BodyTrack]) -> float:
    if end - start < 4:
        raise MocapFormatError(f"{path}: line {start}: the {block} block needs a rate, a names "
                               "row, a labels row and a units row")
    rate = _number(lines[start].split(",")[0], str(path), start + 1, "frame rate, Hz")
    if not rate > 0:
        raise MocapFormatError(f"{path}: line {start + 1}: frame rate missing or not positive")
    names = lines[start + 1].split(",")
    labels = [s.strip() for s in lines[start + 2].split(",")]
    if labels[:2] != ["Frame", "Sub Frame"]:
        raise MocapFormatError(f"{path}: line {start + 3}: expected the labels row "
                               f"'Frame,Sub Frame,...', got {lines[start + 2][:40]!r}")
    width = 6 if block == "Segments" else 3
    expected = ["RX", "RY", "RZ", "TX", "TY", "TZ"] if width == 6 else ["X", "Y", "Z"]
    groups: list[tuple[str, int]] = []
    for col in range(2, len(labels), width):
        group = labels[col:col + width]
        if group != expected:
            raise MocapFormatError(f"{path}: line {start + 3}: columns {col + 1}-{col + width} "
                                   f"are {','.join(group)}, expected {','.join(expected)}")
        name = names[col].strip() if col < len(names) else ""
        if not name:
            raise MocapFormatError(f"{path}: line {start + 2}: no object name above column "
                                   f"{col + 1}")
        groups.append((name, col))
    rows = []
    for number in range(start + 4, end):
        cells = lines[number].split(",")
        cells += [""] * (len(labels) - len(cells))  # trailing empty cells may be left out
        if len(cells) != len(labels):
            raise MocapFormatError(f"{path}: line {number + 1}: {len(cells)} values, expected "
                                   f"{len(labels)}")
        rows.append([_number(c, str(path), number + 1, label)
                     for c, label in zip(cells, labels, strict=True)])
    data = np.array(rows, dtype=np.float64).reshape(-1, len(labels))
    frame = data[:, 0]
    if np.isnan(frame).any():
        bad = start + 5 + int(np.flatnonzero(np.isnan(frame))[0])
        raise MocapFormatError(f"{path}: line {bad}: the Frame column is empty")
    t = (frame - (frame[0] if len(frame) else 0)) / rate
    for name, col in groups:
        if width == 6:
            helical = data[:, col:col + 3]
            bodies[name] = BodyTrack(name, t, frame, data[:, col + 3:col + 6],
                                     helical_to_quaternion(helical), helical, ("rx", "ry", "rz"))
        else:
            bodies.setdefault(name, BodyTrack(name, t, frame, data[:, col:col + 3]))
    return rate


# -- Qualisys TSV (6DOF) --------------------------------------------------------------------
def read_qualisys(path: str | Path) -> MocapExport:
    """Read a Qualisys QTM 6DOF TSV export."""
    path = Path(path)
    lines = _read_lines(path)
    header: dict[str, list[str]] = {}
    label_line = -1
    for k, line in enumerate(lines):
        cells = line.rstrip("\r\n").split("\t")
        if cells[0].strip() == "Frame":
            label_line = k
            break
        if cells[0].strip():
            header[cells[0].strip().upper()] = [c.strip() for c in cells[1:]]
    if label_line < 0:
        raise MocapFormatError(f"{path}: line {len(lines)}: no column-label row starting "
                               "'Frame<TAB>Time' (not a Qualisys 6DOF TSV export)")
    names = [n for n in header.get("BODY_NAMES", []) if n]
    if not names:
        raise MocapFormatError(f"{path}: line {label_line + 1}: no BODY_NAMES header line "
                               "before the column labels")
    rate = _number((header.get("FREQUENCY") or [""])[0], str(path), 0, "FREQUENCY")
    labels = [c.strip() for c in lines[label_line].split("\t")]
    if len(labels) < 2 or labels[1] != "Time":
        raise MocapFormatError(f"{path}: line {label_line + 1}: expected 'Frame<TAB>Time', got "
                               f"{lines[label_line][:40]!r}")
    lead = 3 if len(labels) > 2 and labels[2] == "SMPTE" else 2
    span = len(labels) - lead
    if span % len(names) or span // len(names) not in (7, 16):
        raise MocapFormatError(f"{path}: line {label_line + 1}: {span} body columns for "
                               f"{len(names)} bodies (expected 16 or 7 per body)")
    width = span // len(names)
    for b, name in enumerate(names):
        first = labels[lead + b * width]
        if not first.lower().startswith(name.lower()):
            raise MocapFormatError(f"{path}: line {label_line + 1}: column "
                                   f"{lead + b * width + 1} is {first!r}, expected body "
                                   f"{name!r} (BODY_NAMES)")
    rows = []
    for number in range(label_line + 1, len(lines)):
        if not lines[number].strip():
            continue
        cells = lines[number].split("\t")
        if len(cells) != len(labels):
            raise MocapFormatError(f"{path}: line {number + 1}: {len(cells)} values, expected "
                                   f"{len(labels)}")
        del cells[2:lead]
        rows.append([_number(c, str(path), number + 1, "value") for c in cells])
    data = np.array(rows, dtype=np.float64).reshape(-1, 2 + span)
    frame, t = data[:, 0], data[:, 1]
    if not rate > 0 and len(t) > 1:
        rate = 1.0 / float(np.median(np.diff(t)))
    bodies = {}
    for b, name in enumerate(names):
        col = 2 + b * width
        euler = data[:, col + 3:col + 6]
        if width == 16:
            rot = data[:, col + 7:col + 16].reshape(-1, 3, 3).swapaxes(1, 2)  # column-major
        else:
            rot = qualisys_euler_to_dcm(euler)
        quat = np.full((len(data), 4), np.nan)
        ok = np.isfinite(rot).all(axis=(1, 2))
        if ok.any():
            quat[ok] = dcm_to_quaternion(rot[ok])
        bodies[name] = BodyTrack(name, t - (t[0] if len(t) else 0), frame, data[:, col:col + 3],
                                 quat, euler, ("roll", "pitch", "yaw"))
    return MocapExport(str(path), rate, bodies)


def qualisys_euler_to_dcm(euler_deg: np.ndarray) -> np.ndarray:
    """QTM's default ("Qualisys standard") angles, deg → ``[N, 3, 3]`` body → lab:
    roll about X, then pitch about the new Y, then yaw about the newest Z (R = Rx Ry Rz)."""
    r, p, y = np.radians(np.asarray(euler_deg, dtype=np.float64)).T
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    one, zero = np.ones_like(r), np.zeros_like(r)
    rx = np.stack([one, zero, zero, zero, cr, -sr, zero, sr, cr], -1).reshape(-1, 3, 3)
    ry = np.stack([cp, zero, sp, zero, one, zero, -sp, zero, cp], -1).reshape(-1, 3, 3)
    rz = np.stack([cy, -sy, zero, sy, cy, zero, zero, zero, one], -1).reshape(-1, 3, 3)
    return rx @ ry @ rz


def body_table(track: BodyTrack) -> tuple[list[str], np.ndarray]:
    """Columns and rows of ``bpms extract vicon|qualisys``: time, frame, position mm, then for
    a rigid body the quaternion and the exported angles in degrees."""
    columns = ["time_s", "frame", "x_mm", "y_mm", "z_mm"]
    parts = [track.t[:, None], track.frame[:, None], track.position]
    if track.quaternion is not None and track.euler is not None:
        columns += ["qw", "qx", "qy", "qz", *(f"{n}_deg" for n in track.euler_names)]
        parts += [track.quaternion, track.euler]
    return columns, np.concatenate(parts, axis=1)
