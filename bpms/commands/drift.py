"""``bpms drift RAW_FILE``: how far each sensor's attitude drifted between the calibration
pauses at the start and the end of a trial (found automatically), in degrees — total, heading
and inclination per IMU. See docs/analysis.md."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bpms.analysis.cli_support import add_filter_option
from bpms.commands import CliError
from bpms.commands._shared import add_sources, refuse_special_output


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "drift", help="attitude drift between the start and end calibration pauses",
        description="Finds the still calibration pauses at the start and the end of a trial "
                    "and reports each IMU's attitude change between them (degrees).")
    parser.add_argument("raw_file", metavar="RAW_FILE", help="raw recording")
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="also write the report as CSV")
    add_sources(parser, "the one stored in the recording", "the options stored in the recording")
    add_filter_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.drift import DriftInputError, drift_of_recording
    from bpms.commands._analysis import open_recording_for, stream
    from bpms.io.frames import IMU_NAMES

    opened = open_recording_for("drift", args.raw_file, args.calibration, args.options,
                                args.filter_name, args.heading, args.reset_zero)
    try:
        report = drift_of_recording(opened, stream("drift", opened))
    except DriftInputError as exc:
        raise CliError(str(exc)) from None
    if not report.ok:
        raise CliError(f"{args.raw_file}: {report.problem}")
    algorithm = opened.processor.options.filter.algorithm
    lines = ["imu,name,total_deg,heading_deg,inclination_deg"]
    lines += [f"{i},{name},{report.total_deg[i]:.2f},{report.heading_deg[i]:.2f},"
              f"{report.inclination_deg[i]:.2f}" for i, name in enumerate(IMU_NAMES)]
    print(f"filter {algorithm}: start pause ends {report.t_start:.2f} s, end pause starts "
          f"{report.t_end:.2f} s ({report.t_end - report.t_start:.1f} s apart)")
    print(f"{'IMU':>3}  {'segment':<16} {'total °':>8} {'heading °':>10} {'inclin. °':>10}")
    for i, name in enumerate(IMU_NAMES):
        print(f"{i:>3}  {name:<16} {report.total_deg[i]:8.2f} {report.heading_deg[i]:10.2f} "
              f"{report.inclination_deg[i]:10.2f}")
    if args.output:
        out = refuse_special_output(Path(args.output))
        try:
            out.write_text("\n".join(lines) + "\n", encoding="utf-8")
        except OSError as exc:
            raise CliError(f"cannot write {out}: {exc.strerror or exc}") from exc
        print(f"→ {out}", file=sys.stderr)
    return 0
