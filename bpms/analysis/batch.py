"""Study batches: every recording under a folder, processed in parallel worker processes.

Each worker filters one recording in one chunk-by-chunk pass and, on the way, writes the
requested per-recording outputs (the filtered file and ``.mat`` in ``OUT/SUBJECT/``, Parquet
as one dataset partitioned by subject, ``OUT/parquet/subject=S01/TRIAL.parquet``) and reduces
the range of motion (min/max of each joint angle over every frame with segment orientations).
The parent collects one tidy table (one row per recording × joint angle, with the study's
columns: :mod:`bpms.analysis.study`) and a Markdown summary page with figures.

An unreadable recording is skipped and reported (``Outcome.failure == "recording"``); a
recording the machinery lost (its worker process died, the Dask scheduler went away) is
reported apart (``"infrastructure"``). Either way the batch is incomplete and the command
exits non-zero.

The worker function is a module-level function with plain arguments, so it runs under the
"spawn" start method (Windows, macOS: each worker loads the filter kernels itself, a few
seconds) as under "fork" (Linux: the workers inherit the kernels loaded once in the parent),
and on the workers of a Dask distributed cluster (``scheduler="tcp://HOST:PORT"``, the
``dask`` extra): the same function on the same files, so the outputs are the same bytes. The
cluster's workers must run the same bpms version and see the recordings and the output
folder at the same paths (a shared file system).
"""

from __future__ import annotations

import csv
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

OUTPUTS = ("filter", "rom", "mat", "parquet", "compare")
PARQUET_DIR = "parquet"  # the Parquet dataset's root under OUT (hive-style: subject=...)
RAW_SUFFIXES = (".bpmsraw",)
LEGACY_SUFFIXES = (".txt",)
TABLE_NAME = "batch_rom.csv"
SUMMARY_NAME = "batch_summary.md"


@dataclass
class Job:
    """One recording: its path, subject, trial and the study sheet's other columns."""

    path: str
    subject: str
    trial: str
    info: dict[str, str] = field(default_factory=dict)


@dataclass
class Outcome:
    """One recording's result. ``rows``: (joint, min deg, max deg) per joint angle;
    ``error``: why it was skipped (None when it was processed)."""

    job: Job
    frames: int = 0
    seconds: float = 0.0
    convention: str = ""
    utc_start: str = ""
    rows: list[tuple[str, float, float]] = field(default_factory=list)
    written: list[str] = field(default_factory=list)
    error: str | None = None
    problems: list[str] = field(default_factory=list)  # warnings (file, header, options)
    #: why it failed: "recording" (the file) or "infrastructure" (the worker or cluster)
    failure: str = ""
    #: where its numbers came from (:func:`bpms.analysis.stamp.provenance`)
    origin: dict[str, str] = field(default_factory=dict)


def find_recordings(folder: str | Path) -> list[Job]:
    """Every raw recording under ``folder`` (native ``.bpmsraw`` files, and legacy ``.txt``
    raw files recognised by their content), sorted. Subject = the first folder level under
    ``folder`` (``-`` for files directly in it), trial = the file's stem
    (:func:`bpms.analysis.study.naming_rule`)."""
    from bpms.analysis.study import naming_rule
    from bpms.filter.door import is_raw_recording

    root = Path(folder)
    jobs = []
    for path in sorted(root.rglob("*")):
        if not path.is_file():
            continue
        suffix = path.suffix.lower()
        if suffix in RAW_SUFFIXES or (suffix in LEGACY_SUFFIXES and is_raw_recording(path)):
            jobs.append(Job(str(path), *naming_rule(root, path)))
    return jobs


def apply_study(jobs: list[Job], study) -> tuple[list[Job], list[Job]]:
    """(the jobs the study sheet lists, with its subject, trial and columns; the jobs it does
    not list). ``study``: :class:`bpms.analysis.study.Study`."""
    listed, left = [], []
    for job in jobs:
        row = study.rows.get(Path(job.path).resolve())
        if row is None:
            left.append(job)
            continue
        info = {c: row[c] for c in study.columns}
        listed.append(Job(job.path, row["subject"], row["trial"], info))
    found = {Path(j.path).resolve() for j in jobs}
    listed += [Job(str(p), row["subject"], row["trial"], {c: row[c] for c in study.columns})
               for p, row in study.rows.items() if p not in found]
    return listed, left


def parquet_path(out_dir: str | Path, job: Job) -> Path:
    """``OUT/parquet/subject=S01/TRIAL.parquet`` (the subject URI-encoded, as pyarrow's hive
    partitioning reads it back)."""
    from urllib.parse import quote

    from bpms.io.naming import safe_stem

    return (Path(out_dir) / PARQUET_DIR / f"subject={quote(job.subject, safe='')}"
            / f"{safe_stem(job.trial) or 'trial'}.parquet")


def process_one(job: Job, out_dir: str, outputs: tuple[str, ...],
                options: str | None = None, reset_zero=None) -> Outcome:
    """Worker: filter ``job``'s recording once, write ``outputs`` into ``out_dir`` (per
    subject), reduce the range of motion. Never raises: failures become ``Outcome.error``."""
    from dataclasses import replace

    from bpms.analysis.binary_out import SUFFIX, open_writer
    from bpms.analysis.rom import RomAccumulator
    from bpms.analysis.stamp import provenance
    from bpms.analysis.stream_export import open_for_processing
    from bpms.filter.joints import JOINT_ANGLE_NAMES
    from bpms.io.naming import safe_stem
    from bpms.io.paths import remove_regular_file

    t0 = time.perf_counter()
    outcome = Outcome(job)
    writers: list = []
    try:
        opened = open_for_processing(job.path, None, options, reset_zero)
        outcome.problems = [str(p) for p in opened.problems]
        if len(opened) == 0:
            raise ValueError("the recording holds no frames")
        outcome.origin = provenance(opened.door)
        target = Path(out_dir) / (safe_stem(job.subject) or "-")
        trial = safe_stem(job.trial) or "trial"
        if {"filter", "mat", "compare"} & set(outputs):
            target.mkdir(parents=True, exist_ok=True)
        stem = target / trial
        study = {"subject": job.subject, "trial": job.trial, **job.info}
        filtered = None
        if "filter" in outputs:
            from bpms.filter.door import filtered_convention, filtered_layout, heading_header
            from bpms.io.filtered_file.writer import FilteredWriter

            path = stem.with_name(f"{trial}_filtered.csv")
            remove_regular_file(path)  # never a folder, a named pipe or a device
            groups, kind = filtered_layout()  # as bpms filter and the live recording write
            filtered = FilteredWriter(path, degrees=True, groups=groups, euler=kind,
                                      convention=filtered_convention(opened.meta.convention),
                                      meta={**heading_header(opened.door.processor.options),
                                            **outcome.origin, "study": "; ".join(
                                                f"{k}={v}" for k, v in study.items())})
            writers.append(filtered)
            outcome.written.append(str(path))
        for kind in ("mat", "parquet"):
            if kind in outputs:
                if kind == "parquet":  # the subject is the dataset's partition column
                    path = parquet_path(out_dir, job)
                    path.parent.mkdir(parents=True, exist_ok=True)
                    columns = {k: v for k, v in study.items() if k != "subject"}
                else:
                    path, columns = stem.with_name(trial + SUFFIX[kind]), study
                writers.append(open_writer(kind, path, replace(opened.meta, columns=columns)))
                outcome.written.append(str(path))
        rom = RomAccumulator(job.trial)  # the ROM rule of bpms rom
        for result in opened.chunks():
            if filtered is not None:
                from bpms.filter.door import filtered_arrays

                filtered.write_block(result.t, **filtered_arrays(result, filtered.groups))
            for w in writers:
                if w is not filtered:
                    w.write(result)
            rom.add(result.t, result.joint_angles)
            outcome.frames += len(result)
        if "rom" in outputs:
            try:
                table = rom.table()
            except ValueError:
                raise ValueError("no frame with segment orientations (no Reset Zero)") from None
            outcome.rows = [(name, float(a), float(b)) for name, a, b in zip(
                JOINT_ANGLE_NAMES, table.minimum, table.maximum, strict=True)]
        if "compare" in outputs:  # the optical file beside it (bpms.analysis.compare_batch)
            from bpms.analysis.compare_batch import compare_beside

            outcome.written += compare_beside(job.path, stem, options, reset_zero,
                                              outcome.problems)
        outcome.convention = opened.meta.convention
        outcome.utc_start = opened.meta.utc_iso
    except Exception as exc:  # one bad file must not stop a study
        outcome.error = one_line(f"{type(exc).__name__}: {exc}")
        outcome.failure = "recording"
    finally:
        for w in writers:
            try:
                w.close()
            except Exception as exc:
                outcome.error = outcome.error or one_line(f"closing an output failed: {exc}")
                outcome.failure = outcome.failure or "recording"
    outcome.seconds = time.perf_counter() - t0
    return outcome


class SchedulerError(RuntimeError):
    """The Dask scheduler cannot be used (unreachable, no workers, another bpms version)."""


def run_batch(jobs: list[Job], out_dir: str | Path, outputs: tuple[str, ...] = ("rom",),
              workers: int = 1, options: str | None = None,
              progress: Callable[[int, int, Outcome], None] | None = None,
              start_method: str | None = None, scheduler=None,
              reset_zero=None) -> list[Outcome]:
    """Process ``jobs`` with ``workers`` processes (1 = in this process), or on the Dask
    cluster whose scheduler is at ``scheduler`` (``"tcp://HOST:PORT"``, or a client of
    :func:`dask_client`; ``workers`` is then the cluster's); outcomes in job order.
    ``progress(done, total, outcome)`` after each recording. ``start_method``: the
    multiprocessing start method (default: the platform's); ``reset_zero``: which Reset Zero
    (:mod:`bpms.filter.zero_choice`). Raises :class:`SchedulerError` when the scheduler
    cannot be used."""
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    results: dict[int, Outcome] = {}
    if scheduler:
        _run_on_dask(scheduler, jobs, str(out_dir), outputs, options, progress, results,
                     reset_zero)
    elif workers <= 1:
        for k, job in enumerate(jobs):
            results[k] = process_one(job, str(out_dir), outputs, options, reset_zero)
            if progress:
                progress(len(results), len(jobs), results[k])
    else:
        import multiprocessing

        ctx = multiprocessing.get_context(start_method)  # default: spawn on Windows/macOS
        if ctx.get_start_method() == "fork":
            from bpms.filter.processor import BodyPoseProcessor

            BodyPoseProcessor().load_kernels()  # forked workers inherit the loaded kernels
        from concurrent.futures.process import BrokenProcessPool

        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            futures = {}
            for k, job in enumerate(jobs):
                try:
                    futures[pool.submit(process_one, job, str(out_dir), outputs, options,
                                        reset_zero)] = k
                except BrokenProcessPool as exc:  # a worker died while jobs were handed out
                    results[k] = Outcome(job, error=infrastructure_reason(exc),
                                         failure="infrastructure")
            _collect(futures, as_completed, jobs, results, progress)
    return [results[k] for k in range(len(jobs))]


def _collect(futures: dict, completed, jobs: list[Job], results: dict[int, Outcome],
             progress) -> None:
    """Fill ``results`` from ``futures`` (future → job index) as ``completed`` yields them; a
    future that raises (its worker process died, or was lost), or the end of the waiting
    itself (the cluster went away), becomes an infrastructure outcome."""
    try:
        for future in completed(futures):
            k = futures[future]
            try:
                results[k] = future.result()
            except Exception as exc:
                results[k] = Outcome(jobs[k], error=infrastructure_reason(exc),
                                     failure="infrastructure")
            if progress:
                progress(len(results), len(jobs), results[k])
    except Exception as exc:
        reason = infrastructure_reason(exc)
        for k in sorted(set(futures.values()) - set(results)):
            results[k] = Outcome(jobs[k], error=reason, failure="infrastructure")
            if progress:
                progress(len(results), len(jobs), results[k])


def one_line(text: str) -> str:
    """``text`` on one line (a reason in a table cell or a message line)."""
    return " ".join(str(text).split())


def infrastructure_reason(exc: BaseException) -> str:
    """Why the machinery lost a recording (not the file's fault), one line."""
    from concurrent.futures.process import BrokenProcessPool

    if isinstance(exc, BrokenProcessPool):
        return ("not processed: a worker process died (killed, or out of memory); the "
                "recording itself was not judged")
    name = type(exc).__name__
    if name in ("CancelledError", "CommClosedError", "FutureCancelledError", "KilledWorker"):
        return f"not processed: the Dask cluster lost it ({name}: {one_line(str(exc))[:200]})"
    return one_line(f"not processed: the worker failed ({name}: {exc})")[:300]


def dask_client(scheduler: str, timeout_s: float = 30.0):
    """A ``distributed.Client`` of the scheduler at ``scheduler``, checked: it answers (within
    Dask's connect timeout, ``distributed.comm.timeouts.connect``, 30 s unless configured),
    has a worker within ``timeout_s``, and every worker runs this bpms version."""
    from bpms.extras import require

    distributed = require("distributed")
    import bpms

    try:
        client = distributed.Client(scheduler)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler}: "
                             f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
                             ) from None
    try:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except TimeoutError:
            raise SchedulerError(f"the Dask scheduler at {scheduler} has no workers") from None
        versions = client.run(_bpms_version)
        other = {w: v for w, v in versions.items() if v != bpms.__version__}
        if other:
            raise SchedulerError(f"Dask workers run another bpms version than this one "
                                 f"({bpms.__version__}): {other}")
    except BaseException:
        client.close()
        raise
    return client


def _bpms_version() -> str:
    import bpms

    return bpms.__version__


def _run_on_dask(scheduler, jobs: list[Job], out_dir: str, outputs: tuple[str, ...],
                 options: str | None, progress, results: dict[int, Outcome],
                 reset_zero=None) -> None:
    from distributed import as_completed as dask_completed

    own = isinstance(scheduler, str)
    client = dask_client(scheduler) if own else scheduler
    try:
        futures = {client.submit(process_one, job, out_dir, outputs, options, reset_zero,
                                 pure=False): k
                   for k, job in enumerate(jobs)}
        _collect(futures, dask_completed, jobs, results, progress)
    finally:
        if own:
            close_quietly(client)


def close_quietly(client) -> None:
    """Close a Dask client whose scheduler may be gone (its failure is reported already)."""
    import contextlib

    with contextlib.suppress(Exception):  # the scheduler died: nothing left to close
        client.close()


TABLE_COLUMNS_AFTER = ("joint", "min_deg", "max_deg", "range_deg", "frames", "utc_start",
                       "convention", "filter", "reset_zero", "bpms_version", "source_file")


def write_table(path: str | Path, outcomes: list[Outcome]) -> int:
    """The tidy table: one row per recording × joint angle: ``subject``, ``trial``, the study
    sheet's other columns, ``joint`` (the joint angle's name as its columns elsewhere, without
    the unit: ``joint_knee_r_flexion``), the range, and where the numbers came from. Returns
    the number of rows."""
    from bpms.io.names import joint_column

    study = list(dict.fromkeys(c for o in outcomes for c in o.job.info))
    rows = 0
    with open(path, "w", encoding="utf-8", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["subject", "trial", *study, *TABLE_COLUMNS_AFTER])
        for o in outcomes:
            origin = [o.origin.get(k, "") for k in ("filter", "reset_zero", "bpms_version")]
            for joint, lo, hi in o.rows:
                w.writerow([o.job.subject, o.job.trial, *(o.job.info.get(c, "") for c in study),
                            joint_column(joint), f"{lo:.3f}", f"{hi:.3f}", f"{hi - lo:.3f}",
                            o.frames, o.utc_start, o.convention, *origin, o.job.path])
                rows += 1
    return rows


def _cell(text: object) -> str:
    """Text for a Markdown table cell: one line, ``|`` escaped."""
    return one_line(str(text)).replace("|", "\\|")


def write_summary(folder: str | Path, outcomes: list[Outcome], source: str | Path,
                  elapsed_s: float, workers: int, study: str = "",
                  left_out: list[Job] | None = None, figures: bool = True) -> Path:
    """``batch_summary.md`` with counts, where subject and trial came from (``study``: the
    sheet; ``""``: the naming rules), the failures (the recordings', then the machinery's),
    per-joint ranges and a figure (``figures``)."""
    import numpy as np

    from bpms.analysis.study import NAMING_RULE

    folder = Path(folder)
    ok = [o for o in outcomes if o.error is None]
    bad = [o for o in outcomes if o.error is not None and o.failure != "infrastructure"]
    lost = [o for o in outcomes if o.error is not None and o.failure == "infrastructure"]
    where = (f"the study sheet `{study}`" if study else
             f"the file naming rules ({NAMING_RULE}); give --study SHEET.csv to name them")
    lines = [f"# Batch summary: {source}", "",
             f"- recordings found: {len(outcomes)}; processed: {len(ok)}; skipped: {len(bad)}"
             f"; lost by the machinery: {len(lost)}",
             f"- {'COMPLETE' if not bad and not lost else 'INCOMPLETE: see below'}",
             f"- subject and trial from {where}",
             f"- frames processed: {sum(o.frames for o in ok)} "
             f"({sum(o.frames for o in ok) / 50 / 60:.1f} min of recording)",
             f"- {elapsed_s:.1f} s with {workers} worker process(es)",
             f"- joint-angle convention: {', '.join(sorted({o.convention for o in ok})) or '-'}",
             f"- tidy table: `{TABLE_NAME}` (one row per recording × joint angle)", ""]
    if any(PARQUET_DIR in Path(w).parts for o in ok for w in o.written):
        lines.insert(-1, f"- Parquet dataset: `{PARQUET_DIR}/` (partitioned by subject)")
    if left_out:
        lines.insert(-1, f"- {len(left_out)} recording(s) under the folder not in the study "
                         "sheet: not processed")
    if bad:
        lines += ["## Skipped (the recording could not be processed)", "",
                  "| file | reason |", "|---|---|"]
        lines += [f"| {_cell(o.job.path)} | {_cell(o.error)} |" for o in bad]
        lines.append("")
    if lost:
        lines += ["## Not processed (the machinery failed, not the file): run them again", "",
                  "| file | reason |", "|---|---|"]
        lines += [f"| {_cell(o.job.path)} | {_cell(o.error)} |" for o in lost]
        lines.append("")
    with_rom = [o for o in ok if o.rows]
    if with_rom:
        from bpms.io.names import joint_column

        names = [joint_column(r[0]) for r in with_rom[0].rows]
        ranges = np.array([[hi - lo for _, lo, hi in o.rows] for o in with_rom])
        lines += ["## Range of motion across recordings (deg)", "",
                  "| joint | mean range | min range | max range | recordings |",
                  "|---|---:|---:|---:|---:|"]
        for k, name in enumerate(names):
            col = ranges[:, k]
            lines.append(f"| {name} | {col.mean():.1f} | {col.min():.1f} | {col.max():.1f} "
                         f"| {len(col)} |")
        lines.append("")
        if figures and _figure(folder / "batch_rom.png", names, ranges):
            lines += ["![Range of motion per joint angle](batch_rom.png)", ""]
    path = folder / SUMMARY_NAME
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def _figure(path: Path, names: list[str], ranges) -> bool:
    """Box plot of the range per joint angle across recordings (matplotlib, loaded here)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(10, 7))
    ax.boxplot(ranges, orientation="horizontal", tick_labels=names)
    ax.set_xlabel("range of motion per recording, deg")
    ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True
