"""Logging for the ``bpms`` commands: warnings (more with ``-v``) on stderr, and for the app and
the field recorder a rotating log file in the per-user log folder
(:func:`bpms.io.userdirs.log_dir`), so that what happened in the field can be read later."""

from __future__ import annotations

import logging
import logging.handlers
import sys
from pathlib import Path

LOG_FILE_NAME = "bpms.log"
LOG_FILE_BYTES = 2_000_000  # rotate at about 2 MB ...
LOG_FILE_BACKUPS = 3  # ... keeping three older files
_FORMAT = "%(levelname)s %(name)s: %(message)s"
_FILE_FORMAT = "%(asctime)s %(levelname)s %(name)s [%(threadName)s]: %(message)s"

#: Loggers whose warnings are problems in the user's files that are also collected in a
#: ``problems`` list, which every command prints itself as ``bpms CMD: warning: ...``. On the
#: console they would appear twice, so there they show only with ``-v``; the log file keeps
#: them always.
REPORTED_BY_COMMANDS = ("bpms.config", "bpms.io.rawfile", "bpms.io.legacy_raw")


class _NotReportedTwice(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not (record.levelno < logging.ERROR
                    and record.name.startswith(REPORTED_BY_COMMANDS))


def log_file_path() -> Path:
    """The current log file (``bpms.log`` in the per-user log folder)."""
    from bpms.io.userdirs import log_dir

    return log_dir() / LOG_FILE_NAME


def configure_logging(verbosity: int = 0, command: str | None = None,
                      to_file: bool = False) -> Path | None:
    """Console logging at WARNING (``verbosity`` 1: INFO, 2: DEBUG) on stderr, plus, when
    ``to_file``, INFO and above into the rotating log file. Returns the log file's path, or
    None when there is none (not asked for, or the folder cannot be written: said once on
    stderr, the command goes on)."""
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(max(verbosity, 0), 2)]
    root = logging.getLogger()
    for handler in list(root.handlers):  # called again (tests call main() repeatedly)
        if getattr(handler, "_bpms", False):
            root.removeHandler(handler)
            handler.close()
    console = logging.StreamHandler(sys.stderr)
    console.setLevel(level)
    console.setFormatter(logging.Formatter(_FORMAT))
    if verbosity <= 0:
        console.addFilter(_NotReportedTwice())
    console._bpms = True  # type: ignore[attr-defined]
    root.addHandler(console)
    root.setLevel(level)
    if not to_file:
        return None
    path = log_file_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handler = logging.handlers.RotatingFileHandler(
            path, maxBytes=LOG_FILE_BYTES, backupCount=LOG_FILE_BACKUPS, encoding="utf-8")
    except OSError as exc:
        print(f"bpms: no log file ({path}: {exc.strerror or exc})", file=sys.stderr)
        return None
    handler.setLevel(min(level, logging.INFO))
    handler.setFormatter(logging.Formatter(_FILE_FORMAT))
    handler._bpms = True  # type: ignore[attr-defined]
    root.addHandler(handler)
    root.setLevel(min(level, logging.INFO))
    logging.getLogger("bpms").info("bpms %s started", command or "")
    return path
