"""The user's defaults: the options and calibration a session starts from when none is given.

Precedence everywhere (docs/configuration.md): an explicit file > the recording's header > the
user's default (``bpms.io.userdirs.config_dir()``) > the shipped factory files. This module
owns the last two steps: it returns the user's default when one was saved, else the factory
one, and says which (``source``).

When a default is missing, entry points (the CLI commands, the GUI) say so once per process:
one line through the ``bpms.config`` logger (stderr for the CLI, the log for the GUI). The
Python API (``BodyPoseProcessor()``) takes the defaults silently (``announce=False``).
"""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

from bpms.io.calib_file import CalibrationTable, as_table, load_calibration
from bpms.io.options import Options, load_options
from bpms.io.userdirs import config_dir, default_calibration_path, default_options_path

# not "bpms.config": that logger carries file problems, which commands print themselves
log = logging.getLogger("bpms.defaults")

_announced: set[str] = set()


def _announce_factory(kind: str) -> None:
    """The one-line notice that ``kind`` ('options' / 'calibration') is the factory one: one
    line naming every default missing at that moment, once per process."""
    if kind in _announced:
        return
    missing = [name for name, path in (("options", default_options_path()),
                                       ("calibration", default_calibration_path()))
               if not path.is_file()] or [kind]
    _say_factory(missing)


def _say_factory(missing: list[str]) -> None:
    """The notice itself, for the defaults ``missing`` (kinds), marked as said."""
    _announced.update(missing)
    what = " and ".join(missing)
    log.warning("no saved default %s in %s: factory %s used (save with "
                "'bpms config save-default')", what, config_dir(), what)


def announce_factory(options: bool = True, calibration: bool = True) -> None:
    """Say (once per process, one line) which of the defaults asked for are missing; for entry
    points that read their files quietly first and speak once the session really starts."""
    wanted = [("options", default_options_path(), options),
              ("calibration", default_calibration_path(), calibration)]
    missing = [kind for kind, path, asked in wanted if asked and not path.is_file()]
    if missing and not set(missing) <= _announced:
        _say_factory(missing)


def default_options(announce: bool = True) -> Options:
    """The user's default options, or the factory options when none were saved
    (``announce``: say so once per process)."""
    path = default_options_path()
    if path.is_file():
        options = load_options(path)
        options.source = f"user default ({path})"
        return options
    if announce:
        _announce_factory("options")
    return Options()  # source "factory"


def default_calibration(announce: bool = True) -> CalibrationTable:
    """The user's default calibration, or the shipped factory table when none was saved
    (``announce``: say so once per process)."""
    path = default_calibration_path()
    if path.is_file():
        table = load_calibration(path)
        if not table.problems:
            table.source = f"user default ({path})"
        return table
    if announce:
        _announce_factory("calibration")
    return load_calibration(None)


def calibration_source(announce: bool = True) -> str:
    """Where the calibration used when none is given comes from: ``user default (PATH)`` or
    ``factory`` (``announce``: the once-per-process notice when factory)."""
    path = default_calibration_path()
    if path.is_file():
        return f"user default ({path})"
    if announce:
        _announce_factory("calibration")
    return "factory"


def options_or_default(path: str | Path | None, announce: bool = True) -> Options:
    """``path``'s options when given (explicit file), else :func:`default_options`."""
    return load_options(path) if path else default_options(announce)


def calibration_or_default(path: str | Path | None, announce: bool = True) -> CalibrationTable:
    """``path``'s calibration when given (explicit file), else :func:`default_calibration`."""
    return load_calibration(path) if path else default_calibration(announce)


def save_default_options(options: Options | str | Path) -> Path:
    """Make ``options`` (an Options object or an options file) the user's default; returns
    the default file's path. A file is copied as it is (comments kept) after a check that it
    reads without problems (``ValueError`` naming them otherwise)."""
    from bpms.io.options import save_options

    target = default_options_path()
    target.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(options, Options):
        save_options(options, target)
        return target
    loaded = load_options(options)
    if loaded.problems:
        raise ValueError("; ".join(str(p) for p in loaded.problems))
    _copy(Path(options), target)
    return target


def save_default_calibration(calibration: CalibrationTable | str | Path) -> Path:
    """Make ``calibration`` (a table or a ``Calib.cfg`` file) the user's default; returns the
    default file's path. A file with problems is refused (``ValueError`` naming them)."""
    from bpms.io.calib_file import save_legacy

    target = default_calibration_path()
    target.parent.mkdir(parents=True, exist_ok=True)
    table = (load_calibration(calibration) if isinstance(calibration, str | Path)
             else as_table(calibration))
    if table.problems:
        raise ValueError("; ".join(str(p) for p in table.problems))
    save_legacy(table, target)
    # the modern companion (magnetometer ellipsoid fits) goes along when there is one
    companion = target.with_suffix(".json")
    if isinstance(calibration, str | Path) and Path(calibration).with_suffix(
            ".json").is_file():
        _copy(Path(calibration).with_suffix(".json"), companion)
    elif companion.is_file():
        companion.unlink()  # a stale fit must not meet another table
    return target


def _copy(source: Path, target: Path) -> None:
    tmp = target.with_name(target.name + ".tmp")
    shutil.copyfile(source, tmp)
    tmp.replace(target)
