"""Drag and drop between the data table, the joint-angle list and the plots: table cells
and joint angles as MIME payloads, and the accept/take helpers of drop targets."""

from __future__ import annotations

import json
from collections.abc import Sequence

from PyQt6.QtCore import QMimeData

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.gui.columns import COLUMNS, TEXT_GROUPS
from bpms.io.frames import IMU_NAMES

#: Drag-and-drop payload of table cells: JSON ``[[imu, column], ...]``.
CELLS_MIME = "application/x-bpms-cells"
#: Drag-and-drop payload of joint angles: JSON ``[k, ...]`` (``JOINT_ANGLE_NAMES`` indices).
JOINTS_MIME = "application/x-bpms-joints"


def joints_to_mime(joints: Sequence[int]) -> QMimeData:
    mime = QMimeData()
    mime.setData(JOINTS_MIME, json.dumps([int(k) for k in joints]).encode())
    return mime


def joints_from_mime(mime: QMimeData | None) -> list[int]:
    """The joint-angle indices of a drag, [] when it carries none."""
    if mime is None or not mime.hasFormat(JOINTS_MIME):
        return []
    try:
        data = json.loads(bytes(mime.data(JOINTS_MIME)).decode())
        return [int(k) for k in data if 0 <= int(k) < len(JOINT_ANGLE_NAMES)]
    except (ValueError, TypeError):
        return []


def cells_to_mime(cells: Sequence[tuple[int, int]]) -> QMimeData:
    mime = QMimeData()
    mime.setData(CELLS_MIME, json.dumps([[int(r), int(c)] for r, c in cells]).encode())
    return mime


def cells_from_mime(mime: QMimeData | None) -> list[tuple[int, int]]:
    """The (IMU, column) cells of a drag, [] when it carries none."""
    if mime is None or not mime.hasFormat(CELLS_MIME):
        return []
    try:
        data = json.loads(bytes(mime.data(CELLS_MIME)).decode())
        return [(int(r), int(c)) for r, c in data
                if 0 <= int(r) < len(IMU_NAMES) and 0 <= int(c) < len(COLUMNS)
                and COLUMNS[int(c)].group not in TEXT_GROUPS]
    except (ValueError, TypeError):
        return []


def accept_drag(event) -> None:
    """Accept a drag that carries table cells or joint names, ignore any other."""
    take_drop(event)


def take_drop(event) -> tuple[list[tuple[int, int]], list[int]]:
    """The (cells, joints) a drop carries, the drop accepted; ([], []) and ignored when it
    carries neither."""
    cells, joints = cells_from_mime(event.mimeData()), joints_from_mime(event.mimeData())
    if cells or joints:
        event.acceptProposedAction()
    else:
        event.ignore()
    return cells, joints
