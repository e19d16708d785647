"""What several commands share (not a command: the leading underscore): the options naming
the calibration and options files a recording is processed with, the refusal to overwrite an
output, warnings on stderr, the binary formats' packages and Ctrl-C / SIGTERM handling."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Iterable
from pathlib import Path

from bpms.commands import CliError


def add_sources(parser: argparse.ArgumentParser,
                default: str = "the recording's, else your default",
                options_default: str | None = None) -> None:
    """``--calibration Calib.cfg`` and ``--options options.toml``; ``default`` (and
    ``options_default``, else the same) says in their help what is used without them."""
    parser.add_argument("--calibration", metavar="Calib.cfg",
                        help=f"calibration file (default: {default})")
    parser.add_argument("--options", metavar="options.toml",
                        help=f"options file (default: {options_default or default})")


def refuse_existing(path: Path, force: bool) -> Path:
    """``path``; a CliError when it exists and ``--force`` was not given."""
    if path.exists() and not force:
        raise CliError(f"{path} exists (use --force to overwrite)")
    return path


def warn(command: str, problems: Iterable[str], flush: bool = False) -> None:
    """Each problem as a line ``bpms COMMAND: warning: …`` on stderr."""
    for problem in problems:
        print(f"bpms {command}: warning: {problem}", file=sys.stderr, flush=flush)


def require_formats(kinds: Iterable[str]) -> None:
    """A CliError naming the missing package when a binary format (mat, parquet) cannot be
    written here."""
    from bpms.analysis.binary_out import MissingPackageError, check_available

    try:
        for kind in kinds:
            check_available(kind)
    except MissingPackageError as exc:
        raise CliError(str(exc)) from None


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def stop_on_signals() -> None:
    """SIGTERM and Ctrl-C raise KeyboardInterrupt, Ctrl-C even when the command was started
    in the background (where SIGINT is otherwise ignored)."""
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, signal.default_int_handler)
