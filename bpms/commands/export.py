"""``bpms export opensim|bvh|matlab|c3d RAW_FILE [-o STEM]``: exports for the biomechanics
ecosystem.

Every format writes STEM + its ending; STEM is -o (an ending of the format given with it is
dropped: -o walk.bvh is -o walk), else the recording's path without its suffix:

- opensim: OpenSense orientations STEM_orientations.sto (whole trial) and
  STEM_calibration.sto (the calibration-pose window of the automatic Reset Zero);
- bvh: the stick figure as STEM.bvh (centimetres, y up);
- matlab: STEM.csv (time, every IMU's quaternion and Euler angles, every joint angle);
- c3d: STEM.c3d (joint centres in mm and joint angles as angle points, as Vicon writes
  them; needs the c3d extra).

See docs/analysis.md (formats, axes, the IMU placer's rotation)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bpms.analysis.cli_support import add_filter_option
from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, add_sources, number, refuse_existing
from bpms.io.timebase import stream_time

#: format → the endings of the files it writes after the stem (docs/analysis.md).
ENDINGS: dict[str, tuple[str, ...]] = {
    "opensim": ("_orientations.sto", "_calibration.sto"),
    "bvh": (".bvh",),
    "matlab": (".csv",),
    "c3d": (".c3d",),
}


def output_paths(fmt: str, raw_file: str | Path, output: str | Path | None) -> list[Path]:
    """The files ``bpms export FMT RAW_FILE [-o OUTPUT]`` writes: the stem (``output`` less
    an ending or suffix of the format, else ``raw_file`` less its suffix) + each ending."""
    raw = Path(raw_file)
    stem = Path(output) if output else raw.with_suffix("")
    suffixes = {e[e.index("."):] for e in ENDINGS[fmt]}
    for ending in (*ENDINGS[fmt], *suffixes):
        if stem.name.endswith(ending) and len(stem.name) > len(ending):
            stem = stem.with_name(stem.name[: -len(ending)])
            break
    return [stem.with_name(stem.name + ending) for ending in ENDINGS[fmt]]


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "export", help="export a recording to OpenSim .sto, BVH, a MATLAB CSV or C3D")
    parser.add_argument("format", choices=tuple(ENDINGS))
    parser.add_argument("raw_file", metavar="RAW_FILE",
                        help="raw recording, or a filtered .csv (Reset Zero redone on it)")
    parser.add_argument("-o", "--output", metavar="STEM",
                        help="output path without the format's ending (default: beside the "
                             "recording, its name without the suffix)")
    parser.add_argument("--reset-at", type=number(float, 0, LONGEST_S), action="append", default=[],
                        metavar="T",
                        help="extra Reset Zero at T s (repeatable)")
    parser.add_argument("--head-neck", action="store_true",
                        help="opensim: add head_imu and neck_imu (models with a head)")
    parser.add_argument("--radians", action="store_true", help="matlab: angles in radians")
    add_sources(parser)
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    add_filter_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.stamp import recording_stamp
    from bpms.commands._analysis import open_recording_for, stream

    t_start = time.perf_counter()
    targets = [refuse_existing(p, args.force)
               for p in output_paths(args.format, args.raw_file, args.output)]
    if any(p.resolve() == Path(args.raw_file).resolve() for p in targets):
        raise CliError(f"{args.raw_file}: the output would overwrite the recording (give -o)")
    if args.format == "c3d":
        from bpms.extras import require

        require("ezc3d")  # before filtering: a missing extra is one line at once
    opened = open_recording_for("export", args.raw_file, args.calibration, args.options,
                                args.filter_name, args.heading, args.reset_zero)
    proc = opened.processor
    dt = proc.options.filter.dt
    stamp = recording_stamp(opened)
    written: list[str] = []
    n = 0
    writers: list = []
    path = targets[0]
    try:
        if args.format == "opensim":
            from bpms.analysis.opensim import OrientationsWriter, calibration_window

            whole, calib = (OrientationsWriter(p, 1.0 / dt, args.head_neck, meta=stamp.items())
                            for p in targets)
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
            span = f"{stream_time(lo, dt):.2f}–{stream_time(hi, dt):.2f} s"
            written += [f"{targets[0]} ({whole.rows} rows)",
                        f"{targets[1]} ({calib.rows} rows, {span})"]
        elif args.format == "bvh":
            from bpms.analysis.bvh import BvhWriter
            from bpms.analysis.root_path import root_trajectory, walked_steps
            from bpms.filter.body_model import POINT_INDEX
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
        elif args.format == "c3d":
            from bpms.analysis.c3d_export import C3dWriter

            c3d = C3dWriter(path, 1.0 / dt, stamp.items(), str(args.raw_file))
            writers.append(c3d)
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                c3d.write(res.joint_positions, res.joint_angles)
                n += len(res)
            written.append(f"{path} ({c3d.frames} frames, joint centres mm, angles deg)")
        else:
            from bpms.analysis.matlab import MatlabCsvWriter

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
