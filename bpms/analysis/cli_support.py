"""Shared by the analysis commands: filter a recording with CLI error handling."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence

from bpms.commands import CliError


def add_filter_option(parser: argparse.ArgumentParser) -> None:
    """``--filter NAME`` (the attitude filter, docs/filters.md) and ``--heading hip|mean``
    (the body heading reference of Reset Zero)."""
    from bpms.io.options import FilterOptions

    choices = next(f.metadata["choices"] for f in dataclasses.fields(FilterOptions)
                   if f.name == "algorithm")
    parser.add_argument("--filter", dest="filter_name", choices=choices, default=None,
                        help="attitude filter (default: the options'; for walking 'observer' "
                             "or 'vqf', see docs/filters.md)")
    parser.add_argument("--heading", choices=("hip", "mean"), default=None,
                        help="body heading at Reset Zero: the hip IMU or the mean of "
                             "all IMUs (averages out mounting yaw errors; docs/body-model.md)")


def processed(command: str, path: str, calibration: str | None = None,
              options: str | None = None, zero_at_s: Sequence[float] = (),
              algorithm: str | None = None, heading: str | None = None):
    """:func:`bpms.analysis.source.process_recording` (a raw recording, or a filtered CSV),
    problems as warnings on stderr."""
    from bpms.analysis.source import process_recording
    from bpms.io.filtered_file import FilteredFileError
    from bpms.io.rawfile import RawFileError

    try:
        p = process_recording(path, calibration, options, zero_at_s, algorithm=algorithm,
                              heading=heading)
    except (RawFileError, FilteredFileError) as exc:
        raise CliError(str(exc)) from exc
    except OSError as exc:
        raise CliError(f"{path}: {exc.strerror or exc}") from exc
    if len(p.result) == 0:
        raise CliError(f"{path}: the recording holds no frames")
    for problem in p.result.problems:
        print(f"bpms {command}: warning: {problem}", file=sys.stderr)
    return p
