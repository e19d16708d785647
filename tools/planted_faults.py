"""Planted faults: does the test suite catch a wrong instrument?

Copies the package and its tests to a scratch folder, runs a targeted test subset once as is
(it must pass), then plants each fault below on its own (in its own scratch copy) and runs that
fault's tests again. The baseline and the faults run in parallel processes (``--jobs``): most
of each run is pytest starting up, and a fault the tests catch only at a deadline (a link that
never reopens) waits without using the CPU.
Every fault must make at least one test fail by an assertion (pytest.fail and assertion
errors count; import, collection or other errors do not). Prints the table fault → failing
tests; exits 1 if the baseline fails, a patch no longer applies, or a fault survives.

    python tools/planted_faults.py            # the whole run (about 20 s on 2 cores)
    python tools/planted_faults.py --check    # only check that every patch still applies
    python tools/planted_faults.py --only gyro
    python tools/planted_faults.py --jobs 1   # one run after the other

Each fault is an exact-text patch: ``old`` must occur exactly once in ``path``. When someone
changes that code, the patch fails loudly (``--check`` runs in the test suite): update ``old``
and ``new`` to plant the same fault in the new code.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
COPY = ("bpms", "tests", "calib", "docs", "pyproject.toml")  # docs: the UDP reader script


@dataclass(frozen=True)
class Fault:
    name: str
    path: str  # relative to the repository root
    old: str
    new: str
    tests: tuple[str, ...]  # pytest node ids or files, relative to the repository root
    #: its tests fail only at their deadline (tens of seconds): started first
    waits: bool = False


FAULTS: tuple[Fault, ...] = (
    Fault("pitch-90° pre-rotation transposed (13 IMUs)", "bpms/filter/calibration.py",
          "PITCH_90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])",
          "PITCH_90 = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])",
          ("tests/test_conventions_pinned.py", "tests/test_broad_real_motion.py")),
    Fault("roll-90° pre-rotation transposed (shoulders)", "bpms/filter/calibration.py",
          "ROLL_90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])",
          "ROLL_90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])",
          ("tests/test_conventions_pinned.py", "tests/test_broad_real_motion.py")),
    Fault("gyroscope scale x2", "bpms/filter/calibration.py",
          "GYRO_RAD_S_PER_COUNT = 0.06957 * math.pi / 180.0",
          "GYRO_RAD_S_PER_COUNT = 2 * 0.06957 * math.pi / 180.0",
          ("tests/test_broad_real_motion.py",
           "tests/test_sim_physics.py::test_gyro_integrates_to_true_orientation")),
    Fault("gyroscope z sign flipped", "bpms/filter/calibration.py",
          "gyro_signs=np.asarray(sensors.gyro_signs, dtype=np.float64),",
          "gyro_signs=np.asarray(sensors.gyro_signs, dtype=np.float64) * [1.0, 1.0, -1.0],",
          ("tests/test_broad_real_motion.py",)),
    Fault("magnetometer y sign flipped", "bpms/filter/calibration.py",
          "mag_signs=np.asarray(sensors.mag_signs, dtype=np.float64),",
          "mag_signs=np.asarray(sensors.mag_signs, dtype=np.float64) * [1.0, -1.0, 1.0],",
          ("tests/test_conventions_pinned.py", "tests/test_broad_real_motion.py")),
    Fault("one ball joint inverted (right hip: static and dynamic swapped)",
          "bpms/filter/joints.py",
          'BallJoint("hip_r", 0, 6),', 'BallJoint("hip_r", 6, 0),',
          ("tests/test_joint_truth.py",)),
    Fault("suit link never reopens after a read error", "bpms/pipeline/sources.py",
          "            if state is LinkState.GONE:\n                self._reopen()\n",
          "            if state is LinkState.GONE:\n                pass\n",
          ("tests/test_link_reopen.py",), waits=True),
    Fault("parser accepts an end marker one byte early", "bpms/io/parser.py",
          "            if buf[start + END_OFFSET : start + FRAME_SIZE] != END:\n",
          "            if (buf[start + END_OFFSET : start + FRAME_SIZE] != END\n"
          "                    and buf[start + END_OFFSET - 1 : start + FRAME_SIZE - 1] != END):\n",
          ("tests/test_parser_marker_offset.py", "tests/test_parser.py")),
    Fault("Reset Zero ignores the heading reference", "bpms/filter/pose.py",
          "        return np.swapaxes(self.R0, -1, -2) @ rot_z(self.yaw0)\n",
          "        return np.swapaxes(self.R0, -1, -2)\n",
          ("tests/test_filter_pose.py",)),
    Fault("sensor quaternions in the pose (not the segments after Reset Zero)",
          "bpms/pipeline/pose_stream.py",
          "    quats = result.segment_quaternions.astype(np.float32)\n",
          "    quats = result.quaternions.astype(np.float32)\n",
          ("tests/test_recording_udp.py::"
           "test_replayed_pose_datagrams_are_the_segment_orientations",)),
    # issue 46: what the investigator reads, the default filter above 1.5 g, the rate meter,
    # the live filtered file's header
    Fault("joint-angle plot in radians under its [deg] label", "bpms/gui/plot_data.py",
          "lambda b: np.degrees(b.joint_angles[:, k]) if degrees",
          "lambda b: b.joint_angles[:, k] if degrees",
          ("tests/test_displayed_units.py",)),
    Fault("joint-angle list in radians under its [deg] label", "bpms/gui/data_table.py",
          "shown = np.degrees(self.values) if deg else self.values",
          "shown = self.values",
          ("tests/test_displayed_units.py",)),
    Fault("displayed magnetic field without the host's signs", "bpms/filter/calibration.py",
          "mag = (raw[..., 3:6] - self.mag_offset) * MAG_GAUSS_PER_COUNT * self.mag_signs",
          "mag = (raw[..., 3:6] - self.mag_offset) * MAG_GAUSS_PER_COUNT",
          ("tests/test_displayed_units.py", "tests/test_units_outputs.py")),
    Fault("displayed acceleration in the wrong g", "bpms/filter/calibration.py",
          "acc = v[..., 0:3] * (STANDARD_GRAVITY / self.gravity)[:, None]",
          "acc = v[..., 0:3] * (9.80665 / self.gravity)[:, None]",
          ("tests/test_displayed_units.py", "tests/test_units_outputs.py")),
    Fault("Mahony trusts the accelerometer above 1.5 g (weight not clamped at 0)",
          "bpms/filter/mahony.py",
          "    w = min(max(w, 0.0), 1.0)\n", "    w = min(abs(w), 1.0)\n",
          ("tests/test_filter_reference_regimes.py",)),
    Fault("rate meter counts a burst as one frame", "bpms/pipeline/rate.py",
          "self._times.extend([now] * count)", "self._times.append(now)",
          ("tests/test_rate_meter.py",)),
    Fault("hinge constraint turns the proximal segment the wrong way", "bpms/filter/hinge.py",
          "            turn[t, ip] -= e * vp\n", "            turn[t, ip] += e * vp\n",
          ("tests/test_hinge_reference.py",)),
    Fault("disturbance detector learns the gyro bias from a failed gyroscope",
          "bpms/filter/disturbance.py",
          "            if rested and gyr_ok:\n", "            if rested:\n",
          ("tests/test_disturbance_reference.py",)),
    Fault("observer stops tracking gravity above 1.5 g", "bpms/filter/observer.py",
          "    lx = lp[i, 0] + k * (dnx - lp[i, 0])\n",
          "    if math.sqrt(bx * bx + by * by + bz * bz) > 1.5 * G_MS2:\n        k = 0.0\n"
          "    lx = lp[i, 0] + k * (dnx - lp[i, 0])\n",
          ("tests/test_observer_reference.py",)),
    Fault("disturbance detector never takes the field back after a long flag",
          "bpms/filter/disturbance.py",
          "                    if s[F_OK_T] >= p[P_RECOVER_S] and xn > 0.0:\n"
          "                        h0, h1, h2 = x0, x1, x2\n",
          "                    if s[F_OK_T] >= p[P_RECOVER_S] and xn > 0.0:\n"
          "                        pass\n",
          ("tests/test_disturbance_reference.py",)),
    Fault("BVH rotation channels in radians", "bpms/analysis/bvh.py",
          "return np.degrees(np.stack([z, x, y], axis=-1))", "return np.stack([z, x, y], axis=-1)",
          ("tests/test_export_orientations_truth.py",)),
    Fault("OpenSim .mot arm adduction with the abduction's sign", "bpms/filter/joints.py",
          'f"arm_add_{side}": (f"shoulder_{side}.abduction", -1.0)',
          'f"arm_add_{side}": (f"shoulder_{side}.abduction", 1.0)',
          ("tests/test_export_orientations_truth.py",)),
    Fault("OpenSim .sto quaternions written x first", "bpms/analysis/opensim.py",
          "        q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n",
          "        q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n"
          "        q = q[..., [1, 2, 3, 0]]\n",
          ("tests/test_export_orientations_truth.py",)),
    Fault("live filtered file without its source line", "bpms/pipeline/session.py",
          'source = {"source": raw_path.name} if raw else {}', "source = {}",
          ("tests/test_live_equals_batch_file.py",)),
)

# A pytest plugin (written into the scratch folder) that records, per test, whether it failed
# by an assertion (AssertionError or pytest.fail, not a timeout) or by another error.
PLUGIN = '''
import json, os
import pytest

_results = {}


def _is_assertion(value):
    """An assertion error or pytest.fail; a group (hypothesis reports several distinct
    failures as one) counts when all its members do."""
    if isinstance(value, BaseExceptionGroup):
        return all(_is_assertion(v) for v in value.exceptions)
    return isinstance(value, AssertionError) or type(value).__name__ == "Failed"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    entry = _results.setdefault(item.nodeid, {"failed": False, "assertion": False, "why": ""})
    if rep.failed and call.excinfo is not None:
        exc = call.excinfo
        timeout = "Timeout" in str(exc.value)[:40]
        assertion = _is_assertion(exc.value) and not timeout
        entry["failed"] = True
        entry["assertion"] = entry["assertion"] or assertion
        entry["why"] = entry["why"] or f"{rep.when}: {exc.typename}"


def pytest_collectreport(report):
    if report.failed:
        _results[f"<collection> {report.nodeid}"] = {"failed": True, "assertion": False,
                                                    "why": "collection error"}


def pytest_sessionfinish(session):
    with open(os.environ["PLANTED_REPORT"], "w") as f:
        json.dump(_results, f)
'''


def check_patches(root: Path) -> list[str]:
    """Problems with the patches against the code under ``root`` (empty when all apply)."""
    problems = []
    for fault in FAULTS:
        path = root / fault.path
        if not path.is_file():
            problems.append(f"{fault.name}: {fault.path} does not exist")
            continue
        count = path.read_text(encoding="utf-8").count(fault.old)
        if count != 1:
            problems.append(f"{fault.name}: the target text occurs {count} times in "
                            f"{fault.path} (expected once): update the patch")
        for test in fault.tests:
            if not (root / test.split("::")[0]).is_file():
                problems.append(f"{fault.name}: test file {test} does not exist")
    return problems


def run_tests(root: Path, tests: list[str]) -> tuple[int, dict]:
    report = root / "planted_report.json"
    report.unlink(missing_ok=True)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(root / "tests")]),
           "PLANTED_REPORT": str(report)}
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p",
           "planted_plugin", "--rootdir", str(root), *tests]
    proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True,
                          timeout=900)
    results = json.loads(report.read_text()) if report.exists() else {}
    if not results:
        results = {"<pytest>": {"failed": True, "assertion": False,
                                "why": (proc.stdout + proc.stderr)[-300:]}}
    return proc.returncode, results


def scratch_copy(dest: Path) -> Path:
    root = dest / "repo"
    root.mkdir(parents=True)
    for name in COPY:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, root / name, ignore=shutil.ignore_patterns("sketches"))
        else:
            shutil.copy2(src, root / name)
    (root / "tests" / "planted_plugin.py").write_text(PLUGIN)
    return root


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check the patches apply")
    parser.add_argument("--only", metavar="TEXT", help="only the faults whose name contains it")
    parser.add_argument("--jobs", type=int, default=3, metavar="N",
                        help="test runs at the same time (default 3)")
    args = parser.parse_args(argv)
    problems = check_patches(REPO)
    if problems:
        for p in problems:
            print(f"planted faults: {p}", file=sys.stderr)
        return 1
    if args.check:
        print(f"planted faults: all {len(FAULTS)} patches apply")
        return 0
    faults = [f for f in FAULTS if not args.only or args.only.lower() in f.name.lower()]
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="bpms-planted-") as tmp:

        def baseline() -> tuple[int, dict]:
            root = scratch_copy(Path(tmp) / "baseline")
            return run_tests(root, sorted({t for f in faults for t in f.tests}))

        def planted(k: int) -> tuple[list[str], list[str]]:
            fault = faults[k]
            root = scratch_copy(Path(tmp) / f"fault{k}")
            path = root / fault.path
            original = path.read_text(encoding="utf-8")
            path.write_text(original.replace(fault.old, fault.new), encoding="utf-8")
            _, results = run_tests(root, list(fault.tests))
            caught = sorted(n for n, r in results.items() if r["assertion"])
            other = sorted(f"{n} ({r['why']})" for n, r in results.items()
                           if r["failed"] and not r["assertion"])
            print(f"  {'caught' if caught else 'SURVIVED'}: {fault.name} "
                  f"({time.monotonic() - t0:.0f} s)", flush=True)
            return caught, other

        order = sorted(range(len(faults)), key=lambda k: not faults[k].waits)
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            first = pool.submit(baseline)
            runs = {k: pool.submit(planted, k) for k in order}
            code, results = first.result()
            bad = [n for n, r in results.items() if r["failed"]]
            print(f"baseline: {len(results)} tests, {len(bad)} failing "
                  f"({time.monotonic() - t0:.0f} s)", flush=True)
            if code != 0 or bad:
                for future in runs.values():
                    future.cancel()
                for n in bad:
                    print(f"  baseline failure: {n} ({results[n]['why']})")
                print("planted faults: the baseline must pass first", file=sys.stderr)
                return 1
            rows = [(fault, *runs[k].result()) for k, fault in enumerate(faults)]
    print()
    print("| fault | failing tests (assertions) |")
    print("|---|---|")
    for fault, caught, other in rows:
        shown = ", ".join(c.replace("tests/", "") for c in caught[:6])
        more = f" (+{len(caught) - 6} more)" if len(caught) > 6 else ""
        print(f"| {fault.name} | {shown + more if caught else '**NONE: survived**'} |")
        for o in other:
            print(f"|   (not counted: {o}) | |")
    survived = [f.name for f, caught, _ in rows if not caught]
    print(f"\n{len(rows) - len(survived)}/{len(rows)} faults caught "
          f"in {time.monotonic() - t0:.0f} s")
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
