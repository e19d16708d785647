"""``bpms track RAW_FILE [--declination DEG]``: the dead-reckoning walked path —
heel-strike times, per-step vectors and the 3-D track as CSV, plus a PNG plan view.
Thresholds come from the options (``[track]``) and can be overridden here.
See docs/analysis.md."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bpms.analysis.cli_support import add_filter_option
from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, add_sources, number, refuse_special_output


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "track", help="walked path by dead reckoning (CSV + PNG)",
        description="Heel strikes, per-step vectors and the 3-D walked path of a recording.")
    parser.add_argument("raw_file", metavar="RAW_FILE", help="raw recording")
    parser.add_argument("--declination", type=number(float, -180, 180), metavar="DEG",
                        help="magnetic declination, deg east (default: options track."
                             "declination_deg)")
    parser.add_argument("--threshold-g", type=number(float, 0, above=True), metavar="G",
                        help="heel-strike threshold, g (default: options track.heel_strike_g)")
    parser.add_argument("--min-interval", type=number(float, 0, LONGEST_S), metavar="S",
                        help="minimum time between heel strikes, s (default: options)")
    parser.add_argument("--detector", choices=("auto", "accel", "gyro"), default="auto",
                        help="heel strikes from the feet's accelerometers or the shanks' "
                             "gyroscopes (default auto: gyro when the recording was made at "
                             "±2 g, where the accelerometer peaks clip; docs/analysis.md)")
    parser.add_argument("--include-hips", action="store_true",
                        help="feet measured from the pelvis centre (dissertation eq. 3.13): "
                             "the path zig-zags by the hip width")
    parser.add_argument("--from", dest="t0", type=number(float, 0, LONGEST_S),
                        metavar="T0", help="start, s")
    parser.add_argument("--to", dest="t1", type=number(float, 0, LONGEST_S),
                        metavar="T1", help="end, s")
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="track CSV (default: <raw stem>_track.csv); the PNG beside it")
    add_sources(parser)
    parser.add_argument("--no-figure", action="store_true", help="CSV only")
    add_filter_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.root_path import StrikeFinder
    from bpms.commands._analysis import open_recording_for, stream

    opened = open_recording_for("track", args.raw_file, args.calibration, args.options,
                                args.filter_name, args.heading, args.reset_zero)
    if not opened.has_raw:
        raise CliError(f"{args.raw_file}: heel strikes need the foot accelerometers: give the "
                       "raw recording, not a filtered file")
    finder = StrikeFinder(opened.processor, opened.header, args.detector,
                          threshold_g=args.threshold_g, min_interval_s=args.min_interval,
                          declination_deg=args.declination, include_hips=args.include_hips)
    for chunk in stream("track", opened):
        t = chunk.result.t
        window = np.ones(len(t), dtype=bool)
        if args.t0 is not None:
            window &= t >= args.t0
        if args.t1 is not None:
            window &= t <= args.t1
        finder.add(chunk, window)
    detector = finder.detector
    track = finder.track()
    peak_col = "swing_peak_rad_s" if detector == "gyro" else "peak_g"
    out = Path(args.output) if args.output else Path(args.raw_file).with_suffix("")
    out = refuse_special_output(out if out.suffix == ".csv"
                                else out.with_name(out.name + "_track.csv"))
    try:
        with open(out, "w", encoding="utf-8", newline="\n") as f:
            f.write(f"step,time_s,side,{peak_col},step_north_m,step_east_m,step_down_m,"
                    "north_m,east_m,down_m\n")
            for k in range(len(track.times)):
                s, pos = track.steps[k], track.positions[k]
                f.write(f"{k + 1},{track.times[k]:.3f},{track.sides[k]},{track.peaks[k]:.3f},"
                        f"{s[0]:.4f},{s[1]:.4f},{s[2]:.4f},{pos[0]:.4f},{pos[1]:.4f},"
                        f"{pos[2]:.4f}\n")
        figure = None
        if not args.no_figure:
            from bpms.analysis.plots import track_figure

            figure = track_figure(track, out.with_suffix(".png"), Path(args.raw_file).name)
    except OSError as exc:
        raise CliError(f"cannot write {out}: {exc.strerror or exc}") from exc
    how = (f"gyroscope detector, recording at ±{finder.range_g:g} g" if detector == "gyro"
           else f"threshold {finder.threshold_g:.2f} g")
    print(f"{len(track.times)} heel strikes ({how}, ≥ {finder.min_interval_s:.2f} s "
          f"apart), path {track.length_m:.2f} m, declination {finder.declination_deg:.1f}° "
          f"→ {out}"
          + (f", {figure}" if figure else ""), file=sys.stderr)
    return 0
