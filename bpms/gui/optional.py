"""Optional GUI parts (3D views, the browser view, the calibration wizard) load lazily and
say why when they cannot."""

from __future__ import annotations

import importlib


def optional_module(name: str) -> tuple[object | None, str]:
    """Import ``name`` lazily: (module, "") or (None, why it is unavailable)."""
    try:
        return importlib.import_module(name), ""
    except Exception as exc:
        return None, f"{name} is not available ({type(exc).__name__}: {exc})"
