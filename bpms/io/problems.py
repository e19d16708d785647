"""Problems found in user files: reported, counted and logged, never raised to the user."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger("bpms.config")


@dataclass(frozen=True)
class FileProblem:
    """One problem in one file, with enough location to find it by hand."""

    path: str
    where: str  # e.g. "line 3", "IMU 4 field 7 (AyMax)", "key filter.kp_yaw"
    message: str
    fallback: str  # what was used instead

    def __str__(self) -> str:
        return f"{self.path}: {self.where}: {self.message}; {self.fallback}"


def report(problems: list[FileProblem], path: str | Path, where: str, message: str,
           fallback: str) -> None:
    """Append a problem to ``problems`` and log it as a warning."""
    problem = FileProblem(str(path), where, message, fallback)
    problems.append(problem)
    log.warning("%s", problem)
