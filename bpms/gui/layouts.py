"""Named dock layouts, saved per user and remembered between launches.

A layout is Qt's ``QMainWindow.saveState()`` (dock positions, sizes, tabs, floating) plus the
list of dynamic docks it needs (plots with their curves and view, 3D views with their camera)
and extras (the data table's columns), so restoring it first re-creates those docks under the
same object names, then restores the state.

Stored in ``<config_dir>/gui-layouts.json`` (``bpms.io.userdirs.config_dir()``)::

    {"layouts": {"my layout": {"state": "<base64>", "docks": [...], "extras": {...}}, ...},
     "last": {"state": ..., "docks": ...}}

``last`` is the layout in use when the main window closed; the next main window starts with
it. The three defaults ("live monitoring", "playback analysis", "calibration check") are built
in code (:data:`DEFAULT_LAYOUTS`) and can be overridden by saving under the same name.
"""

from __future__ import annotations

import base64
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bpms.io.userdirs import config_dir

log = logging.getLogger(__name__)

LIVE, PLAYBACK, CALIBRATION = "live monitoring", "playback analysis", "calibration check"
DEFAULT_LAYOUTS = (LIVE, PLAYBACK, CALIBRATION)
FILE_NAME = "gui-layouts.json"


@dataclass
class Layout:
    """``state``: QMainWindow.saveState() bytes; ``docks``: the dynamic docks, each a dict
    with ``kind`` ("plot" or "view3d"), ``name`` (objectName) and, for plots, ``plot`` (the
    plot's description, :meth:`bpms.gui.plots.PlotWindow.description`), for 3D views
    ``view`` (:meth:`bpms.gui.view3d.View3DWindow.view_settings`); ``extras``:
    ``table_header`` (the data table's column widths and order, base64 of
    ``QHeaderView.saveState()``)."""

    state: bytes
    docks: list[dict[str, Any]] = field(default_factory=list)
    extras: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"state": base64.b64encode(self.state).decode("ascii"), "docks": self.docks,
                "extras": self.extras}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Layout:
        extras = data.get("extras", {})
        return cls(base64.b64decode(data["state"]), list(data.get("docks", [])),
                   dict(extras) if isinstance(extras, dict) else {})


class LayoutStore:
    """The user's saved layouts (a JSON file; a damaged file is set aside with a warning)."""

    def __init__(self, path: str | Path | None = None) -> None:
        self.path = Path(path) if path is not None else config_dir() / FILE_NAME
        self.problem = ""
        self._data: dict[str, Any] = {"layouts": {}, "last": None}
        if self.path.exists():
            try:
                data = json.loads(self.path.read_text(encoding="utf-8"))
                if not isinstance(data, dict) or not isinstance(data.get("layouts"), dict):
                    raise ValueError("not a layouts file")
                self._data = {"layouts": data["layouts"], "last": data.get("last")}
            except (OSError, ValueError) as exc:
                self.problem = f"saved layouts in {self.path} could not be read ({exc}); " \
                               "the defaults are used"
                log.warning("%s", self.problem)

    def names(self) -> list[str]:
        """Saved layout names (sorted)."""
        return sorted(self._data["layouts"])

    def get(self, name: str) -> Layout | None:
        data = self._data["layouts"].get(name)
        return Layout.from_json(data) if data else None

    def put(self, name: str, layout: Layout) -> None:
        self._data["layouts"][name] = layout.to_json()
        self.save()

    def delete(self, name: str) -> None:
        if self._data["layouts"].pop(name, None) is not None:
            self.save()

    @property
    def last(self) -> Layout | None:
        data = self._data.get("last")
        return Layout.from_json(data) if data else None

    def remember(self, layout: Layout) -> None:
        """The layout in use at close (restored at the next launch)."""
        self._data["last"] = layout.to_json()
        self.save()

    def save(self) -> None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_suffix(".tmp")
            tmp.write_text(json.dumps(self._data, indent=1), encoding="utf-8")
            tmp.replace(self.path)
        except OSError as exc:
            self.problem = f"layouts could not be saved to {self.path}: {exc}"
            log.warning("%s", self.problem)
