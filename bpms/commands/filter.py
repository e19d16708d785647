"""``bpms filter RAW_FILE``: filter a whole raw recording as fast as the machine allows.

Writes the filtered CSV file (:mod:`bpms.io.filtered_file`, docs/filtered-file.md): time since
the start, host time, then roll, pitch, yaw of IMU 0..17, radians (``--degrees`` for degrees),
plus the 28 joint angles with ``--joints``, the per-IMU re-initialisation and disturbance
flags (``--no-flags`` leaves them out) and, with ``--estimates``, the gyro-bias and
body-acceleration estimates. The recording is opened through the one door
(:mod:`bpms.filter.door`): ``--calibration`` / ``--options`` > the recording's header > the
user's default > factory; the line ``calibration: …; options: …`` on stderr says which. Reads
native recordings and the original suite's pickled raw files (never executing code), chunk by
chunk (memory stays flat). Progress goes to stderr for long files.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bpms.analysis.cli_support import add_pose_calibration_option, add_reset_zero_option
from bpms.commands import CliError
from bpms.commands._shared import add_sources, refuse_existing
from bpms.io.options import ALGORITHMS


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "filter", help="filter a raw recording into a filtered CSV file",
        description="Filter a raw recording (no real-time pacing) into a filtered CSV file: "
                    "time, host time, then roll, pitch, yaw of IMU 0..17.")
    parser.add_argument("raw_file", metavar="RAW_FILE",
                        help="raw recording (.bpmsraw, or the original suite's pickled .txt)")
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="output file (default: Filtered… beside the raw file)")
    parser.add_argument("--degrees", action="store_true", help="angles in degrees (default rad)")
    parser.add_argument("--joints", action="store_true", help="add the 28 joint-angle columns")
    parser.add_argument("--estimates", action="store_true",
                        help="add each IMU's gyro-bias (rad/s) and body-acceleration (m/s², "
                             "observer/adaptive filters) estimates (docs/filtered-file.md)")
    parser.add_argument("--no-flags", dest="flags", action="store_false",
                        help="leave out the per-IMU re-initialisation and disturbance flags")
    add_sources(parser)
    parser.add_argument("--force", action="store_true", help="overwrite an existing output file")
    parser.add_argument("--filter", metavar="NAME",
                        help="attitude filter for all 18 IMUs: " + ", ".join(ALGORITHMS)
                             + " (default: the options' [filter] algorithm, normally mahony; "
                             "docs/filters.md)")
    add_reset_zero_option(parser)
    add_pose_calibration_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.commands._analysis import open_recording_for, stream
    from bpms.filter.door import (
        filtered_arrays,
        filtered_convention,
        filtered_layout,
        heading_header,
    )
    from bpms.io.background import InBackground
    from bpms.io.filtered_file.writer import FilteredWriter, default_output_path
    from bpms.io.paths import remove_regular_file

    t_start = time.perf_counter()
    if args.filter is not None and args.filter not in ALGORITHMS:
        raise CliError(f"unknown filter '{args.filter}' (choose {', '.join(ALGORITHMS)})")
    out_path = refuse_existing(Path(args.output) if args.output
                               else default_output_path(args.raw_file), args.force)
    opened = open_recording_for("filter", args.raw_file, args.calibration, args.options,
                                args.filter, reset_zero=args.reset_zero,
                                pose_calibration=args.pose_calibration, posture=args.posture)
    if opened.kind == "filtered":
        raise CliError(f"{args.raw_file}: is a filtered file already; give a raw recording")
    n = 0
    writer = None

    def write(chunk) -> None:  # in the background: a chunk's rows while the next is filtered
        res = chunk.result
        writer.write_block(res.t, host_time=chunk.host_time, hole=chunk.hole,
                           **filtered_arrays(res, writer.groups))

    try:
        if args.force:
            remove_regular_file(out_path)  # a file only (refuse_existing checked, and again)
        with InBackground(name="bpms-filtered-rows") as later:
            for chunk in stream("filter", opened):
                res = chunk.result
                if writer is None:
                    groups, kind = filtered_layout(res, args.joints,
                                                   args.flags, args.estimates)
                    writer = FilteredWriter(out_path, degrees=args.degrees, groups=groups,
                                            euler=kind, convention=filtered_convention(
                                                res.convention),
                                            meta={"source": Path(args.raw_file).name,
                                                  **heading_header(opened.processor.options)})
                later.submit(write, chunk)
                n += len(res)
    except OSError as exc:
        raise CliError(f"cannot write {out_path}: {exc.strerror or exc}") from exc
    finally:
        if writer is not None:
            writer.close()
    if n == 0:
        raise CliError(f"{args.raw_file}: the recording holds no frames")
    elapsed = time.perf_counter() - t_start
    print(f"{out_path}: {n} frames filtered in {elapsed:.1f} s "
          f"({n * 18 / max(elapsed, 1e-9) / 1e6:.2f} M IMU updates/s incl. file I/O)",
          file=sys.stderr)
    return 0
