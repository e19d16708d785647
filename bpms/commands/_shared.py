"""What several commands share (not a command: the leading underscore): the options naming
the calibration and options files a recording is processed with, the type of every numeric
option (:func:`number`: finite and in range), the refusal to overwrite an output, warnings on
stderr, the binary formats' packages and Ctrl-C / SIGTERM handling."""

from __future__ import annotations

import argparse
import math
import signal
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

from bpms.commands import CliError
from bpms.io.timebase import LONGEST_S

__all__ = ["LONGEST_S", "add_sources", "number", "refuse_existing", "refuse_special_output",
           "require_formats", "stop_on_signals", "warn"]


def add_sources(parser: argparse.ArgumentParser,
                default: str = "the recording's, else your default",
                options_default: str | None = None) -> None:
    """``--calibration Calib.cfg`` and ``--options options.toml``; ``default`` (and
    ``options_default``, else the same) says in their help what is used without them."""
    parser.add_argument("--calibration", metavar="Calib.cfg",
                        help=f"calibration file (default: {default})")
    parser.add_argument("--options", metavar="options.toml",
                        help=f"options file (default: {options_default or default})")


def number(kind: type = float, low: float | None = None, high: float | None = None, *,
           above: bool = False) -> Callable[[str], float]:
    """The argparse ``type`` of a numeric option: ``kind(text)`` (float or int), finite and
    within ``low`` … ``high`` (``above``: strictly more than ``low``); anything else is refused
    with argparse's one-line error, exit 2 (issue 43: ``nan`` and ``inf`` hung or crashed
    commands). Every numeric option of every command uses it (tests/test_cli_numbers.py)."""
    kind_name = "an integer" if kind is int else "a number"

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"'{text}' is not {kind_name}") from None
        if kind is float and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"'{text}' is not a finite number")
        too_low = low is not None and (value < low or (above and value == low))
        if too_low or (high is not None and value > high):
            low_text = f"{'more than' if above else 'at least'} {low:g}" if low is not None \
                else ""
            high_text = f"at most {high:g}" if high is not None else ""
            raise argparse.ArgumentTypeError(
                f"{text}: must be {' and '.join(t for t in (low_text, high_text) if t)}")
        return value

    parse.bounds = (kind, low, high, above)  # type: ignore[attr-defined]  (for the tests)
    parse.__name__ = kind.__name__
    return parse


def refuse_existing(path: Path, force: bool) -> Path:
    """``path``; a CliError when it exists and ``--force`` was not given, or when it is not a
    file that ``--force`` may replace: a folder, a named pipe or a device such as
    ``/dev/null`` is never replaced (nor written through)."""
    from bpms.io.paths import special_kind

    kind = special_kind(path) or ("a folder" if path.is_dir() else None)
    if kind is not None:
        raise CliError(f"{path} is {kind}, not a file: give the name of a file to write "
                       "(--force replaces only a file)")
    if path.exists() and not force:
        raise CliError(f"{path} exists (use --force to overwrite)")
    return path


def refuse_special_output(path: Path) -> Path:
    """``path``; a CliError when it is a named pipe or a device (writing would block or go
    nowhere): for commands that overwrite their output without ``--force``."""
    from bpms.io.paths import special_kind

    kind = special_kind(path)
    if kind is not None:
        raise CliError(f"{path} is {kind}, not a file: give the name of a file to write")
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
