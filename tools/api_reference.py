"""Build the API reference of BPMS Suite's Python API from its docstrings (pdoc, HTML).

    .venv/bin/python tools/api_reference.py            # → build/api/index.html
    .venv/bin/python tools/api_reference.py -o DIR

What it covers: the headless API a script uses (``bpms.io``, ``bpms.filter``,
``bpms.pipeline``, ``bpms.analysis``, ``bpms.calibration``, the simulated suit
``bpms.firmware.sim`` and the small top-level helpers). The command line is documented by
``bpms COMMAND --help`` and docs/, the desktop app by docs/gui.md, so ``bpms.commands`` and
``bpms.gui`` are left out. ``bpms.filter`` itself is a package of lazy re-exports (its
``__getattr__`` keeps numba out of light imports), which pdoc cannot resolve: its entry points
are documented in their own modules (``bpms.filter.processor`` and the others).

A pdoc warning (a docstring it cannot render, a name it cannot resolve) is an error: the test
command builds the reference (tests/test_api_reference.py) and fails on any.
"""

from __future__ import annotations

import argparse
import pkgutil
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: Packages documented with every module under them (pdoc walks them).
PACKAGES = ("bpms.io", "bpms.pipeline", "bpms.analysis", "bpms.calibration",
            "bpms.firmware.sim")
MODULES = ("bpms.progress", "bpms.extras", "bpms.docs_location")
#: Packages documented module by module, without their own page (see the module docstring).
UNPACKED = ("bpms.filter",)


def modules() -> list[str]:
    """The module specifications given to pdoc."""
    import importlib

    names = [*MODULES, *PACKAGES]
    for name in UNPACKED:
        package = importlib.import_module(name)
        names += sorted(info.name for info in pkgutil.iter_modules(package.__path__,
                                                                   name + "."))
    return names


def build(output: Path) -> list[str]:
    """Write the HTML into ``output``; returns the modules documented. Raises on a warning."""
    import pdoc
    import pdoc.render

    pdoc.render.configure(docformat="restructuredtext", search=False, show_source=False,
                          footer_text="BPMS Suite")
    names = modules()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pdoc.pdoc(*names, output_directory=output)
    return names


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "build" / "api",
                        help="output folder (default build/api)")
    args = parser.parse_args(argv)
    try:
        names = build(args.output)
    except Warning as exc:
        print(f"api_reference: pdoc warned: {exc}", file=sys.stderr)
        return 1
    pages = len(list(args.output.rglob("*.html"))) - 1
    print(f"{pages} module pages ({len(names)} specifications) → {args.output / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
