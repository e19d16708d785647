"""``bpms export opensim|bvh|matlab|c3d RAW_FILE [-o STEM]``: exports for the biomechanics
ecosystem.

Every format writes STEM + its ending; STEM is -o (an ending of the format given with it is
dropped: -o walk.bvh is -o walk), else the recording's path without its suffix:

- opensim: OpenSense orientations STEM_orientations.sto (whole trial) and
  STEM_calibration.sto (the calibration-pose window of the automatic Reset Zero), and the
  joint angles as STEM_joint_angles.mot (degrees, OpenSim's signs and the coordinate names of
  the Rajagopal et al. 2016 full-body model; every frame, nan where a segment is missing);
- bvh: the stick figure as STEM.bvh (centimetres, y up);
- matlab: STEM.csv (time, every IMU's quaternion and Euler angles, every joint angle);
- c3d: STEM.c3d (joint centres in mm, joint angles as angle points as Vicon writes them,
  the IMUs' calibrated channels as analog channels, heel strikes, markers and Reset Zero as
  events; --walk moves the figure along the walked path).

Every file states where it came from (bpms version, filter, Reset Zero, recording:
:func:`bpms.analysis.stamp.provenance`). A recording without one usable frame (no Reset Zero,
every IMU failed) is refused: the outputs are removed and the exit status is 2.

See docs/analysis.md (formats, axes, the IMU placer's rotation)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bpms.analysis.cli_support import add_filter_option, add_pose_calibration_option
from bpms.commands import CliError
from bpms.commands._shared import LONGEST_S, add_sources, number, refuse_existing
from bpms.io.timebase import stream_time

#: format → the endings of the files it writes after the stem (docs/analysis.md).
ENDINGS: dict[str, tuple[str, ...]] = {
    "opensim": ("_orientations.sto", "_calibration.sto", "_joint_angles.mot"),
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
    parser.add_argument("--walk", action="store_true",
                        help="c3d: move the figure along the walked path (the heel strikes of "
                             "bpms track; one more pass over the recording)")
    add_sources(parser)
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    add_filter_option(parser)
    add_pose_calibration_option(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.stamp import recording_stamp
    from bpms.commands._analysis import open_recording_for, stream

    t_start = time.perf_counter()
    targets = [refuse_existing(p, args.force)
               for p in output_paths(args.format, args.raw_file, args.output)]
    if any(p.resolve() == Path(args.raw_file).resolve() for p in targets):
        raise CliError(f"{args.raw_file}: the output would overwrite the recording (give -o)")
    opened = open_recording_for("export", args.raw_file, args.calibration, args.options,
                                args.filter_name, args.heading, args.reset_zero,
                                args.pose_calibration, args.posture)
    proc = opened.processor
    dt = proc.options.filter.dt
    stamp = recording_stamp(opened, args.reset_at)
    written: list[str] = []
    notes: list[str] = []
    n = usable = 0
    writers: list = []
    path = targets[0]
    try:
        if args.format == "opensim":
            from bpms.analysis.opensim import (
                JointAnglesMotWriter,
                OrientationsWriter,
                calibration_quaternions,
                calibration_window,
                pose_calibration_window,
            )

            whole, calib = (OrientationsWriter(p, 1.0 / dt, args.head_neck, meta=stamp.items())
                            for p in targets[:2])
            mot = JointAnglesMotWriter(targets[2], stamp.convention, stamp.items())
            writers += [whole, calib, mot]
            lo, hi = calibration_window(proc.pose.settle, proc.pose.window, opened.n_frames)
            calib_zero = None
            if opened.pose_event is not None:  # posture / functional: its window and zero
                try:
                    lo, hi, calib_zero = pose_calibration_window(opened.pose_event[1].data,
                                                                 opened.n_frames)
                except ValueError as exc:
                    raise CliError(f"{args.raw_file}: {exc}") from None
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                q = res.segment_quaternions
                usable += whole.write(res.t, q)
                mot.write(res.t, res.joint_angles)
                a, b = max(lo - chunk.start, 0), min(hi - chunk.start, len(res))
                if a < b:
                    calib.write(res.t[a:b], q[a:b] if calib_zero is None else
                                calibration_quaternions(res.R[a:b], calib_zero))
                n += len(res)
            span = f"{stream_time(lo, dt):.2f}–{stream_time(hi, dt):.2f} s"
            written += [f"{targets[0]} ({whole.rows} rows)",
                        f"{targets[1]} ({calib.rows} rows, {span})",
                        f"{targets[2]} ({mot.rows} rows, joint angles deg, coordinates of "
                        "the Rajagopal 2016 model)"]
            if 0 < whole.rows < n:
                notes.append(f"{n - whole.rows} of {n} frames left out of the .sto files: a "
                             "mapped segment had no orientation (before the first Reset Zero, "
                             "or its IMU failed); OpenSense takes no missing value")
        elif args.format == "bvh":
            from bpms.analysis.bvh import BvhWriter
            from bpms.analysis.root_path import root_trajectory, walked_steps
            from bpms.filter.body_model import POINT_INDEX
            from bpms.filter.door import open_for_processing

            # the root walks the heel-strike path: a first pass finds the steps (constant
            # memory), the second writes the frames
            first = open_for_processing(args.raw_file, args.calibration, args.options,
                                        args.filter_name, args.heading, args.reset_zero)
            if opened.pose_event is not None:  # the same pose calibration as the frames'
                first.pose_event = opened.pose_event
            steps = walked_steps(first, args.reset_at)
            bvh = BvhWriter(path, proc.options.body, dt)
            writers.append(bvh)
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                bvh.write(res.C, root_trajectory(res.t, res.joint_positions[:, POINT_INDEX[
                    "pelvis"]], *steps))
                n += len(res)
                usable += _usable(res)
            written.append(f"{path} ({bvh.frames} frames, cm, y up)")
        elif args.format == "c3d":
            n, usable = _c3d(args, opened, path, stamp, writers, written, notes)
        else:
            from bpms.analysis.matlab import MatlabCsvWriter

            mat = MatlabCsvWriter(path, degrees=not args.radians, meta=stamp.items())
            writers.append(mat)
            for chunk in stream("export", opened, args.reset_at):
                res = chunk.result
                mat.write(res.t, res.quaternions, res.euler, res.joint_angles)
                n += len(res)
                usable += _usable(res)
            written.append(f"{path} ({mat.rows} rows)")
    except OSError as exc:
        raise CliError(f"cannot write: {exc.strerror or exc} ({exc.filename})") from exc
    finally:
        for w in writers:
            w.close()
    if not usable:
        for p in targets:
            p.unlink(missing_ok=True)
        raise CliError(f"{args.raw_file}: no frame with joint angles to export ({n} frames, "
                       "none after a Reset Zero with its IMUs working: try --reset-zero auto "
                       "or --reset-at T); nothing written")
    for w in written:
        print(w, file=sys.stderr)
    for note in notes:
        print(f"bpms export: {note}", file=sys.stderr)
    print(f"bpms export: {stamp.line()}", file=sys.stderr)
    if args.format == "bvh":  # BVH has no comment its readers accept (bvhio refuses a "#")
        for key, value in stamp.origin:
            print(f"bpms export: {key}: {value}", file=sys.stderr)
    print(f"bpms export: {n} frames in {time.perf_counter() - t_start:.1f} s",
          file=sys.stderr)
    return 0


def _usable(result) -> int:
    """Frames of ``result`` with at least one joint angle (after a Reset Zero)."""
    import numpy as np

    return int(np.isfinite(result.joint_angles).any(axis=1).sum())


def _c3d(args: argparse.Namespace, opened, path: Path, stamp, writers: list,
         written: list[str], notes: list[str]) -> tuple[int, int]:
    """The C3D: points, angle points, analog channels and events in one pass (two with
    --walk: the walked path first). Returns (frames, usable frames)."""
    from bpms.analysis.c3d_export import C3dWriter, recorded_markers
    from bpms.analysis.root_path import StrikeFinder, walked_offset, walked_track
    from bpms.commands._analysis import stream
    from bpms.filter.door import open_for_processing

    proc = opened.processor
    dt = proc.options.filter.dt
    track = None
    if args.walk:
        if not opened.has_raw:
            raise CliError(f"{args.raw_file}: --walk needs the foot sensors: give the raw "
                           "recording, not a filtered file")
        track = walked_track(open_for_processing(args.raw_file, args.calibration, args.options,
                                                 args.filter_name, args.heading,
                                                 args.reset_zero), args.reset_at)
    finder = StrikeFinder(proc, opened.header) if opened.has_raw and track is None else None
    c3d = C3dWriter(path, 1.0 / dt, stamp.items(), analog=opened.has_raw)
    writers.append(c3d)
    n = usable = 0
    for chunk in stream("export", opened, args.reset_at):
        res = chunk.result
        imu = proc.sensor_calibration.physical_units(chunk.raw) if opened.has_raw else None
        if finder is not None:
            finder.add(chunk)
        c3d.write(res.joint_positions, res.joint_angles, imu,
                  walked_offset(res.t, track) if track is not None else None)
        for zero in res.zeros:
            c3d.add_event("Reset Zero", "General", zero.frame * dt,
                          f"Reset Zero ({zero.source})")
        n += len(res)
        usable += _usable(res)
    track = track if track is not None else finder.track() if finder is not None else None
    strikes = 0 if track is None else len(track.times)
    for k in range(strikes):
        c3d.add_event("Foot Strike", track.sides[k].title(), float(track.times[k]),
                      "heel strike (bpms track)")
    markers = recorded_markers(args.raw_file)
    for frame, text in markers:
        c3d.add_event("Marker", "General", frame * dt, text or "marker")
    if c3d.dropped_events:
        notes.append(f"{c3d.dropped_events} of {len(c3d.events)} events left out of the C3D "
                     "(a C3D EVENT group holds 255); bpms track lists every heel strike")
    analog = "analog: 18 IMUs' acc, gyro, mag" if opened.has_raw else "no analog (filtered file)"
    written.append(f"{path} ({c3d.frames} frames, joint centres mm, angles deg, {analog}; "
                   f"events: {strikes} heel strikes, {len(markers)} markers"
                   f"{', walked path' if args.walk else ''})")
    return n, usable
