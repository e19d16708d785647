"""Benchmark: start-up time of ``bpms`` beside ``python -c "import numpy"``, in the same run.

Run: .venv/bin/python bench/startup.py [--repeats N] [--seconds S]
Prints the median wall time of each command over N runs (fresh processes taking turns, warm
disk cache, numba kernels already compiled), its ratio to the numpy reference, the same
``bpms filter`` of the tree before issue 24 (bench/reference.py), whether the start-up window
imports numba or OpenGL, and a ``-X importtime`` summary of ``bpms filter``.
Aims: ``bpms --help`` ≤ 2× (issue 18.3) and ``bpms filter`` of the 5-s recording ≤ 8×
``import numpy`` (issue 24; numba's import alone is about 3.5×); the start-up window imports
neither numba nor OpenGL.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def wall(cmd: list[str], env: dict[str, str], repeats: int) -> float:
    """Median wall time of ``cmd`` over ``repeats`` fresh processes, s."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def importtime(cmd: list[str], env: dict[str, str], top: int) -> list[tuple[int, str]]:
    """The ``top`` imports of ``cmd`` by cumulative time: ``(microseconds, module)``,
    first-level packages and bpms modules only."""
    done = subprocess.run([cmd[0], "-X", "importtime", *cmd[1:]], env=env, cwd=ROOT,
                          capture_output=True, text=True, check=True)
    rows = []
    for line in done.stderr.splitlines():
        if not line.startswith("import time:") or "|" not in line:
            continue
        _, cumulative, name = (part.strip() for part in line[len("import time:"):].split("|"))
        if not cumulative.isdigit():
            continue
        if "." not in name or name.startswith("bpms."):
            rows.append((int(cumulative), name))
    return sorted(rows, reverse=True)[:top]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--seconds", type=float, default=5.0, help="length of the short recording")
    ap.add_argument("--top", type=int, default=15, help="rows of the importtime summary")
    ap.add_argument("--reference", default="auto",
                    help="auto (also time the tree before issue 24) or none")
    ap.add_argument("--python", default=None, metavar="PATH",
                    help="time the bpms installed for this interpreter (e.g. a virtualenv made "
                         "from the wheel) instead of this source tree")
    args = ap.parse_args()
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    # as installed: modules load from their cached bytecode (pip writes it at install time)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if args.python:
        env.pop("PYTHONPATH", None)
    else:
        env["PYTHONPATH"] = str(ROOT)
    py = args.python or sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "Raw_short_1.bpmsraw"
        out = Path(tmp) / "Filtered_short_1.csv"
        subprocess.run([py, "-c", "import sys; from bpms.firmware.sim.session import simulate; "
                        f"simulate({args.seconds}).save_raw(sys.argv[1])", str(raw)],
                       env=env, cwd=ROOT, check=True)
        subprocess.run([py, "-m", "bpms", "warmup"], env=env, cwd=ROOT, check=True,
                       stderr=subprocess.DEVNULL)
        filt = [py, "-m", "bpms", "filter", str(raw), "-o", str(out), "--force"]
        cases = [
            ("python -c 'import numpy' (reference)", [py, "-c", "import numpy"], None),
            ("python -c 'import numba' (compiled kernels' floor)", [py, "-c", "import numba"],
             None),
            ("bpms --help", [py, "-m", "bpms", "--help"], 2.0),
            ("bpms filter --help", [py, "-m", "bpms", "filter", "--help"], None),
            (f"bpms filter ({args.seconds:g} s recording)", filt, 8.0),
        ]
        ref_env = None
        if not args.python and args.reference != "none":
            sys.path.insert(0, str(ROOT / "bench"))
            from reference import python_in, reference_tree

            try:
                tree = reference_tree()
                ref_env = {**python_in(tree), "QT_QPA_PLATFORM": "offscreen"}
                subprocess.run([py, "-m", "bpms", "warmup"], env=ref_env, cwd=ROOT, check=True,
                               stderr=subprocess.DEVNULL)
                cases.append((f"bpms filter ({args.seconds:g} s), before issue 24", filt, None))
            except (RuntimeError, subprocess.CalledProcessError) as exc:
                print(f"reference not measured: {exc}")
        if not subprocess.run([py, "-c", "import PyQt6"], env=env, capture_output=True).returncode:
            cases.append(("import the start-up window (Qt)",
                          [py, "-c", "import bpms.gui.startup"], None))
        # Interleaved rounds, so that a burst of load elsewhere hits every case alike.
        times: dict[str, list[float]] = {name: [] for name, _, _ in cases}
        for _ in range(args.repeats):
            for name, cmd, _ in cases:
                times[name].append(wall(cmd, ref_env if "before issue 24" in name else env, 1))
        ref = statistics.median(times[cases[0][0]])
        print(f"median of {args.repeats} fresh processes each, this machine, same run")
        print(f"{'command':<52} {'s':>7} {'× numpy':>8}  aim")
        for name, _, aim in cases:
            t = statistics.median(times[name])
            verdict = "" if aim is None else (f"≤ {aim:g}×  " + ("met" if t / ref <= aim
                                                                 else "NOT met"))
            print(f"{name:<52} {t:7.3f} {t / ref:8.2f}  {verdict}")
        has_qt = not subprocess.run([py, "-c", "import PyQt6"], env=env,
                                    capture_output=True).returncode
        heavy = "n/a (no Qt installed)"
        if has_qt:
            heavy = subprocess.run(
                [py, "-c", "import sys, bpms.gui.startup; print(sorted(m for m in "
                 "('numba', 'OpenGL', 'matplotlib') if m in sys.modules))"],
                env=env, cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
        print(f"start-up window imports of numba/OpenGL/matplotlib: {heavy}")
        print(f"\n-X importtime of `bpms filter` (cumulative, top {args.top}):")
        for us, name in importtime(filt, env, args.top):
            print(f"  {us / 1000:8.1f} ms  {name}")


if __name__ == "__main__":
    main()
