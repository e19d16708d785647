"""``bpms extract raw|filtered|vicon|qualisys``: the translators (docs/analysis.md) — one or several
IMUs, or one rigid body of a Vicon/Qualisys export, to a CSV whose header names every column
with its unit. Missing arguments are asked for when stdin is a terminal; otherwise they are a
usage error. See docs/analysis.md."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bpms.commands import CliError
from bpms.commands._shared import refuse_existing, warn

KINDS = ("raw", "filtered", "vicon", "qualisys")


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "extract", help="translators: one IMU / rigid body to CSV",
        description="Extract one or several IMUs from a raw recording (raw counts, or "
                    "calibrated with --calibrated) or a filtered file (Euler angles), or one "
                    "rigid body from a Vicon Nexus CSV / Qualisys 6DOF TSV export, to CSV.")
    parser.add_argument("kind", nargs="?", choices=KINDS, help="what the input file is")
    parser.add_argument("input", nargs="?", metavar="FILE", help="the file to read")
    parser.add_argument("--imu", nargs="+", metavar="ID",
                        help="IMU ids 0..17 (several, comma lists or 'all'; raw/filtered)")
    parser.add_argument("--body", metavar="NAME", help="rigid body name (vicon/qualisys)")
    parser.add_argument("--calibrated", action="store_true",
                        help="raw: calibrated values (m/s², gauss, rad/s) instead of counts")
    parser.add_argument("--calibration", metavar="Calib.cfg",
                        help="raw --calibrated: calibration file (default: the recording's)")
    parser.add_argument("--degrees", action="store_true", help="filtered: angles in degrees")
    parser.add_argument("-o", "--output", metavar="OUT.csv", help="output CSV file")
    parser.add_argument("--force", action="store_true", help="overwrite an existing output")
    return parser


def _ask(args: argparse.Namespace, name: str, prompt: str) -> None:
    """Fill a missing argument interactively (stdin a terminal) or fail with usage."""
    if getattr(args, name):
        return
    if not sys.stdin.isatty():
        raise CliError(f"missing {prompt}; usage: bpms extract raw|filtered RAW_FILE --imu ID "
                       "-o OUT.csv, or bpms extract vicon|qualisys FILE --body NAME -o OUT.csv")
    try:
        answer = input(f"{prompt}: ").strip()
    except EOFError:
        answer = ""
    if not answer:
        raise CliError(f"missing {prompt}")
    setattr(args, name, answer.split() if name == "imu" else answer)


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.extract import (
        ExtractError,
        filtered_rows,
        parse_imu_ids,
        raw_rows,
        write_csv,
    )
    from bpms.analysis.mocap_import import (
        MocapFormatError,
        UnknownBodyError,
        body_table,
        read_qualisys,
        read_vicon,
    )
    from bpms.io.filtered_file.reader import FilteredFileError
    from bpms.io.paths import remove_regular_file
    from bpms.io.rawfile import RawFileError

    _ask(args, "kind", "kind of input (raw, filtered, vicon, qualisys)")
    if args.kind not in KINDS:
        raise CliError(f"unknown kind {args.kind!r}: choose raw, filtered, vicon or qualisys")
    _ask(args, "input", "input file")
    if args.kind in ("raw", "filtered"):
        if not args.imu and sys.stdin.isatty():
            from bpms.analysis.extract import available_imus

            print(f"available IMUs: {available_imus()}, or all", file=sys.stderr)
        _ask(args, "imu", "IMU id(s)")
    else:
        _ask(args, "body", "rigid body name")
    _ask(args, "output", "output CSV file")
    out = refuse_existing(Path(args.output), args.force)
    problems: list[str] = []
    try:
        if args.kind == "raw":
            ids = parse_imu_ids(args.imu)
            columns, data, opened = raw_rows(args.input, ids, args.calibrated, args.calibration)
            print(f"bpms extract: {opened.sources_line()}", file=sys.stderr)
            problems = opened.problems
        elif args.kind == "filtered":
            ids = parse_imu_ids(args.imu)
            columns, data, problems = filtered_rows(args.input, ids, args.degrees)
            print("bpms extract: calibration: not used (filtered file: angles as logged); "
                  "options: not used", file=sys.stderr)
        else:
            reader = read_vicon if args.kind == "vicon" else read_qualisys
            columns, data = body_table(reader(args.input).body(args.body))
        try:
            rows = write_csv(out, columns, data)
        except OSError as exc:
            remove_regular_file(out)
            if exc.filename and str(exc.filename) == str(out):
                raise CliError(f"cannot write {out}: {exc.strerror or exc}") from exc
            raise
    except (ExtractError, MocapFormatError, UnknownBodyError, FilteredFileError,
            RawFileError) as exc:
        raise CliError(str(exc)) from exc
    except OSError as exc:
        raise CliError(f"{args.input}: {exc.strerror or exc}") from exc
    warn("extract", problems)
    if rows == 0 and args.kind == "filtered":
        remove_regular_file(out)
        raise CliError(f"{args.input}: the file holds no rows of data")
    print(f"{out}: {rows} rows × {len(columns)} columns", file=sys.stderr)
    return 0
