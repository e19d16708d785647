"""``bpms compare RAW_FILE OPTICAL_FILE [--map MAP]``: the recording against an optical
motion-capture export (Vicon Nexus CSV, Qualisys TSV): clocks and frames aligned from the data,
errors per segment and per joint angle, CSV + Markdown + figures (+ ``--json``). See
docs/compare.md."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bpms.analysis.cli_support import add_filter_option
from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, add_sources, number, warn


def _window(text: str) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected START:END in seconds") from None
    if not b > a:
        raise argparse.ArgumentTypeError(f"{text!r}: END must be after START")
    return a, b


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "compare", help="compare a recording with optical motion capture (Vicon, Qualisys)",
        description="Compare a recording with an optical motion-capture export (Vicon Nexus "
                    "CSV, Qualisys TSV): the clock offset and each segment's IMU-to-cluster "
                    "and world rotations estimated from the data, then per segment the "
                    "orientation error (inclination, heading, drift) and per joint angle the "
                    "errors and a Bland-Altman summary (docs/compare.md).")
    parser.add_argument("raw_file", metavar="RAW_FILE", help="raw recording (or filtered .csv)")
    parser.add_argument("optical_file", metavar="OPTICAL_FILE",
                        help="Vicon Nexus .csv or Qualisys QTM 6DOF .tsv export")
    parser.add_argument("--map", metavar="MAP",
                        help="file pairing optical bodies with BPMS segments, one "
                             "'Body = Segment' per line (default: the standard Nexus and QTM "
                             "full-body names)")
    parser.add_argument("--offset", type=number(float, -LONGEST_S, LONGEST_S), metavar="S",
                        help="clock offset in s (recording time = optical time + S) instead of "
                             "the cross-correlation of the angular rates")
    parser.add_argument("--align", choices=("sensors", "orientation", "none"),
                        default="sensors",
                        help="world rotation from the IMU's gravity and magnetic north "
                             "('sensors', default), by least squares on the orientations "
                             "('orientation': also absorbs the filter's constant errors), or "
                             "none (the export is already in the IMU's frames)")
    parser.add_argument("--alignment", metavar="JSON",
                        help="use the rotations of this file (a 'bpms compare --json' output) "
                             "instead of estimating them")
    parser.add_argument("--window", type=_window, metavar="START:END",
                        help="estimate the frame alignment over this span of the recording, s "
                             "(default: the whole overlap)")
    parser.add_argument("-o", "--output-dir", metavar="DIR", default=".",
                        help="folder for the outputs (default: .)")
    parser.add_argument("--name", default="compare",
                        help="file name stem: NAME.csv, NAME.md, NAME_series.csv, "
                             "NAME_errors.png, NAME_bland_altman.png")
    parser.add_argument("--no-figures", action="store_true", help="tables only")
    parser.add_argument("--json", action="store_true",
                        help="print the results as JSON on stdout (instead of the report)")
    add_sources(parser)
    add_filter_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.compare import CompareError, compare, load_recording, read_optical
    from bpms.analysis.compare_map import resolve_map
    from bpms.analysis.compare_report import (
        figures,
        markdown,
        read_alignment,
        to_dict,
        write_csv,
        write_series_csv,
    )
    from bpms.commands._analysis import open_recording_for

    if not Path(args.optical_file).is_file():
        raise CliError(f"{args.optical_file}: no such file")
    if args.map is not None and not Path(args.map).is_file():
        raise CliError(f"{args.map}: no such map file")
    given = None
    if args.alignment:
        try:
            given = read_alignment(args.alignment)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    try:
        export = read_optical(args.optical_file)
        resolve_map(export, args.map)  # a bad map or a missing body before the long part
        opened = open_recording_for("compare", args.raw_file, args.calibration, args.options,
                                    args.filter_name, args.heading, args.reset_zero)
        shown = set(opened.problems)  # printed by open_recording_for
        rec = load_recording(args.raw_file, opened)
        warn("compare", [p for p in opened.problems if p not in shown])
        result = compare(rec, export, args.map, offset_s=args.offset, align=args.align,
                         window=args.window, given=given, recording_name=str(args.raw_file))
    except CompareError as exc:
        raise CliError(str(exc)) from None
    warn("compare", result.warnings)
    out = Path(args.output_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_csv(out / f"{args.name}.csv", result)
        write_series_csv(out / f"{args.name}_series.csv", result)
        text = markdown(result)
        (out / f"{args.name}.md").write_text(text, encoding="utf-8")
        pngs = [] if args.no_figures else figures(result, out, args.name)
    except OSError as exc:
        raise CliError(f"cannot write to {out}: {exc.strerror or exc}") from exc
    if args.json:
        json.dump(to_dict(result), sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(text)
    print(f"{out / args.name}.csv, _series.csv, .md and {len(pngs)} figures written",
          file=sys.stderr)
    return 0
