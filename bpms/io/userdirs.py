"""Per-user folders: settings, recordings and logs, in each platform's usual place.

Linux follows XDG (``~/.config/bpms``, ``~/.local/share/bpms``, ``~/.local/state/bpms/log``),
Windows uses ``%LOCALAPPDATA%\\bpms`` and macOS ``~/Library/Application Support/bpms``.
Each folder can be moved with an environment variable, which the tests use to start from a
fresh per-user folder:

============================  =================================
variable                      folder
============================  =================================
``BPMS_CONFIG_DIR``           default options and calibration
``BPMS_DATA_DIR``             recordings (``recordings/`` inside)
``BPMS_LOG_DIR``              log files
============================  =================================

Nothing here creates a folder: callers create one when they first write into it.
"""

from __future__ import annotations

import os
from pathlib import Path

APP_NAME = "bpms"


def _platform_dirs():
    import platformdirs

    return platformdirs.PlatformDirs(APP_NAME, appauthor=False)


def _override(variable: str) -> Path | None:
    value = os.environ.get(variable, "").strip()
    return Path(value).expanduser() if value else None


def config_dir() -> Path:
    """Where the user's default options and calibration live."""
    return _override("BPMS_CONFIG_DIR") or Path(_platform_dirs().user_config_dir)


def data_dir() -> Path:
    """The user's data folder (recordings go into ``recordings/`` inside it)."""
    return _override("BPMS_DATA_DIR") or Path(_platform_dirs().user_data_dir)


def recordings_dir() -> Path:
    """The default folder for new recordings."""
    return data_dir() / "recordings"


def log_dir() -> Path:
    """Where log files go."""
    return _override("BPMS_LOG_DIR") or Path(_platform_dirs().user_log_dir)


def default_options_path() -> Path:
    """The user's default options file (absent until the user saves one)."""
    return config_dir() / "options.toml"


def default_calibration_path() -> Path:
    """The user's default sensor calibration in the legacy ``Calib.cfg`` format (absent until the
    user saves one)."""
    return config_dir() / "Calib.cfg"
