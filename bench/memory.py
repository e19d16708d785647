"""Peak memory of every whole-recording command (a short vs a long recording, side by side),
and of the API's ``process_file`` against the arrays it returns.

Run: ``.venv/bin/python bench/memory.py [--short 10] [--long 180] [--commands filter,rom]
[--api 60] [--reference none]``.

The recordings are the simulated suit's scripted motion (``simulate(seed=1)``, 60 s) repeated
to the requested length (minutes) and written as native raw files with its calibration. Each
command runs in a fresh subprocess (``python -m bpms ...``); its peak resident set size comes
from the operating system (``os.wait4`` rusage; Linux and macOS). The short and the long
recording take turns command by command, so that load from elsewhere falls on both alike.
Printed per command: peak RSS for the short and the long recording, their ratio (the goal:
≤ 1.2, constant memory), and the wall time of each with their ratio against the length ratio
(linear time).

``process_file`` of an ``--api`` minutes recording, in a fresh process: the peak RSS minus the
RSS after the imports and the filter's warm-up, against the ``nbytes`` of every array of the
returned Result, its lazy fields (segment Euler angles, output angles, estimates, joint angles
and positions, both quaternion sets) counted as materialised (the aim, issue 24: ≤ 1.3×);
beside the same figures of the tree before issue 24 (bench/reference.py). Figures only.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

COMMANDS: dict[str, list[str]] = {
    "filter": ["filter", "{raw}", "--joints", "-o", "{out}/f.csv", "--force"],
    "export opensim": ["export", "opensim", "{raw}", "-o", "{out}/os", "--force"],
    "export bvh": ["export", "bvh", "{raw}", "-o", "{out}/b.bvh", "--force"],
    "export matlab": ["export", "matlab", "{raw}", "-o", "{out}/m.csv", "--force"],
    "export c3d": ["export", "c3d", "{raw}", "-o", "{out}/c", "--force"],
    "convert mat": ["convert", "{raw}", "-f", "mat", "-o", "{out}/v", "--force"],
    "rom": ["rom", "{raw}", "-o", "{out}", "--no-figures"],
    "track": ["track", "{raw}", "-o", "{out}/t.csv", "--no-figure"],
    "extract raw": ["extract", "raw", "{raw}", "--imu", "all", "-o", "{out}/r.csv", "--force"],
    "extract filtered": ["extract", "filtered", "{filtered}", "--imu", "all", "-o",
                         "{out}/e.csv", "--force"],
}


def make_long_recording(path: str | Path, minutes: float, seed: int = 1) -> Path:
    """A native raw recording of ``minutes`` of the simulated suit: 60 s of its scripted
    motion (with its true calibration in the header) repeated, written block by block (the
    memory used does not grow with the length)."""
    from bpms.firmware.sim.session import simulate
    from bpms.io.frames import FRAME_PERIOD_S
    from bpms.io.rawfile import RECORD_DTYPE, new_header, write_raw

    rec = simulate(duration_s=60.0, seed=seed)
    n = len(rec.t)
    total = max(1, round(minutes * 60.0 / FRAME_PERIOD_S))
    path = Path(path)
    first = min(n, total)
    start = 1.7e9
    write_raw(path, start + np.arange(first) * FRAME_PERIOD_S, rec.frames[: first * 340],
              new_header(calibration=rec.calibration.values, notes="bench: repeated simulation"))
    block = np.empty(n, dtype=RECORD_DTYPE)
    block["frame"] = np.frombuffer(rec.frames, dtype=RECORD_DTYPE["frame"])
    with open(path, "ab") as f:
        done = first
        while done < total:
            k = min(n, total - done)
            block["time"][:k] = start + (done + np.arange(k)) * FRAME_PERIOD_S
            f.write(block[:k].tobytes())
            done += k
    return path


def peak_rss_mb(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(peak RSS in MB, wall time in s) of ``python -m bpms argv`` in a fresh process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "bpms", *argv], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    elapsed = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"bpms {' '.join(argv)} failed ({proc.returncode}): {err[-400:]}")
    scale = 1 / 1024 if sys.platform != "darwin" else 1 / 1024 / 1024  # kB on Linux, B on macOS
    return usage.ru_maxrss * scale, elapsed


_API_CHILD = r"""
import resource, sys
import numpy as np
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize()
try:
    from bpms.filter.door import process_file
except ImportError:  # the tree before issue 24
    from bpms.filter.processor import BodyPoseProcessor
    process_file = lambda path: BodyPoseProcessor().process_file(path)
process_file(sys.argv[2])  # warm-up: numba and every kernel loaded, caches filled
import gc; gc.collect()
base = rss()
result = process_file(sys.argv[1])
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
arrays = [v for v in vars(result).values() if isinstance(v, np.ndarray)]
if result.disturbance is not None:
    arrays += [v for v in vars(result.disturbance).values() if isinstance(v, np.ndarray)]
lazy = [result.euler_segment, result.euler_output, result.estimates, result.joint_angles,
        result.joint_positions, result.quaternions, result.segment_quaternions]
print(peak - base, sum(a.nbytes for a in arrays), sum(a.nbytes for a in lazy), len(result))
"""


def api_figures(tmp: Path, minutes: float, env: dict[str, str], reference: str) -> None:
    """``process_file`` peak memory against the returned arrays, this tree and the one before
    issue 24, in fresh processes taking turns."""
    raw = make_long_recording(tmp / "Raw_api_001.bpmsraw", minutes)
    small = make_long_recording(tmp / "Raw_api_002.bpmsraw", 0.2)
    trees = [("this tree", ROOT)]
    if reference != "none":
        sys.path.insert(0, str(ROOT / "bench"))
        from reference import as_version_1, reference_tree

        for path in (raw, small):  # the reference reads raw format version 1 only
            as_version_1(path)
        try:
            trees.append(("before issue 24", reference_tree()))
        except RuntimeError as exc:
            print(f"reference not measured: {exc}")
    print(f"\nprocess_file of a {minutes:g}-minute recording (MiB; aim: peak − after import "
          "≤ 1.3 × the arrays returned, lazy fields counted as materialised)")
    for name, tree in trees:
        child_env = {**env, "PYTHONPATH": str(tree)}
        done = subprocess.run([sys.executable, "-c", _API_CHILD, str(raw), str(small)],
                              env=child_env, cwd=tree, capture_output=True, text=True)
        if done.returncode:
            print(f"  {name}: failed: {done.stderr.strip().splitlines()[-1:]}")
            continue
        grown, eager, lazy, frames = (int(x) for x in done.stdout.split())
        mib = 1 << 20
        print(f"  {name:<16} {frames:,} frames: peak − after import {grown / mib:7.0f}; "
              f"arrays returned {eager / mib:6.0f} + lazy {lazy / mib:6.0f} = "
              f"{(eager + lazy) / mib:6.0f}; ratio {grown / (eager + lazy):4.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", type=float, default=10.0, help="short recording, minutes")
    parser.add_argument("--long", type=float, default=180.0, help="long recording, minutes")
    parser.add_argument("--commands", default=",".join(COMMANDS),
                        help="comma-separated subset of: " + ", ".join(COMMANDS))
    parser.add_argument("--api", type=float, default=60.0,
                        help="minutes of the process_file recording (0: skip)")
    parser.add_argument("--reference", default="auto",
                        help="auto (the tree before issue 24) or none")
    args = parser.parse_args()
    if not hasattr(os, "wait4"):
        raise SystemExit("this benchmark needs os.wait4 (Linux or macOS)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    chosen = [c.strip() for c in args.commands.split(",") if c.strip()]
    with tempfile.TemporaryDirectory(prefix="bpms-mem-") as tmp:
        rows = {}
        made = {}
        for minutes in (args.short, args.long):
            folder = Path(tmp) / f"{minutes:g}"
            folder.mkdir()
            raw = make_long_recording(folder / "Raw_bench_001.bpmsraw", minutes)
            filtered = folder / "Filtered_bench_001.csv"
            subprocess.run([sys.executable, "-m", "bpms", "filter", str(raw), "-o",
                            str(filtered)], env=env, check=True, capture_output=True)
            print(f"{minutes:g} min: {raw.stat().st_size / 1e6:.0f} MB raw", flush=True)
            made[minutes] = (folder, raw, filtered)
        for name in chosen:
            for minutes in (args.short, args.long):
                folder, raw, filtered = made[minutes]
                argv = [a.format(raw=raw, out=folder, filtered=filtered)
                        for a in COMMANDS[name]]
                rows.setdefault(name, []).append(peak_rss_mb(argv, env))
                print(f"  {name}, {minutes:g} min: {rows[name][-1][0]:.0f} MB, "
                      f"{rows[name][-1][1]:.1f} s", flush=True)
        if args.api:
            api_figures(Path(tmp), args.api, env, args.reference)
    length_ratio = args.long / args.short
    print(f"\npeak RSS (MB) and wall time (s), {args.short:g} vs {args.long:g} minutes "
          f"(length ×{length_ratio:.0f}; goal: RSS ratio ≤ 1.2, time ratio ≈ length ratio)")
    print(f"{'command':<18}{'RSS short':>10}{'RSS long':>10}{'ratio':>7}"
          f"{'t short':>9}{'t long':>9}{'t ratio':>9}")
    for name, ((m0, t0), (m1, t1)) in rows.items():
        print(f"{name:<18}{m0:10.0f}{m1:10.0f}{m1 / m0:7.2f}{t0:9.1f}{t1:9.1f}{t1 / t0:9.1f}")
    print(f"load average: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
