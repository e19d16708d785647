"""Speed of the filters on a 30-minute 18-IMU session, each figure beside the tree before the
one-implementation work (bench/reference.py) measured in the same run, and beside the peers.

Run: ``.venv/bin/python bench/filter.py [--minutes 30] [--peer-seconds 60] [--rounds 2]
[--reference none]``; each tree is measured in child processes taking turns.

The session is the simulated suit's scripted motion (``bpms.firmware.sim.session.simulate``)
looped to the requested length (90,000 frames = 1.62 M IMU updates for 30 minutes). Printed:

- the first-ever compile: ``bpms warmup`` with an empty numba cache, this tree and the
  reference (aim, issue 24: ≤ 10 s);
- a check that the Mahony kernel matches the scalar reference (tests/reference_mahony.py)
  within 1e-9;
- IMU updates/s: the Mahony kernel alone on calibrated inputs (aim ≥ 0.9× the reference),
  the whole processor (raw counts → calibration → filters → guard → Reset Zero → disturbance
  indicators), and ``--filter vqf`` through the processor and through its bank beside the
  ``vqf`` package's own batch call on the same data (aim ≥ 0.8×);
- the peers on the same data in their units: ``imufusion.Ahrs`` (a Python call per sample),
  ``ahrs.filters.Mahony`` (pure Python, ``--peer-seconds`` of data per IMU only);
- one live frame from its wire bytes (``step_wire``, 18 IMUs), p50 / p99, in a tight loop.

Figures only; nothing is asserted on time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
N_IMUS = 18


def _tree() -> Path:
    """The bpms tree this process runs (``--tree`` for a child run of the reference)."""
    if "--tree" in sys.argv:
        return Path(sys.argv[sys.argv.index("--tree") + 1]).resolve()
    return HERE.parent


sys.path.insert(0, str(_tree()))

from bpms.filter.bank import MahonyBank  # noqa: E402
from bpms.filter.processor import BodyPoseProcessor  # noqa: E402
from bpms.firmware.sim.session import simulate  # noqa: E402
from bpms.io.frames import encode_frame  # noqa: E402
from bpms.io.options import Options  # noqa: E402


def session(minutes: float) -> tuple[np.ndarray, np.ndarray, BodyPoseProcessor]:
    rec = simulate(seed=0)
    n = round(minutes * 60 * 50)
    reps = -(-n // len(rec))
    raw = np.tile(rec.raw, (reps, 1, 1))[:n]
    errors = np.tile(rec.errors, (reps, 1, 1))[:n]
    return raw, errors, BodyPoseProcessor(rec.calibration)


def _best(run, repeats: int = 3) -> float:
    """The shortest of ``repeats`` runs of ``run()``, s (the least disturbed by other load)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def measure(minutes: float) -> dict[str, float]:
    """The figures of this process's tree (s, or µs for the live frame)."""
    raw, errors, proc = session(minutes)
    cal = proc.sensor_calibration
    acc, mag, gyr = cal.calibrate(raw)
    out: dict[str, float] = {"frames": len(raw)}
    MahonyBank(cal.gravity).process(acc[:10], mag[:10], gyr[:10])  # loaded before timing
    out["kernel"] = _best(lambda: MahonyBank(cal.gravity).process(acc, mag, gyr, errors))
    BodyPoseProcessor(proc.table).process(raw[:10], errors[:10])
    out["processor"] = _best(lambda: BodyPoseProcessor(proc.table).process(raw, errors))
    options = Options()
    options.filter.algorithm = "vqf"
    try:
        BodyPoseProcessor(proc.table, options).process(raw[:10], errors[:10])
        out["vqf processor"] = _best(
            lambda: BodyPoseProcessor(proc.table, options).process(raw, errors), 1)
    except Exception:
        pass
    p = BodyPoseProcessor(proc.table)
    wire = [encode_frame(raw[k], errors[k]) for k in range(3000)]
    for k in range(100):
        p.step_wire(wire[k])
    lat = np.empty(len(wire) - 100)
    for k in range(100, len(wire)):
        t0 = time.perf_counter()
        p.step_wire(wire[k])
        lat[k - 100] = time.perf_counter() - t0
    out["live p50"], out["live p99"] = (float(v) * 1e6 for v in np.percentile(lat, [50, 99]))
    return out


def check_reference(frames: int = 2000) -> float:
    """Max difference of the Mahony kernel from the scalar reference over all IMUs."""
    sys.path.insert(0, str(HERE.parent))
    from tests.reference_mahony import ReferenceMahony

    raw, _errors, proc = session(frames / 50 / 60)
    acc, mag, gyr = proc.sensor_calibration.calibrate(raw)
    gravity = proc.sensor_calibration.gravity
    out = MahonyBank(gravity).process(acc, mag, gyr, store_terms=True)
    worst = 0.0
    for i in range(N_IMUS):
        ref = ReferenceMahony(gravity[i])
        for k in range(frames):
            ref.update(acc[k, i].tolist(), mag[k, i].tolist(), gyr[k, i].tolist())
        worst = max(worst, np.abs(out.R[k, i] - np.array(ref.R)).max(),
                    np.abs(out.w_i[k, i] - np.array(ref.w_i)).max(),
                    np.abs(out.euler[k, i] - [ref.roll, ref.pitch, ref.yaw]).max())
    return float(worst)


def vqf_figures(minutes: float) -> tuple[float, float] | None:
    """(the VQF bank on calibrated inputs, the vqf package alone on the same data), s."""
    try:
        import vqf
    except ImportError:
        return None
    from bpms.filter.algorithms import VqfBank

    raw, errors, proc = session(minutes)
    cal = proc.sensor_calibration
    acc, mag, gyr = cal.calibrate(raw)
    options = Options().filter
    options.algorithm = "vqf"
    bank = VqfBank(cal.gravity, options)
    f, m, g = bank.physical(acc, mag, gyr,
                            out=tuple(np.empty((N_IMUS, len(acc), 3)) for _ in range(3)))
    columns = [(g[i], f[i], m[i]) for i in range(N_IMUS)]

    def package() -> None:
        for gi, fi, mi in columns:
            vqf.VQF(0.02).updateBatch(gi, fi, mi)

    return (_best(lambda: VqfBank(cal.gravity, options).process(acc, mag, gyr, errors), 2),
            _best(package, 2))


def first_compile(tree: Path) -> float:
    """``bpms warmup`` of ``tree`` with an empty numba cache, s (the whole command)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(tree)}
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "bpms", "warmup"], env=env, cwd=tree,
                       capture_output=True, text=True, timeout=600, check=True)
        return time.perf_counter() - t0


def child_figures(tree: Path, minutes: float) -> dict[str, float] | str:
    """:func:`measure` of ``tree`` in a fresh child process (its figures, or why it failed)."""
    sys.path.insert(0, str(HERE))
    from reference import python_in

    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        path = f.name
    done = subprocess.run([sys.executable, __file__, "--tree", str(tree), "--child", path,
                           "--minutes", str(minutes)], env=python_in(tree), cwd=tree,
                          capture_output=True, text=True, timeout=3600)
    if done.returncode:
        return f"failed: {done.stderr.strip().splitlines()[-1:]}"
    figures = json.loads(Path(path).read_text())
    os.unlink(path)
    return figures


def figures_in_turns(trees: dict[str, Path], minutes: float, rounds: int
                     ) -> dict[str, dict[str, float]]:
    """Each tree's figures, each the best over ``rounds`` child processes taking turns (so
    that other load falls on every tree alike)."""
    best: dict[str, dict[str, float]] = {name: {} for name in trees}
    for _ in range(rounds):
        for name, tree in trees.items():
            figures = child_figures(tree, minutes)
            if isinstance(figures, str):
                print(f"{name}: {figures}")
                continue
            for key, value in figures.items():
                best[name][key] = min(best[name].get(key, value), value)
    return best


def _line(name: str, updates: int, ours: float, ref: float | None, aim: str = "") -> None:
    rate = updates / ours / 1e6
    text = f"{name:<36}{rate:7.2f} M IMU-updates/s ({ours:6.2f} s)"
    if ref is not None:
        text += f"   reference {updates / ref / 1e6:6.2f} M/s ({ref:6.2f} s): {ref / ours:4.2f}×"
    print(text + (f"  {aim}" if aim else ""))


def peers(minutes: float, peer_frames: int) -> None:
    raw, _, proc = session(minutes)
    acc, mag, gyr = proc.sensor_calibration.calibrate(raw)
    f = -acc / proc.sensor_calibration.gravity[None, :, None] * 9.81
    n = len(raw)
    try:
        import imufusion

        g_deg, f_g = np.degrees(gyr), f / 9.81
        t0 = time.perf_counter()
        for i in range(N_IMUS):
            a = imufusion.Ahrs()
            settings = imufusion.AhrsSettings()
            settings.convention = imufusion.CONVENTION_NED
            settings.sample_rate = 50
            a.set_settings(settings)
            for k in range(n):
                a.update(g_deg[k, i], f_g[k, i], mag[k, i])
        _line("imufusion Ahrs.update (Python loop)", n * N_IMUS, time.perf_counter() - t0, None)
    except ImportError:
        print("imufusion: not installed")
    try:
        from ahrs.filters import Mahony

        m = min(n, peer_frames)
        t0 = time.perf_counter()
        for i in range(N_IMUS):
            Mahony(gyr=gyr[:m, i], acc=f[:m, i], mag=mag[:m, i], frequency=50.0)
        _line("ahrs Mahony batch (pure Python)", m * N_IMUS, time.perf_counter() - t0, None)
    except ImportError:
        print("ahrs: not installed")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="session length, min")
    parser.add_argument("--peer-seconds", type=float, default=60.0,
                        help="data per IMU for the slow pure-Python peer (ahrs), s")
    parser.add_argument("--reference", default="auto", help="auto (the tree before issue 24) "
                        "or none")
    parser.add_argument("--rounds", type=int, default=2,
                        help="child processes per tree, taking turns")
    parser.add_argument("--tree", help=argparse.SUPPRESS)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        Path(args.child).write_text(json.dumps(measure(args.minutes)))
        return
    trees = {"this tree": HERE.parent}
    tree = None
    if args.reference != "none":
        sys.path.insert(0, str(HERE))
        from reference import reference_tree

        try:
            tree = trees["reference"] = reference_tree()
        except RuntimeError as exc:
            print(f"reference: {exc}")
    ours_compile = first_compile(HERE.parent)
    text = f"first-ever compile (bpms warmup, empty numba cache): {ours_compile:5.1f} s"
    if tree is not None:
        text += f"   reference {first_compile(tree):5.1f} s"
    print(text + "  (aim ≤ 10 s)")
    worst = check_reference()
    print(f"Mahony kernel vs the scalar reference, 2000 frames × 18 IMUs: max |diff| "
          f"{worst:.1e} ({'OK' if worst < 1e-9 else 'FAIL'}, limit 1e-9)")
    figures = figures_in_turns(trees, args.minutes, args.rounds)
    ours, theirs = figures["this tree"], figures.get("reference", {})
    n = int(ours["frames"])
    print(f"session: {n:,} frames × 18 IMUs = {n * N_IMUS / 1e6:.2f} M IMU updates "
          f"({n / 50 / 60:.1f} min at 50 Hz); each tree in {args.rounds} child processes "
          "taking turns, best of 3 runs in each")
    _line("Mahony kernel (calibrated in)", n * N_IMUS, ours["kernel"], theirs.get("kernel"),
          "(aim ≥ 0.9×)")
    _line("processor, mahony (raw in)", n * N_IMUS, ours["processor"], theirs.get("processor"))
    if "vqf processor" in ours:
        _line("processor, vqf (raw in)", n * N_IMUS, ours["vqf processor"],
              theirs.get("vqf processor"))
    vqf = vqf_figures(args.minutes)
    if vqf is not None:
        bank, package = vqf
        _line("VqfBank (calibrated in)", n * N_IMUS, bank, None)
        _line("vqf package, VQF.updateBatch × 18", n * N_IMUS, package, None)
        print(f"{'':<36}VqfBank at {package / bank:.2f}× the package (aim ≥ 0.8×)")
    peers(args.minutes, round(args.peer_seconds * 50))
    text = (f"live frame from wire bytes (step_wire)  p50 {ours['live p50']:6.1f} µs  "
            f"p99 {ours['live p99']:6.1f} µs")
    if "live p50" in theirs:
        text += f"   reference p50 {theirs['live p50']:6.1f} µs  p99 {theirs['live p99']:6.1f} µs"
    print(text)
    print(f"load average: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
