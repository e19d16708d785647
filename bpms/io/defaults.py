"""The user's defaults: the options and calibration a session starts from when none is given.

Precedence everywhere (docs/configuration.md): an explicit file > the recording's header > the
user's default (``bpms.io.userdirs.config_dir()``) > the shipped factory files. This module
owns the last two steps: it returns the user's default when one was saved, else the factory
one, and says which (``source``).
"""

from __future__ import annotations

import logging

from bpms.io.calib_file import CalibrationTable, load_calibration
from bpms.io.options import Options, load_options
from bpms.io.userdirs import default_calibration_path, default_options_path

log = logging.getLogger("bpms.config")


def default_options() -> Options:
    """The user's default options, or the factory options when none were saved."""
    path = default_options_path()
    if path.is_file():
        options = load_options(path)
        options.source = f"user default ({path})"
        return options
    options = Options()
    options.source = "factory"
    return options


def default_calibration() -> CalibrationTable:
    """The user's default calibration, or the shipped factory table when none was saved."""
    path = default_calibration_path()
    if path.is_file():
        table = load_calibration(path)
        if not table.problems:
            table.source = f"user default ({path})"
        return table
    return load_calibration(None)
