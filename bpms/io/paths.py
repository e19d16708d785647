"""Where the shipped (factory) calibration and option files live; what kind of thing a path
names (a regular file, a named pipe, a device), so that readers and writers refuse the rest."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parents[1]


def factory_dir() -> Path:
    """The shipped ``calib/`` folder: inside an installed wheel, or at the top of a checkout."""
    for candidate in (_PACKAGE_DIR / "calib", _PACKAGE_DIR.parent / "calib"):
        if (candidate / "Calib.cfg").is_file():
            return candidate
    raise FileNotFoundError("the shipped calib/ folder is missing from this installation")


def factory_calibration_path() -> Path:
    """The prototype's calibration (dissertation Table 2.2) in the legacy ``Calib.cfg`` format."""
    return factory_dir() / "Calib.cfg"


def factory_options_path() -> Path:
    """The factory options file."""
    return factory_dir() / "options.toml"


def special_kind(path: str | Path) -> str | None:
    """What ``path`` is when it exists and is neither a regular file nor a folder (``a named
    pipe``, ``a device``, ``a socket``; symbolic links followed), else None."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    if stat.S_ISFIFO(mode):
        return "a named pipe"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a socket" if stat.S_ISSOCK(mode) else "not a regular file"


def require_regular_input(path: str | Path) -> None:
    """Raise OSError (one-line ``strerror``) when ``path`` is a named pipe, a device or a
    socket: reading one would block for ever or never end (issue 43: a named pipe called
    ``x.bpmsraw`` blocked ``filter`` and ``replay``). Readers call it before they open a
    recording or a configuration file; a missing path or a folder is left to ``open``."""
    kind = special_kind(path)
    if kind is not None:
        raise OSError(errno.EINVAL, f"{kind}, not a file", str(path))


def remove_regular_file(path: str | Path) -> None:
    """Remove ``path`` when it is a regular file (or a symbolic link, which is removed, not
    what it points at); a missing path is fine. Anything else, a folder, a named pipe or a
    device (``/dev/null``), raises OSError and is left as it was (issue 43: ``filter
    --force`` unlinked ``/dev/null``)."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
        raise OSError(errno.EPERM, f"{special_kind(path) or 'a folder'}, not a file: "
                      "left in place", str(path))
    os.unlink(path)
