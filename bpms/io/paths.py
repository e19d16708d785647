"""Where the shipped (factory) calibration and option files live."""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parents[1]


def factory_dir() -> Path:
    """The shipped ``calib/`` folder: inside an installed wheel, or at the top of a checkout."""
    for candidate in (_PACKAGE_DIR / "calib", _PACKAGE_DIR.parent / "calib"):
        if (candidate / "Calib.cfg").is_file():
            return candidate
    raise FileNotFoundError("the shipped calib/ folder is missing from this installation")


def factory_calibration_path() -> Path:
    """The prototype's calibration (dissertation Table 2.2) in the legacy ``Calib.cfg`` format."""
    return factory_dir() / "Calib.cfg"


def factory_options_path() -> Path:
    """The factory options file."""
    return factory_dir() / "options.toml"
