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


def add_pose_calibration_option(parser: argparse.ArgumentParser) -> None:
    """``--pose-calibration reset-zero|posture|functional`` and ``--posture``
    (docs/pose-calibration.md)."""
    from bpms.filter.pose_methods import METHODS

    parser.add_argument("--pose-calibration", choices=METHODS, default=None,
                        help="sensor-to-segment calibration: reset-zero (default: the neutral "
                             "pose), posture (the still window in the --posture declared), "
                             "functional (from the movements after the still window)")
    parser.add_argument("--posture", default=None, metavar="POSTURE",
                        help="with --pose-calibration posture: neutral, suit or measured joint "
                             "angles in degrees, e.g. 'elbow_r.flexion=15,knee_r.flexion=12'")
