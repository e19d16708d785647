"""Outputs of a 60-minute session, each figure beside a reference measured in the same run:

- binary writers: ``.mat`` and Parquet from the filter's results, beside ``np.save`` of the
  arrays they hold (the arrays built before the clock starts);
- CSV text: the one row writer (:class:`bpms.io.text_rows.RowFormat`) beside the writers it
  replaced (the filtered file's printf rows with their 0/1 flag shortcut, and
  ``numpy.savetxt`` of the extract / MATLAB tables), kept here only, on the same arrays, for
  whole files and for the live filtered file's 10-row batches;
- whole commands: ``bpms convert`` beside ``bpms filter``, and with ``--reference DIR`` (a
  checkout of the commit to compare with, e.g. ``git worktree add /tmp/ref HEAD~1``)
  ``bpms filter`` of this tree beside that tree's, alternated, as separate processes.

Run: ``.venv/bin/python bench/outputs.py [--minutes 60] [--reference /tmp/ref]``.

The recording is the simulated suit's scripted motion looped to the requested length. Figures
only (the minimum of the repeats; CPU seconds beside wall seconds for the processes).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.analysis.binary_out import ExportMeta, open_writer
from bpms.cli import main
from bpms.filter.door import CHUNK_FRAMES
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.columns import FLAG_FMT, HOST_TIME_FMT, VALUE_FMT, column_groups
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.text_rows import RowFormat

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference import as_version_1

REPO = Path(__file__).resolve().parents[1]


def run(argv: list[str]) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    if rc:
        raise SystemExit(f"bpms {' '.join(argv)} failed ({rc})")
    return time.perf_counter() - t0


def run_process(tree: Path, argv: list[str]) -> tuple[float, float]:
    """(wall s, CPU s) of ``python -m bpms ARGV`` importing bpms from ``tree``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "bpms", *argv], cwd=tree, check=True,
                   env={**os.environ, "PYTHONPATH": str(tree)}, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def best_of(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


# -- the writers the row writer replaced (kept here only, for the comparison) ----------------
def old_filtered_rows(block: np.ndarray, fmts: list[str]) -> str:
    """The filtered file's rows as the writer of the previous commit wrote them: one printf
    format per row, the trailing 0/1 flag columns from their bytes."""
    fmt = ",".join(fmts)
    flags = len(fmts) - next(k for k in range(len(fmts), 0, -1) if fmts[k - 1] != FLAG_FMT)
    head_fmt = ",".join(fmts[:len(fmts) - flags])
    tail = block[:, block.shape[1] - flags:] if flags else None
    if tail is None or not ((tail == 1.0) | ((tail == 0.0) & ~np.signbit(tail))).all():
        return "\n".join([fmt % tuple(r) for r in block.tolist()]) + "\n"
    chars = np.full((len(block), 2 * flags), ord(","), dtype=np.uint8)
    chars[:, 1::2] = tail.astype(np.uint8) + ord("0")
    tails = chars.view(f"S{2 * flags}").ravel().tolist()
    return "\n".join([(head_fmt % tuple(r)) + t.decode("ascii") for r, t in
                      zip(block[:, :block.shape[1] - flags].tolist(), tails,
                          strict=True)]) + "\n"


def old_savetxt(data: np.ndarray, fmt: str) -> str:
    """``numpy.savetxt`` in chunks of 10,000 rows, as the analysis tables were written."""
    out = io.StringIO()
    for lo in range(0, len(data), 10_000):
        np.savetxt(out, data[lo:lo + 10_000], fmt=fmt, delimiter=",")
    return out.getvalue()


def filtered_block(path: Path) -> tuple[np.ndarray, list[str]]:
    """The rows of a filtered file as the writer holds them (columns in file order) and
    their formats."""
    data = read_filtered(path)
    known = column_groups()
    cols = [data.t[:, None], data.host_time[:, None], data.hole[:, None].astype(float)]
    fmts = [VALUE_FMT, HOST_TIME_FMT, "%d"]
    for g in data.info.groups:
        cols.append(data.groups[g].reshape(len(data.t), -1))
        fmts += [known[g].fmt] * known[g].width
    return np.concatenate(cols, axis=1), fmts


def csv_figures(block: np.ndarray, fmts: list[str]) -> None:
    rows = RowFormat(fmts, [","] * (len(fmts) - 1))
    n = len(block)
    assert rows.text(block[:20_000]) == old_filtered_rows(block[:20_000], fmts)
    t_old = best_of(lambda: [old_filtered_rows(block[lo:lo + 5000], fmts)
                             for lo in range(0, n, 5000)], 2)
    t_new = best_of(lambda: [rows.ascii(block[lo:lo + 5000]) for lo in range(0, n, 5000)], 2)
    print(f"{'filtered rows, previous writer':34s} {t_old:6.2f} s  ({n} rows × "
          f"{block.shape[1]} columns, CPU)")
    print(f"{'filtered rows, row writer':34s} {t_new:6.2f} s  ({t_new / t_old:.2f}× previous)")
    batch = block[:10]
    reps = 300
    t_old = best_of(lambda: [old_filtered_rows(batch, fmts) for _ in range(reps)], 5) / reps
    t_new = best_of(lambda: [rows.ascii(batch) for _ in range(reps)], 5) / reps
    print(f"{'live batch of 10 rows, previous':34s} {t_old * 1e6:6.0f} µs")
    print(f"{'live batch of 10 rows, row writer':34s} {t_new * 1e6:6.0f} µs  "
          f"({t_new / t_old:.2f}× previous)")
    table = block[:, 3:3 + 128]  # an extract / MATLAB table: %.10g everywhere
    text_rows = RowFormat.parse("%.10g", ",", table.shape[1])
    t_old = best_of(lambda: old_savetxt(table, "%.10g"), 1)
    t_new = best_of(lambda: [text_rows.text(table[lo:lo + 10_000])
                             for lo in range(0, len(table), 10_000)], 2)
    print(f"{'%.10g table, numpy.savetxt':34s} {t_old:6.2f} s")
    print(f"{'%.10g table, row writer':34s} {t_new:6.2f} s  ({t_new / t_old:.2f}× savetxt)")


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--reference", type=Path,
                        help="a checkout of the commit to compare `bpms filter` with")
    parser.add_argument("--repeat", type=int, default=3, help="pairs of `bpms filter` runs")
    args = parser.parse_args()
    rec = simulate(seed=1)
    loops = max(1, int(np.ceil(args.minutes * 60 / (len(rec) * FRAME_PERIOD_S))))
    n = len(rec) * loops
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        short = folder / "warmup.bpmsraw"
        write_raw(short, 1.7e9 + rec.t, rec.frames, new_header(
            calibration=rec.calibration.values))
        run(["convert", str(short), "-o", str(folder / "w")])
        run(["filter", str(short), "-o", str(folder / "w.csv")])
        raw = folder / "Raw_long_001.bpmsraw"
        write_raw(raw, 1.7e9 + np.arange(n) * FRAME_PERIOD_S, rec.frames * loops,
                  new_header(calibration=rec.calibration.values))
        if args.reference is not None:  # the reference reads raw format version 1 only
            for path in (short, raw):
                as_version_1(path)
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"recording: {n} frames = {n * FRAME_PERIOD_S / 60:.1f} min")

        # -- binary writers, on results already computed ---------------------------------------
        decoded = read_raw(raw).decode()
        proc = BodyPoseProcessor(rec.calibration)
        results = []
        for lo in range(0, n, CHUNK_FRAMES):
            hi = lo + CHUNK_FRAMES
            r = proc.process(decoded.raw[lo:hi], decoded.errors[lo:hi])
            r.segment_quaternions, r.joint_angles, r.joint_positions  # noqa: B018 (computed here)
            results.append(r)
        meta = ExportMeta(1.7e9, n_frames=n)  # .mat written chunk by chunk
        arrays = {"t": np.concatenate([r.t for r in results]),
                  "q": np.concatenate([r.segment_quaternions for r in results]).astype(np.float32),
                  "a": np.degrees(np.concatenate([r.joint_angles for r in results]))
                  .astype(np.float32),
                  "p": np.concatenate([r.joint_positions for r in results]).astype(np.float32)}
        t0 = time.perf_counter()  # the arrays are built: np.save alone
        for key, value in arrays.items():
            np.save(folder / f"ref_{key}.npy", value)
        t_npy = time.perf_counter() - t0
        size_npy = sum((folder / f"ref_{k}.npy").stat().st_size for k in arrays) / 1e6
        print(f"{'np.save of the same arrays':34s} {t_npy:6.2f} s  {size_npy:7.1f} MB")
        for kind, suffix in (("mat", ".mat"), ("parquet", ".parquet")):
            target = folder / f"writer{suffix}"
            t0 = time.perf_counter()
            writer = open_writer(kind, target, meta)
            for r in results:
                writer.write(r)
            writer.close()
            elapsed = time.perf_counter() - t0
            print(f"{kind + ' writer':34s} {elapsed:6.2f} s  {target.stat().st_size / 1e6:7.1f} MB"
                  f"  ({elapsed / t_npy:.1f}× np.save)")
        del results, decoded, arrays

        # -- whole commands ------------------------------------------------------------------
        t_filter = run(["filter", str(raw), "-o", str(folder / "f.csv")])
        print(f"{'bpms filter (reference)':34s} {t_filter:6.2f} s")
        for kind in ("mat", "parquet"):
            elapsed = run(["convert", str(raw), "-f", kind, "-o", str(folder / f"c_{kind}")])
            print(f"{'bpms convert -f ' + kind:34s} {elapsed:6.2f} s  "
                  f"({elapsed / t_filter:.2f}× bpms filter)")
        elapsed = run(["convert", str(raw), "-o", str(folder / "c_both")])
        print(f"{'bpms convert (both, one pass)':34s} {elapsed:6.2f} s  "
              f"({elapsed / t_filter:.2f}× bpms filter)")

        # -- CSV text, on the rows of that filtered file ----------------------------------------
        block, fmts = filtered_block(folder / "f.csv")
        csv_figures(block, fmts)

        if args.reference is not None:
            trees = {"this tree": REPO, "reference": args.reference.resolve()}
            for tree in trees.values():  # compile or load each tree's kernels first
                run_process(tree, ["filter", str(short), "-o", str(folder / "w.csv"),
                                   "--force"])
            figures: dict[str, list[tuple[float, float]]] = {k: [] for k in trees}
            for _ in range(args.repeat):
                for name, tree in trees.items():
                    figures[name].append(run_process(tree, [
                        "filter", str(raw), "-o", str(folder / "g.csv"), "--force"]))
            same = (folder / "g.csv").read_bytes() == (folder / "f.csv").read_bytes()
            ref_wall = min(w for w, _ in figures["reference"])
            ref_cpu = min(c for _, c in figures["reference"])
            for name in trees:
                wall = min(w for w, _ in figures[name])
                cpu = min(c for _, c in figures[name])
                print(f"{'bpms filter, ' + name:34s} {wall:6.2f} s wall {cpu:6.2f} s CPU  "
                      f"({wall / ref_wall:.2f}× / {cpu / ref_cpu:.2f}× reference)")
            # the trees' files differ in their header lines and in the columns and stages
            # added since (disturbance strengths, the hinge constraint); the row writer's text
            # equals Python's % formatting byte for byte (tests/test_text_rows.py)
            print(f"{'same bytes from both':34s} {'yes' if same else 'no (header, columns)'}")


if __name__ == "__main__":
    main_bench()
