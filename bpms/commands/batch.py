"""``bpms batch FOLDER [-o OUT] [--outputs rom,filter,mat,parquet] [--workers N]
[--scheduler tcp://HOST:PORT]``: a study.

Finds every raw recording under FOLDER (subject = the first folder level, trial = the file
name), processes them in parallel worker processes with progress, skips and reports unreadable
files, and writes into OUT (default ``FOLDER/batch``):

- ``batch_rom.csv``: one row per recording × joint angle (subject, trial, joint, min, max,
  range in degrees, ...), ready for a statistics package;
- ``batch_summary.md``: counts, skipped files, ranges across recordings and a figure;
- per recording (``OUT/SUBJECT/``), the chosen outputs: ``filter`` (filtered CSV with joint
  angles, degrees), ``mat`` (MATLAB), ``parquet``.

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
                   help="comma-separated: rom, filter, mat, parquet (default: rom)")
    p.add_argument("--workers", type=number(int, 1, 1024), default=None, metavar="N",
                   help="worker processes (default: the number of CPU cores)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on a Dask distributed cluster (its scheduler's address) instead "
                        "of local worker processes")
    p.add_argument("--options", metavar="options.toml",
                   help="options file (default: each recording's stored options)")
    add_reset_zero_option(p)
    return p


def run(args: argparse.Namespace) -> int:
    from bpms.analysis.batch import (
        OUTPUTS,
        TABLE_NAME,
        SchedulerError,
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
    if not jobs:
        raise CliError(f"{folder}: no raw recording found (.bpmsraw or a legacy raw .txt)")
    client = None
    if args.scheduler:
        try:
            client = dask_client(args.scheduler)
        except SchedulerError as exc:
            raise CliError(str(exc)) from None
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
            client.close()
    elapsed = time.perf_counter() - t0
    rows = write_table(out / TABLE_NAME, outcomes)
    summary = write_summary(out, outcomes, folder, elapsed, workers)
    skipped = [o for o in outcomes if o.error]
    for o in skipped:
        print(f"bpms batch: skipped {o.job.path}: {o.error}", file=sys.stderr)
    print(f"{len(outcomes) - len(skipped)} processed, {len(skipped)} skipped in {elapsed:.1f} s; "
          f"{out / TABLE_NAME} ({rows} rows), {summary}", flush=True)
    return 0
