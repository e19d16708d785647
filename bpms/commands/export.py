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
                        help="calibration file (default: the recording's, else your default)")
    parser.add_argument("--options", metavar="options.toml",
                        help="options file (default: the recording's, else your default)")
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    add_filter_option(parser)
    parser.set_defaults(run=run)
    return parser


def _target(path: Path, force: bool) -> Path:
    if path.exists() and not force:
        raise CliError(f"{path} exists (use --force to overwrite)")
    return path


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.stamp import recording_stamp
    from bpms.commands._analysis import open_recording_for, stream

    t_start = time.perf_counter()
    raw = Path(args.raw_file)
    out = Path(args.output) if args.output else raw.with_suffix("")
    opened = open_recording_for("export", args.raw_file, args.calibration, args.options,
                                args.filter_name, args.heading, args.reset_zero)
    proc = opened.processor
    dt = proc.options.filter.dt
    stamp = recording_stamp(opened)
    written: list[str] = []
    n = 0
    writers: list = []
    try:
        if args.format == "opensim":
            from bpms.analysis.opensim import OrientationsWriter, calibration_window

            stem = str(out.with_suffix("")) if out.suffix == ".sto" else str(out)
            whole_path = _target(Path(f"{stem}_orientations.sto"), args.force)
            calib_path = _target(Path(f"{stem}_calibration.sto"), args.force)
            whole = OrientationsWriter(whole_path, 1.0 / dt, args.head_neck,
                                       meta=stamp.items())
            calib = OrientationsWriter(calib_path, 1.0 / dt, args.head_neck,
                                       meta=stamp.items())
            writers += [whole, calib]
            lo, hi = calibration_window(proc.pose.settle, proc.pose.window, opened.n_frames)
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                q = res.segment_quaternions
                whole.write(res.t, q)
                a, b = max(lo - chunk.start, 0), min(hi - chunk.start, len(res))
                if a < b:
                    calib.write(res.t[a:b], q[a:b])
                n += len(res)
            written += [f"{whole_path} ({whole.rows} rows)",
                        f"{calib_path} ({calib.rows} rows, {lo * dt:.2f}–{hi * dt:.2f} s)"]
        elif args.format == "bvh":
            from bpms.analysis.bvh import BvhWriter
            from bpms.filter.body_model import POINT_INDEX

            path = _target(out if out.suffix == ".bvh" else out.with_name(out.name + ".bvh"),
                           args.force)
            from bpms.analysis.root_path import root_trajectory, walked_steps
            from bpms.filter.door import open_for_processing

            # the root walks the heel-strike path: a first pass finds the steps (constant
            # memory), the second writes the frames
            steps = walked_steps(open_for_processing(args.raw_file, args.calibration,
                                                     args.options, args.filter_name,
                                                     args.heading, args.reset_zero),
                                 args.reset_at)
            bvh = BvhWriter(path, proc.options.body, dt)
            writers.append(bvh)
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                bvh.write(res.C, root_trajectory(res.t, res.joint_positions[:, POINT_INDEX[
                    "pelvis"]], *steps))
                n += len(res)
            written.append(f"{path} ({bvh.frames} frames, cm, y up)")
        else:
            from bpms.analysis.matlab import MatlabCsvWriter

            path = _target(out if out.suffix == ".csv" else out.with_name(out.name
                                                                          + "_matlab.csv"),
                           args.force)
            mat = MatlabCsvWriter(path, degrees=not args.radians, meta=stamp.items())
            writers.append(mat)
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                mat.write(res.t, res.quaternions, res.euler, res.joint_angles)
                n += len(res)
            written.append(f"{path} ({mat.rows} rows)")
    except OSError as exc:
        raise CliError(f"cannot write: {exc.strerror or exc} ({exc.filename})") from exc
    finally:
        for w in writers:
            w.close()
    for w in written:
        print(w, file=sys.stderr)
    # BVH has no comment syntax: for it this line is the only statement of both
    print(f"bpms export: {stamp.line()}", file=sys.stderr)
    print(f"bpms export: {n} frames in {time.perf_counter() - t_start:.1f} s",
          file=sys.stderr)
    return 0
