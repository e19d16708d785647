"""Optional parts of BPMS Suite and the pip *extra* that installs each.

A plain ``pip install bpms`` gives every command; a few features need more packages, installed
with ``pip install "bpms[EXTRA]"``. :func:`require` imports such a package or raises
:class:`MissingExtraError`, whose message is the one line the user sees (``bpms`` prints it without
a traceback, exit status 2).
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: module → (extra, what it is for). The extras are declared in pyproject.toml.
EXTRAS: dict[str, tuple[str, str]] = {
    "matplotlib": ("figures", "the PNG figures of bpms rom and bpms track"),
    "vpython": ("vpython", "the browser 3D views"),
    "pylsl": ("lsl", "Lab Streaming Layer output"),
    "pyarrow": ("parquet", "Parquet output"),
    "distributed": ("dask", "bpms batch --scheduler (a Dask cluster)"),
    "vqf": ("vqf", "the VQF filter"),
}


class MissingExtraError(ImportError):
    """An optional package is not installed; ``str()`` says which extra installs it."""

    def __init__(self, module: str, extra: str, purpose: str, hint: str = "") -> None:
        message = (f'{module} is not installed (needed for {purpose}): pip install "bpms[{extra}]"'
                   + (f", {hint}" if hint else ""))
        super().__init__(message, name=module)
        self.module = module
        self.extra = extra


def require(module: str, hint: str = "") -> ModuleType:
    """Import the optional ``module`` (a key of :data:`EXTRAS`), or raise MissingExtraError.
    ``hint``: what the user can do instead (e.g. ``"or leave them out with --no-figures"``)."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if exc.name is not None and exc.name.split(".")[0] != module.split(".")[0]:
            raise  # the package is there but broken: not a missing extra
        extra, purpose = EXTRAS[module.split(".")[0]]
        raise MissingExtraError(module, extra, purpose, hint) from None
