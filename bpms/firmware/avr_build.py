"""Building the suit's AVR images and the simulator host that runs them (``make avr-suit``).

:func:`build` runs ``make`` in ``bpms/firmware`` (the Makefile knows what is out of date, so a
second call costs a fraction of a second) and returns the paths of the two images and of the
``avr_suit`` program (``bpms/firmware/avr_host``). The products go below
:func:`build_dir`: ``bpms/firmware/build`` in a source checkout (ignored by git), else the
per-user cache folder. Missing tools give :class:`AvrBuildError` with a one-line message that
names the Debian packages (``tools/dev.sh setup`` installs them).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

FIRMWARE_DIR = Path(__file__).resolve().parent
ARDUINO_CORE = Path("/usr/share/arduino/hardware/arduino/avr/cores/arduino")
#: Tool → Debian package that provides it.
TOOLS = {"make": "make", "gcc": "gcc", "avr-gcc": "gcc-avr", "avr-g++": "gcc-avr",
         "avr-gcc-ar": "gcc-avr", "avr-objcopy": "binutils-avr"}


class AvrBuildError(RuntimeError):
    """The images or the simulator cannot be built here (one-line reason)."""


@dataclass(frozen=True)
class AvrBuild:
    """Paths of what ``make avr-suit`` built."""

    arbiter_hex: Path
    cluster_hex: Path
    host: Path  # the avr_suit program


def build_dir() -> Path:
    """Where the firmware is built: ``bpms/firmware/build`` when the package folder can be
    written (a source checkout), else ``<user cache>/bpms/firmware-build``."""
    if os.access(FIRMWARE_DIR, os.W_OK):
        return FIRMWARE_DIR / "build"
    import platformdirs

    return Path(platformdirs.user_cache_dir("bpms", appauthor=False)) / "firmware-build"


def missing_tools() -> list[str]:
    """Debian packages whose tools are missing (empty when the build can run)."""
    missing = {pkg for tool, pkg in TOOLS.items() if shutil.which(tool) is None}
    if not ARDUINO_CORE.is_dir():
        missing.add("arduino-core-avr")
    if shutil.which("gcc") is not None:
        lib = subprocess.run(["gcc", "-print-file-name=libsimavr.a"], capture_output=True,
                             text=True, check=False).stdout.strip()
        if not Path(lib).is_absolute():
            missing.add("libsimavr-dev")
    return sorted(missing)


@contextlib.contextmanager
def build_lock(folder: Path, timeout_s: float) -> Iterator[None]:
    """Hold ``folder/.make.lock`` (so that parallel processes never build into the same
    folder at once)."""
    import fcntl  # the simulator host builds on Linux and macOS only

    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".make.lock", "w") as lock:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise AvrBuildError(f"another process held {folder}/.make.lock for "
                                        f"{timeout_s:g} s") from None
                time.sleep(0.2)
        yield


def build(timeout_s: float = 600.0) -> AvrBuild:
    """Build (or bring up to date) both AVR images and the simulator host."""
    if sys.platform == "win32":
        raise AvrBuildError("the AVR simulator (simavr) runs on Linux and macOS, not Windows")
    missing = missing_tools()
    if missing:
        raise AvrBuildError("cannot build the AVR suit: missing " + ", ".join(missing)
                            + " (tools/dev.sh setup installs them on Debian)")
    out = build_dir()
    with build_lock(out, timeout_s):
        try:
            result = subprocess.run(
                ["make", "--no-print-directory", "-C", str(FIRMWARE_DIR), f"BUILD={out}",
                 "-j2", "avr-suit"], capture_output=True, text=True, timeout=timeout_s,
                check=False)
        except subprocess.TimeoutExpired:
            raise AvrBuildError(f"make avr-suit took longer than {timeout_s:g} s") from None
    if result.returncode != 0:
        lines = [line for line in (result.stderr or result.stdout).splitlines() if line.strip()]
        raise AvrBuildError("make avr-suit failed: " + (lines[-1] if lines else "no output"))
    return AvrBuild(out / "avr" / "arbiter.hex", out / "avr" / "cluster.hex",
                    out / "sim" / "avr_suit")
