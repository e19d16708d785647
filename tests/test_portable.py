"""Runs where there is no ``termios``/``tty``/``pty``/``fcntl`` and no ``os.openpty`` (Windows).

Windows and macOS can only be emulated here: each check runs ``bpms`` in a subprocess whose
``sys.modules`` maps those four modules to None (so importing them fails) and which has no
``os.openpty``. pyserial is imported before the block, as its own platform back-end would be
(on Linux that back-end needs termios; on Windows pyserial uses its win32 one instead).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path, PurePosixPath, PureWindowsPath

import pytest

from bpms.cli import command_names
from bpms.firmware.sim.session import simulate
from bpms.io.naming import RecordingNamer, safe_stem
from bpms.io.recordings import open_recording

ROOT = Path(__file__).resolve().parents[1]
UNIX_ONLY = ("termios", "tty", "pty", "fcntl")

PRELUDE = f"""
import os, sys
import serial, serial.tools.list_ports  # third-party, loaded by its own platform back-end
for _name in {UNIX_ONLY!r}:
    sys.modules[_name] = None
if hasattr(os, "openpty"):
    del os.openpty
sys.argv[0] = "bpms"
"""


def blocked(code: str, **kw) -> subprocess.CompletedProcess:
    """Run ``code`` in a Python without the Unix-only modules."""
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-c", PRELUDE + code], cwd=kw.pop("cwd", ROOT),
                          env=env, capture_output=True, text=True, timeout=kw.pop("timeout", 120),
                          **kw)


def blocked_cli(*args: str, **kw) -> subprocess.CompletedProcess:
    return blocked(f"from bpms.cli import main; sys.exit(main({list(args)!r}))", **kw)


def test_the_emulation_really_blocks_them():
    done = blocked("import tty")
    assert done.returncode != 0 and "ModuleNotFoundError" in done.stderr
    done = blocked("from bpms.firmware.sim.server import pty_available; print(pty_available())")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_help_of_bpms_and_of_every_command():
    names = command_names()
    assert {"filter", "record", "monitor", "calibrate", "sim", "gui"} <= set(names)
    code = (
        "from bpms.cli import main\n"
        f"for argv in [['--help'], *[[n, '--help'] for n in {names!r}]]:\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit as exc:\n"
        "        assert exc.code == 0, (argv, exc.code)\n"
        "    print('HELPED', argv[0], flush=True)\n"
        f"bad = sorted(m for m in {UNIX_ONLY!r} if sys.modules.get(m) is not None)\n"
        "print('LOADED', bad)\n"
    )
    done = blocked(code)
    assert done.returncode == 0, done.stderr
    helped = re.findall(r"^HELPED (\S+)", done.stdout, re.M)
    assert helped == ["--help", *names]
    assert "LOADED []" in done.stdout
    for name in names:
        assert re.search(rf"^\s+{name}\s+\S", done.stdout, re.M), name  # listed with its line


def test_filter_a_recording_into_a_folder_with_spaces(tmp_path):
    folder = tmp_path / "Lab data" / "S 01"
    folder.mkdir(parents=True)
    raw = simulate(2.0, seed=3).save_raw(folder / "Raw_S01_1.bpmsraw")
    out = folder / "Filtered S01.csv"
    done = blocked_cli("filter", str(raw), "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    rows = lines[1:]  # after the column names
    assert len(rows) == len(open_recording(raw)) == 100  # 2 s at 50 Hz, every frame filtered


def test_sim_serves_tcp_and_monitor_reads_it():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    sim = subprocess.Popen(
        [sys.executable, "-c", PRELUDE + "from bpms.cli import main; "
         "sys.exit(main(['sim', '--tcp', '0']))"],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = sim.stdout.readline().strip()
        assert url.startswith("socket://127.0.0.1:"), sim.stderr.read() if sim.poll() else url
        done = blocked_cli("monitor", url, "--seconds", "2.5")
        assert done.returncode == 0, done.stderr
        assert f"connected to the suit on {url}" in done.stdout
        frames = [int(n) for n in re.findall(r"frames\s+(\d+)", done.stdout)]
        assert frames and max(frames) > 0, done.stdout
    finally:
        sim.terminate()
        sim.communicate(timeout=20)


def test_sim_pty_says_in_one_line_to_use_tcp():
    done = blocked_cli("sim", "--pty")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--tcp" in lines[0], done.stderr


def test_record_the_simulated_suit_over_tcp(tmp_path):
    done = blocked_cli("record", "--sim", "--seconds", "2", "-o", str(tmp_path),
                       "--name", 'S01: "left" <knee>')
    assert done.returncode == 0, done.stderr
    assert "socket://127.0.0.1:" in done.stdout
    raws = sorted(tmp_path.glob("*.bpmsraw"))
    assert len(raws) == 1
    assert _valid_windows_name(raws[0].name)
    assert len(open_recording(raws[0])) > 25  # 2 s at 50 Hz, minus connecting


def test_calibrate_the_simulated_suit(tmp_path):
    out = tmp_path / "Calib.cfg"
    done = blocked_cli("calibrate", "--sim", "--sim-speed", "0", "--yes", "--imu", "3",
                       "--sensor", "gyro", "--gyro-samples", "50", "-o", str(out), timeout=240)
    assert done.returncode == 0, done.stderr
    assert out.is_file() and "Traceback" not in done.stderr


def test_gui_start_up_and_its_simulated_suit():
    code = """
from PyQt6.QtWidgets import QApplication
app = QApplication([])
from bpms.gui.startup import StartupWindow
from bpms.gui.modes import SimulatedSuit
from bpms.io.link import SuitLink
w = StartupWindow()
w.show()
app.processEvents()
suit = SimulatedSuit()
with SuitLink(suit.path) as link:
    link.identify()
print('SIM', suit.path)
suit.close()
w.close()
print('HEAVY', sorted(m for m in ('numba', 'OpenGL') if m in sys.modules))
"""
    done = blocked(code)
    assert done.returncode == 0, done.stderr
    assert re.search(r"^SIM socket://127\.0\.0\.1:\d+$", done.stdout, re.M), done.stdout
    assert "HEAVY []" in done.stdout  # the start-up window loads neither numba nor OpenGL


# -- file names ------------------------------------------------------------------------------
WINDOWS_FORBIDDEN = set('<>:"/\\|?*') | {chr(c) for c in range(32)}
WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)),
                    *(f"LPT{i}" for i in range(1, 10))}


def _valid_windows_name(name: str) -> bool:
    """Windows' own rules for one file name (Microsoft's "Naming Files, Paths, and
    Namespaces"): no forbidden character, no reserved device name, no trailing dot or space."""
    stem = name.split(".")[0].upper()
    return (bool(name) and not (set(name) & WINDOWS_FORBIDDEN) and stem not in WINDOWS_RESERVED
            and not name.endswith((".", " ")) and len(name) <= 255)


@pytest.mark.parametrize("subject", [
    'S01: "left" <knee>', r"C:\Users\lab\S01", "../../etc/passwd", "a/b\\c|d?e*f",
    "CON", "nul", "  trailing dots...  ", "Müller, Jürgen", "x" * 400, "\t\n",
])
def test_recording_names_from_subject_names_are_valid_everywhere(tmp_path, subject):
    namer = RecordingNamer(tmp_path, subject)
    raw, filtered = namer.next_paths()
    for path in (raw, filtered):
        assert path.parent == tmp_path  # never another folder, whatever the separators
        assert _valid_windows_name(path.name), path.name
        assert PureWindowsPath(path.name).name == path.name
        assert PurePosixPath(path.name).name == path.name
    stem = safe_stem(subject)
    assert not (set(stem) & WINDOWS_FORBIDDEN)
    raw.write_bytes(b"")
    assert namer.next_paths()[0] != raw  # a taken name is skipped


def test_per_user_folders_resolve_windows_style_overrides(monkeypatch, tmp_path):
    from bpms.io import userdirs

    monkeypatch.setenv("BPMS_DATA_DIR", str(tmp_path / "D ata"))
    assert userdirs.recordings_dir() == tmp_path / "D ata" / "recordings"
    assert PureWindowsPath(r"C:\Users\lab\AppData\Local\bpms").parts[-1] == "bpms"


def test_no_unix_only_import_at_module_level_in_bpms():
    """Static check over every module: termios/tty/pty/fcntl only inside functions."""
    import ast

    offenders = []
    for path in (ROOT / "bpms").rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in tree.body:
            names = []
            if isinstance(node, ast.Import):
                names = [a.name.split(".")[0] for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module.split(".")[0]]
            offenders += [f"{path.relative_to(ROOT)}: {n}" for n in names if n in UNIX_ONLY]
    assert offenders == []



def test_ports_lists_the_serial_ports_with_their_descriptions():
    code = ("from bpms.io.link import describe_candidate_ports\n"
            "import serial.tools.list_ports as lp\n"
            "listed = {p.device for p in lp.comports()}\n"
            "ours = describe_candidate_ports()\n"
            "assert listed <= {d for d, _ in ours}, (listed, ours)\n"
            "from bpms.cli import main\n"
            "sys.exit(main(['ports']))\n")
    done = blocked(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() and "Traceback" not in done.stderr
