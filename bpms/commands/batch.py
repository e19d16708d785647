"""``bpms batch FOLDER [-o OUT] [--study SHEET.csv] [--outputs rom,filter,mat,parquet]
[--workers N] [--scheduler tcp://HOST:PORT] [--no-figures]``: a study.

Finds every raw recording under FOLDER (subject and trial from the study sheet, else from the
file naming rules: subject = the first folder level, trial = the file name), processes them
in parallel worker processes with progress, skips and reports unreadable files, and writes
into OUT (default ``FOLDER/batch``):

- ``batch_rom.csv``: one row per recording × joint angle (subject, trial, the sheet's
  columns, joint, min, max, range in degrees, ...), ready for a statistics package;
- ``batch_summary.md``: counts, where subject and trial came from, failures, ranges across
  recordings and a figure;
- per recording, the chosen outputs: ``filter`` (filtered CSV with joint angles, degrees) and
  ``mat`` (MATLAB) in ``OUT/SUBJECT/``; ``parquet`` as one dataset partitioned by subject,
  ``OUT/parquet/subject=SUBJECT/TRIAL.parquet``.

Exit status: 0 when every recording was processed; 1 when a recording could not be processed
(a bad file: the rest of the study is written); 3 when the machinery lost recordings (a worker
process died, the Dask scheduler went away): run the batch again.

With ``--scheduler tcp://HOST:PORT`` the recordings are processed on the workers of a Dask
distributed cluster instead of local processes (the ``dask`` extra): for a lab's cluster; the
workers must run this bpms version and see FOLDER and OUT at the same paths. The outputs are
the same bytes either way. docs/analysis.md ("Study batches").
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from bpms.analysis.cli_support import add_reset_zero_option
from bpms.commands import CliError
from bpms.commands._shared import number, require_formats, warn


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("batch", help="process every recording under a folder (a study)")
    p.add_argument("folder", help="folder searched recursively for raw recordings")
    p.add_argument("-o", "--output", metavar="DIR", help="output folder (default FOLDER/batch)")
    p.add_argument("--outputs", default="rom", metavar="LIST",
                   help="comma-separated: rom, filter, mat, parquet, compare (default: rom; "
                        "compare: each recording against the optical file beside it, "
                        "docs/compare.md)")
    p.add_argument("--workers", type=number(int, 1, 1024), default=None, metavar="N",
                   help="worker processes (default: the number of CPU cores)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on a Dask distributed cluster (its scheduler's address) instead "
                        "of local worker processes")
    p.add_argument("--study", metavar="SHEET.csv",
                   help="study sheet: columns file, subject, trial, condition, any others "
                        "(carried into every table); only its recordings are processed")
    p.add_argument("--no-figures", action="store_true",
                   help="no figure in the summary (no matplotlib needed)")
    p.add_argument("--options", metavar="options.toml",
                   help="options file (default: each recording's stored options)")
    add_reset_zero_option(p)
    return p


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.batch import (
        OUTPUTS,
        TABLE_NAME,
        SchedulerError,
        apply_study,
        close_quietly,
        dask_client,
        find_recordings,
        run_batch,
        write_summary,
        write_table,
    )

    folder = Path(args.folder)
    if not folder.is_dir():
        raise CliError(f"{folder}: not a folder")
    outputs = tuple(dict.fromkeys(s.strip() for s in args.outputs.split(",") if s.strip()))
    unknown = [o for o in outputs if o not in OUTPUTS]
    if unknown or not outputs:
        raise CliError(f"--outputs: unknown {', '.join(unknown) or '(empty)'}; "
                       f"choose from {', '.join(OUTPUTS)}")
    require_formats(kind for kind in ("mat", "parquet") if kind in outputs)
    out = Path(args.output) if args.output else folder / "batch"
    if out.exists() and not out.is_dir():
        raise CliError(f"{out} exists and is not a folder: give a folder for the outputs")
    jobs = [j for j in find_recordings(folder) if out.resolve() not in Path(j.path).resolve()
            .parents]
    left_out = []
    if args.study:
        from bpms.analysis.study import StudySheetError, read_study_sheet

        try:
            study = read_study_sheet(args.study, folder)
        except StudySheetError as exc:
            raise CliError(str(exc)) from None
        jobs, left_out = apply_study(jobs, study)
    if not jobs:
        raise CliError(f"{folder}: no raw recording found (.bpmsraw or a legacy raw .txt)")
    client = None
    if args.scheduler:
        try:
            client = dask_client(args.scheduler)
        except SchedulerError as exc:
            raise CliError(str(exc)) from None
        _quiet_dask()
        workers = len(client.nthreads())
        where = f"on the Dask cluster at {args.scheduler} ({workers} workers)"
    else:
        workers = max(1, min(args.workers or os.cpu_count() or 1, len(jobs)))
        where = f"{workers} worker process(es)"
    print(f"{len(jobs)} recordings, {where}, outputs: {', '.join(outputs)}", flush=True)
    t0 = time.perf_counter()

    def progress(done: int, total: int, outcome) -> None:
        state = (f"skipped: {outcome.error}" if outcome.error
                 else f"{outcome.frames} frames, {outcome.seconds:.1f} s")
        print(f"[{done}/{total}] {outcome.job.subject}/{outcome.job.trial}: {state}",
              flush=True)
        warn("batch", outcome.problems, flush=True)

    try:
        outcomes = run_batch(jobs, out, outputs, workers, args.options, progress,
                             scheduler=client, reset_zero=args.reset_zero)
    finally:
        if client is not None:
            close_quietly(client)
    elapsed = time.perf_counter() - t0
    rows = write_table(out / TABLE_NAME, outcomes)
    summary = write_summary(out, outcomes, folder, elapsed, workers, args.study or "",
                            left_out, figures=not args.no_figures)
    if "compare" in outputs:  # docs/compare.md, "In a study"
        from bpms.analysis.compare_batch import write_study_table

        write_study_table(out)
    skipped = [o for o in outcomes if o.error and o.failure != "infrastructure"]
    lost = [o for o in outcomes if o.error and o.failure == "infrastructure"]
    for o in skipped:
        print(f"bpms batch: skipped {o.job.path}: {o.error}", file=sys.stderr)
    for o in lost:
        print(f"bpms batch: lost {o.job.path}: {o.error}", file=sys.stderr)
    if not args.study:
        print("bpms batch: subject and trial from the file naming rules (give --study "
              "SHEET.csv to name them)", file=sys.stderr)
    if left_out:
        print(f"bpms batch: {len(left_out)} recording(s) under {folder} not in the study "
              "sheet: not processed", file=sys.stderr)
    done = len(outcomes) - len(skipped) - len(lost)
    print(f"{done} processed, {len(skipped)} skipped, {len(lost)} lost in {elapsed:.1f} s; "
          f"{out / TABLE_NAME} ({rows} rows), {summary}", flush=True)
    if lost:
        print(f"bpms batch: INCOMPLETE: {len(lost)} recording(s) lost by the machinery (a "
              "worker process died or the Dask cluster failed), not by their files: run the "
              "batch again", file=sys.stderr)
        return 3
    if skipped:
        print(f"bpms batch: INCOMPLETE: {len(skipped)} recording(s) could not be processed "
              f"(see {summary})", file=sys.stderr)
        return 1
    return 0


def _quiet_dask() -> None:
    """Dask logs a lost scheduler with tracebacks; the batch reports it in one line a file.
    (After the import: distributed sets its loggers' levels when it is imported.)"""
    import logging

    for name in [n for n in logging.root.manager.loggerDict if n.startswith("distributed")]:
        logging.getLogger(name).setLevel(logging.CRITICAL)
