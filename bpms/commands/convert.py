"""``bpms convert RAW_FILE [-f mat] [-f parquet] [-o STEM]``: binary exports of a recording.

- ``mat``: a MATLAB v5 file ``<stem>.mat`` (load with ``load``): time, segment quaternions,
  joint angles (degrees), joint positions, names, units, the UTC start time and the joint-angle
  convention;
- ``parquet``: a Parquet table ``<stem>.parquet`` (one row per frame; pandas, polars, R arrow,
  MATLAB ``parquetread``), for large studies.

Both are written in one filtering pass. docs/analysis.md describes the contents.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bpms.analysis.cli_support import add_reset_zero_option
from bpms.commands import CliError
from bpms.commands._shared import add_sources, refuse_existing, require_formats, warn


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("convert", help="binary exports of a recording (.mat, Parquet)")
    p.add_argument("raw_file", metavar="RAW_FILE", help="raw recording")
    p.add_argument("-f", "--format", action="append", choices=("mat", "parquet"), default=[],
                   help="output format (repeatable; default: both)")
    p.add_argument("-o", "--output", metavar="STEM",
                   help="output path without suffix (default: beside the raw file)")
    add_sources(p, "the one stored in the recording", "the options stored in the recording")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    add_reset_zero_option(p)
    return p


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.binary_out import SUFFIX
    from bpms.analysis.mat5_stream import ExportLimitError
    from bpms.analysis.stream_export import NoUsableFramesError, export_recording
    from bpms.io.filtered_file.reader import FilteredFileError
    from bpms.io.rawfile import RawFileError
    from bpms.progress import stderr_progress

    t0 = time.perf_counter()
    raw = Path(args.raw_file)
    stem = Path(args.output) if args.output else raw.with_suffix("")
    kinds = list(dict.fromkeys(args.format or ["mat", "parquet"]))
    require_formats(kinds)
    outputs = {k: refuse_existing(stem.with_name(stem.name + SUFFIX[k]), args.force)
               for k in kinds}
    try:
        summary = export_recording(raw, outputs, args.calibration, args.options,
                                   stderr_progress, args.reset_zero)
    except (RawFileError, FilteredFileError, ExportLimitError, NoUsableFramesError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"cannot write: {exc.strerror or exc}") from None
    if summary.frames == 0:
        raise CliError(f"{raw}: the recording holds no frames")
    warn("convert", summary.problems)
    for kind, target in summary.written.items():
        print(f"wrote {target} ({summary.frames} frames, {kind})")
    print(f"UTC start {summary.utc_start}, joint angles: {summary.convention}; "
          f"{time.perf_counter() - t0:.2f} s")
    return 0
