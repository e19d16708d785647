"""``bpms filter RAW_FILE``: filter a whole raw recording as fast as the machine allows.

Writes the filtered CSV file (:mod:`bpms.io.filtered_file`): time, then roll, pitch, yaw of
IMU 0..17, radians (``--degrees`` for degrees), plus the 28 joint angles with ``--joints``.
The calibration and options stored in the recording's header are used unless ``--calibration``
/ ``--options`` name files (legacy pickled raw files carry none: factory values). Reads native
recordings and the original suite's pickled raw files (never executing code). Progress goes
to stderr for long files.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from bpms.commands import CliError
from bpms.io.calib_file import CalibrationTable, load_calibration
from bpms.io.filtered_file import FilteredWriter, default_output_path
from bpms.io.frames import decode_frames
from bpms.io.options import FilterOptions, Options, load_options, options_from_dict
from bpms.io.rawfile import RawFileError
from bpms.io.recordings import open_recording
from bpms.progress import write_progress

CHUNK_FRAMES = 15_000  # 5 min of recording per kernel call (keeps memory flat)
PROGRESS_ABOVE_FRAMES = 30_000
FILTER_CHOICES = tuple(next(f for f in dataclasses.fields(FilterOptions)
                            if f.name == "algorithm").metadata["choices"])


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "filter", help="filter a raw recording into a filtered CSV file",
        description="Filter a raw recording (no real-time pacing) into a filtered CSV file: "
                    "time, then roll, pitch, yaw of IMU 0..17.")
    parser.add_argument("raw_file", metavar="RAW_FILE",
                        help="raw recording (.bpmsraw, or the original suite's pickled .txt)")
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="output file (default: Filtered… beside the raw file)")
    parser.add_argument("--degrees", action="store_true", help="angles in degrees (default rad)")
    parser.add_argument("--joints", action="store_true", help="add the 28 joint-angle columns")
    parser.add_argument("--calibration", metavar="Calib.cfg",
                        help="calibration file (default: the one stored in the recording)")
    parser.add_argument("--options", metavar="options.toml",
                        help="options file (default: the options stored in the recording)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing output file")
    parser.add_argument("--filter", metavar="NAME",
                        help="attitude filter for all 18 IMUs: " + ", ".join(FILTER_CHOICES)
                             + " (default: the options' [filter] algorithm, normally mahony; "
                             "docs/filters.md)")
    parser.set_defaults(run=run)
    return parser


def _calibration(args: argparse.Namespace, header: dict) -> CalibrationTable | None:
    if args.calibration:
        return load_calibration(args.calibration)
    values = header.get("calibration")
    if values is not None:
        try:
            return CalibrationTable(np.asarray(values, dtype=np.float64),
                                    source=f"{args.raw_file} header")
        except (ValueError, TypeError):
            print(f"bpms filter: warning: the calibration in {args.raw_file} is unusable; "
                  "factory calibration used", file=sys.stderr)
    return None


def _options(args: argparse.Namespace, header: dict) -> Options | None:
    if args.options:
        return load_options(args.options)
    stored = header.get("options")
    if isinstance(stored, dict) and stored:
        return options_from_dict(stored, f"{args.raw_file} header")
    return None


def run(args: argparse.Namespace) -> int:
    t_start = time.perf_counter()
    try:
        recording = open_recording(args.raw_file)
    except RawFileError as exc:
        raise CliError(str(exc)) from exc
    for problem in recording.problems:
        print(f"bpms filter: warning: {problem}", file=sys.stderr)
    n = len(recording)
    if n == 0:
        raise CliError(f"{args.raw_file}: the recording holds no frames")
    if args.filter is not None and args.filter not in FILTER_CHOICES:
        raise CliError(f"unknown filter '{args.filter}' (choose {', '.join(FILTER_CHOICES)})")
    out_path = Path(args.output) if args.output else default_output_path(args.raw_file)
    if out_path.exists() and not args.force:
        raise CliError(f"{out_path} exists (use --force to overwrite)")
    from bpms.filter.processor import BodyPoseProcessor  # numba: only when filtering
    from bpms.filter.vqf_filter import VqfMissingError

    options = _options(args, recording.header)
    if args.filter:
        options = options or Options()
        options.filter.algorithm = args.filter
    try:
        proc = BodyPoseProcessor(_calibration(args, recording.header), options)
    except VqfMissingError as exc:
        raise CliError(str(exc)) from exc
    for problem in proc.problems:
        print(f"bpms filter: warning: {problem}", file=sys.stderr)
    show = n > PROGRESS_ABOVE_FRAMES
    try:
        if args.force:
            out_path.unlink(missing_ok=True)
        with FilteredWriter(out_path, degrees=args.degrees, joints=args.joints) as writer:
            for lo in range(0, n, CHUNK_FRAMES):
                hi = min(n, lo + CHUNK_FRAMES)
                decoded = decode_frames(recording.frames[lo:hi].tobytes())
                result = proc.process(decoded.raw, decoded.errors)
                writer.write_block(result.t, result.euler,
                                   result.joint_angles if args.joints else None)
                if show:
                    write_progress(f"filtering {args.raw_file}: {100 * hi // n:3d}% "
                                   f"({hi}/{n} frames)", sys.stderr, final=hi >= n)
    except OSError as exc:
        raise CliError(f"cannot write {out_path}: {exc.strerror or exc}") from exc
    elapsed = time.perf_counter() - t_start
    print(f"{out_path}: {n} frames filtered in {elapsed:.1f} s "
          f"({n * 18 / max(elapsed, 1e-9) / 1e6:.2f} M IMU updates/s incl. file I/O)",
          file=sys.stderr)
    return 0

