"""What the GUI remembers between launches: mode, port, UDP targets, recording folder, subject
name and window geometry.

An INI file (QSettings, IniFormat) in the user's configuration folder
(``bpms.io.userdirs.config_dir() / "gui.ini"``), so it lives beside the default options and
calibration, moves with ``BPMS_CONFIG_DIR`` (the tests use a fresh folder) and reads the same on
every platform. Nothing here is an option of the measurement: the options and calibration in
force stay the files of docs/configuration.md.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from PyQt6.QtCore import QByteArray, QSettings

from bpms.io.userdirs import config_dir

FILE_NAME = "gui.ini"

#: Remembered keys and their types.
KEYS: dict[str, type] = {
    "mode": str,
    "port": str,
    "udp_targets": str,  # comma-separated host:port
    "recording_dir": str,
    "subject": str,
    "startup_geometry": QByteArray,
    "main_geometry": QByteArray,
}


def settings_path() -> Path:
    """The remembered GUI settings' file."""
    return config_dir() / FILE_NAME


class SettingsStore:
    """Read and write the remembered values (missing ones read as None)."""

    def __init__(self, path: str | Path | None = None) -> None:
        self.path = Path(path) if path is not None else settings_path()
        self._qs = QSettings(str(self.path), QSettings.Format.IniFormat)

    def get(self, key: str) -> Any:
        if key not in KEYS or not self._qs.contains(key):
            return None
        value = self._qs.value(key)
        if KEYS[key] is str:
            return str(value) if value is not None else None
        return value if isinstance(value, QByteArray) else None

    def set(self, key: str, value: Any) -> None:
        if key not in KEYS:
            raise KeyError(f"not a remembered GUI setting: {key}")
        if value is None:
            self._qs.remove(key)
        else:
            self._qs.setValue(key, value)

    def sync(self) -> str | None:
        """Write to disk; None or why not (a read-only folder is not an error worth more than
        a log line: the GUI just forgets)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._qs.sync()
        if self._qs.status() != QSettings.Status.NoError:
            return f"cannot write {self.path}"
        return None


# -- hooks for the start-up and main windows (a few lines each there) ------------------------
def restore_startup(window: Any, store: SettingsStore | None = None) -> None:
    """Put the remembered values into a StartupWindow (before the user changes anything)."""
    store = store or SettingsStore()
    port = store.get("port")
    mode = store.get("mode")
    if mode in window.mode_buttons and not (mode == "suit" and port):
        window.select_mode(mode)
    if port and port != window.options.serial.port:
        # pre-selected (with the suit mode) only when a suit answers there now
        window.probe_remembered_port(port)
    if targets := store.get("udp_targets"):
        window.options.udp.forward_to = [t.strip() for t in targets.split(",") if t.strip()]
    if folder := store.get("recording_dir"):
        window.recording_dir = window.recording_dir or folder
    if subject := store.get("subject"):
        window.options.logging.name = subject
    if (geometry := store.get("startup_geometry")) is not None:
        window.restoreGeometry(geometry)


def forget_port(port: str, store: SettingsStore | None = None) -> None:
    """A port where GO found no suit is not offered again at the next launch."""
    store = store or SettingsStore()
    if store.get("port") == port:
        store.set("port", None)
        store.sync()


def remember_startup(window: Any, store: SettingsStore | None = None) -> None:
    """Keep the start-up window's choices (at GO)."""
    store = store or SettingsStore()
    store.set("mode", window.mode)
    store.set("port", window.port_combo.currentText().strip() or None)
    store.set("recording_dir", window.recording_dir)
    store.set("udp_targets", ", ".join(window.options.udp.forward_to))
    store.set("subject", window.options.logging.name or None)
    store.set("startup_geometry", window.saveGeometry())
    store.sync()


def saved_main_geometry(store: SettingsStore | None = None) -> QByteArray | None:
    """The main window's remembered geometry (``saveGeometry()`` bytes), or None; the
    window uses it only when it fits its screen (:mod:`bpms.gui.screen_fit`)."""
    return (store or SettingsStore()).get("main_geometry")


def remember_main(window: Any, panels: Any = None, store: SettingsStore | None = None) -> None:
    """Keep the main window's geometry, and from its ``panels`` (their ``file_panel`` and
    ``udp_panel``) the subject name and UDP targets (on close)."""
    store = store or SettingsStore()
    store.set("main_geometry", window.saveGeometry())
    panel = getattr(panels, "file_panel", None)
    if panel is not None and hasattr(panel, "name_edit"):
        store.set("subject", panel.name_edit.text().strip() or None)
    udp = getattr(panels, "udp_panel", None)
    if udp is not None and hasattr(udp, "targets_edit"):
        store.set("udp_targets", udp.targets_edit.text().strip() or None)
    store.sync()


__all__ = ["KEYS", "SettingsStore", "forget_port", "remember_main", "remember_startup",
           "restore_startup", "saved_main_geometry", "settings_path"]
