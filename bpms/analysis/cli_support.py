"""Command-line options shared by the analysis commands (argparse only; the command helpers
that open and stream recordings are in ``bpms.commands._analysis``)."""

from __future__ import annotations

import argparse
import dataclasses


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
                        help="body heading at Reset Zero: the hip IMU or the mean of all IMUs "
                             "(averages out mounting yaw errors; docs/analysis.md)")
    add_reset_zero_option(parser)


def add_reset_zero_option(parser: argparse.ArgumentParser) -> None:
    """``--reset-zero events|auto|at SECONDS|none`` (docs/opening-recordings.md)."""
    from bpms.filter.zero_choice import ResetZeroChoice

    def choice(text: str) -> ResetZeroChoice:
        try:
            return ResetZeroChoice.parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("--reset-zero: ")) from None

    parser.add_argument("--reset-zero", type=choice, default=None, metavar="CHOICE",
                        help="which Reset Zero: 'events' (default: the ones recorded live), "
                             "'auto' (made again, once still), 'at SECONDS' (e.g. 'at 12.5' "
                             "or 'at 12.5,30'), 'none' (docs/opening-recordings.md)")
