"""``bpms export opensim|bvh|matlab RAW_FILE``: exports for the biomechanics ecosystem.

- ``opensim``: OpenSense orientations ``<stem>_orientations.sto`` (whole trial) and
  ``<stem>_calibration.sto`` (the calibration-pose window of the automatic Reset Zero);
- ``bvh``: the stick figure as ``<stem>.bvh`` (centimetres, y up);
- ``matlab``: ``<stem>_matlab.csv`` (time, every IMU's quaternion and Euler angles, every
  joint angle).

See docs/analysis.md (formats, axes, the IMU placer's rotation)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bpms.analysis.cli_support import add_filter_option
from bpms.commands import CliError


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "export", help="export a recording to OpenSim .sto, BVH or a MATLAB CSV",
        description="Filter a raw recording and export it: OpenSim OpenSense orientations "
                    "(.sto), a BVH of the stick figure, or a CSV for MATLAB.")
    parser.add_argument("format", choices=("opensim", "bvh", "matlab"))
    parser.add_argument("raw_file", metavar="RAW_FILE",
                        help="raw recording, or a filtered .csv (Reset Zero redone on it)")
    parser.add_argument("-o", "--output", metavar="PATH",
                        help="output file (opensim: the stem of the two .sto files); "
                             "default beside the raw file")
    parser.add_argument("--reset-at", type=float, action="append", default=[], metavar="T",
                        help="extra Reset Zero at T s (repeatable)")
    parser.add_argument("--head-neck", action="store_true",
                        help="opensim: add head_imu and neck_imu (models with a head)")
    parser.add_argument("--radians", action="store_true", help="matlab: angles in radians")
    parser.add_argument("--calibration", metavar="Calib.cfg",
                        help="calibration file (default: the one stored in the recording)")
    parser.add_argument("--options", metavar="options.toml",
                        help="options file (default: the options stored in the recording)")
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    add_filter_option(parser)
    parser.set_defaults(run=run)
    return parser


def _target(path: Path, force: bool) -> Path:
    if path.exists() and not force:
        raise CliError(f"{path} exists (use --force to overwrite)")
    return path


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.cli_support import processed

    t_start = time.perf_counter()
    raw = Path(args.raw_file)
    out = Path(args.output) if args.output else raw.with_suffix("")
    p = processed("export", args.raw_file, args.calibration, args.options, args.reset_at,
                  algorithm=args.filter_name,
                  heading=args.heading)
    res = p.result
    dt = p.processor.options.filter.dt
    written: list[str] = []
    try:
        if args.format == "opensim":
            from bpms.analysis.opensim import calibration_window, write_orientations

            stem = str(out.with_suffix("")) if out.suffix == ".sto" else str(out)
            whole = _target(Path(f"{stem}_orientations.sto"), args.force)
            calib = _target(Path(f"{stem}_calibration.sto"), args.force)
            q = res.segment_quaternions
            rows = write_orientations(whole, res.t, q, 1.0 / dt, args.head_neck)
            lo, hi = calibration_window(p.processor.pose.settle, p.processor.pose.window,
                                        len(res))
            rows_c = write_orientations(calib, res.t[lo:hi], q[lo:hi], 1.0 / dt, args.head_neck)
            written += [f"{whole} ({rows} rows)",
                        f"{calib} ({rows_c} rows, {lo * dt:.2f}–{hi * dt:.2f} s)"]
        elif args.format == "bvh":
            from bpms.analysis.bvh import write_bvh

            path = _target(out if out.suffix == ".bvh" else out.with_name(out.name + ".bvh"),
                           args.force)
            from bpms.analysis.root_path import walked_root  # i16: the walked path

            n = write_bvh(path, res.C, walked_root(p), p.processor.options.body, dt)
            written.append(f"{path} ({n} frames, cm, y up)")
        else:
            from bpms.analysis.matlab import write_matlab_csv

            path = _target(out if out.suffix == ".csv" else out.with_name(out.name
                                                                          + "_matlab.csv"),
                           args.force)
            n = write_matlab_csv(path, res.t, res.quaternions, res.euler, res.joint_angles,
                                 degrees=not args.radians)
            written.append(f"{path} ({n} rows)")
    except OSError as exc:
        raise CliError(f"cannot write: {exc.strerror or exc} ({exc.filename})") from exc
    for w in written:
        print(w, file=sys.stderr)
    print(f"bpms export: {len(res)} frames in {time.perf_counter() - t_start:.1f} s",
          file=sys.stderr)
    return 0
