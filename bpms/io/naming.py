"""Recording file names, as the original suite named them (docs/pipeline.md).

``Raw_<name>_<seq>.bpmsraw`` and ``Filtered_<name>_<seq>.csv``: ``name`` is the user's file
name, or a time stamp ``YYYYmmdd-HHMMSS`` when none is given; ``seq`` grows by one at each
Start/Stop Logging. Existing files are never overwritten: a taken number is skipped.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

RAW_PREFIX = "Raw"
FILTERED_PREFIX = "Filtered"
RAW_SUFFIX = ".bpmsraw"
FILTERED_SUFFIX = ".csv"
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
#: Longest stem kept: whole names stay far below every file system's limit (255 characters on
#: Windows, macOS and Linux) and Windows' classic 260-character paths.
MAX_STEM = 80


def safe_stem(name: str) -> str:
    """A file-system-safe version of a user-typed name ('' stays ''): only ASCII letters,
    digits, ``.``, ``_`` and ``-``, so no path separator (``/`` or ``\\``) nor any character
    Windows forbids (``<>:"|?*``) survives; at most :data:`MAX_STEM` characters."""
    return _UNSAFE.sub("_", name.strip()).strip("._")[:MAX_STEM].strip("._")


def recordings_folder(directory: str | Path | None) -> Path:
    """The folder new recordings go to: ``directory`` when given (an option or ``-o``), else the
    per-user recordings folder (:func:`bpms.io.userdirs.recordings_dir`)."""
    if directory is None or not str(directory).strip():
        from bpms.io.userdirs import recordings_dir

        return recordings_dir()
    return Path(directory).expanduser()


class RecordingNamer:
    """Hands out the next pair of names in ``directory`` for one session.

    ``directory``: empty or None = the per-user recordings folder. The stem is fixed at the
    first call (user name or time stamp). Each :meth:`next_paths`
    returns ``(raw_path, filtered_path)`` with a sequence number higher than every existing
    file of that stem, so names never collide with earlier sessions either.
    """

    def __init__(self, directory: str | Path | None, name: str = "") -> None:
        self.directory = recordings_folder(directory)
        self._name = safe_stem(name)
        self.sequence = 0

    @property
    def stem(self) -> str:
        if not self._name:
            self._name = time.strftime("%Y%m%d-%H%M%S")
        return self._name

    def _taken(self) -> int:
        pattern = re.compile(
            rf"^(?:{RAW_PREFIX}|{FILTERED_PREFIX})_{re.escape(self.stem)}_(\d+)\.")
        highest = 0
        if self.directory.is_dir():
            for path in self.directory.iterdir():
                match = pattern.match(path.name)
                if match:
                    highest = max(highest, int(match.group(1)))
        return highest

    def next_paths(self) -> tuple[Path, Path]:
        """Names for the next Start Logging: ``(Raw_..., Filtered_...)``."""
        self.sequence = max(self.sequence, self._taken()) + 1
        base = f"{self.stem}_{self.sequence}"
        return (self.directory / f"{RAW_PREFIX}_{base}{RAW_SUFFIX}",
                self.directory / f"{FILTERED_PREFIX}_{base}{FILTERED_SUFFIX}")
