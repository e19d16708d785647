"""``bpms rom RAW_FILE... [--from T0 --to T1] [--reset-at T]``: range of motion — min,
max and range of every joint angle over a window, as CSV + Markdown tables and one PNG figure
per joint group; several files give a side-by-side comparison. See docs/analysis.md."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bpms.analysis.cli_support import add_filter_option, add_pose_calibration_option
from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, add_sources, number


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "rom", help="range-of-motion report (CSV, Markdown, PNG)",
        description="Range of motion of every joint angle (min, max, range in degrees) over a "
                    "time window; several recordings are compared side by side.")
    parser.add_argument("raw_files", nargs="+", metavar="RAW_FILE",
                        help="raw recording(s) or filtered .csv file(s)")
    parser.add_argument("--from", dest="t0", type=number(float, 0, LONGEST_S), metavar="T0",
                        help="window start, s since the recording started (default: start)")
    parser.add_argument("--to", dest="t1", type=number(float, 0, LONGEST_S), metavar="T1",
                        help="window end, s (default: end)")
    parser.add_argument("--reset-at", type=number(float, 0, LONGEST_S), action="append", default=[],
                        metavar="T",
                        help="extra Reset Zero at T s (repeatable; same for every file)")
    parser.add_argument("--label", action="append", default=[],
                        help="label per file, in order (default: the file stems)")
    parser.add_argument("-o", "--output-dir", metavar="DIR", default=".",
                        help="folder for rom.csv, rom.md and rom_<group>.png (default: .)")
    parser.add_argument("--name", default="rom", help="file name stem of the outputs")
    add_sources(parser, "each recording's, else your default")
    parser.add_argument("--no-figures", action="store_true", help="tables only")
    add_filter_option(parser)
    add_pose_calibration_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.rom import RomAccumulator, markdown, write_csv
    from bpms.analysis.stamp import recording_stamp
    from bpms.commands._analysis import open_recording_for, stream

    if args.t0 is not None and args.t1 is not None and args.t1 <= args.t0:
        raise CliError(f"--to ({args.t1} s) must be after --from ({args.t0} s)")
    if args.label and len(args.label) != len(args.raw_files):
        raise CliError(f"{len(args.label)} labels for {len(args.raw_files)} files")
    labels = args.label or [Path(f).stem for f in args.raw_files]
    tables = []
    for path, label in zip(args.raw_files, labels, strict=True):
        opened = open_recording_for("rom", path, args.calibration, args.options,
                                    args.filter_name, args.heading, args.reset_zero,
                                    args.pose_calibration, args.posture)
        acc = RomAccumulator(label, args.t0, args.t1)
        for chunk in stream("rom", opened, args.reset_at):
            acc.add(chunk.result.t, chunk.result.joint_angles)
        try:
            table = acc.table()
            table.stamp = recording_stamp(opened, args.reset_at)
            tables.append(table)
        except ValueError as exc:
            raise CliError(str(exc)) from exc
    out = Path(args.output_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_csv(out / f"{args.name}.csv", tables)
        text = markdown(tables)
        (out / f"{args.name}.md").write_text(text, encoding="utf-8")
        figures = []
        if not args.no_figures:
            from bpms.analysis.plots import rom_figures

            figures = rom_figures(tables, out, args.name)
    except OSError as exc:
        raise CliError(f"cannot write to {out}: {exc.strerror or exc}") from exc
    sys.stdout.write(text)
    print(f"{out / args.name}.csv, .md and {len(figures)} figures written", file=sys.stderr)
    return 0
