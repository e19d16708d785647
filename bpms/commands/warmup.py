"""``bpms warmup``: compile the filters for this machine now, instead of at the first use.

The attitude filters are compiled to machine code the first time they run on a computer (or
after an update of BPMS Suite or numba), which takes several seconds; the result is kept in
numba's cache, so later runs start at once. Run this after installing, e.g. before going to
the field, so that no session waits. See docs/folders.md ("The first run").
"""

from __future__ import annotations

import argparse
import os
import sys


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("warmup", help="compile the filters now (else done at their first use)")
    p.add_argument("--filter", dest="filters", action="append", metavar="NAME",
                   choices=("mahony", "observer", "adaptive", "vqf"),
                   help="only this filter (repeatable; default: every filter)")
    return p


def run(args: argparse.Namespace) -> int:
    from bpms.filter.warmup import FILTERS, ensure_kernels

    names = tuple(args.filters or FILTERS)
    # the parts compile side by side, one process per core (progress shown when it takes a while)
    seconds = ensure_kernels(names, processes=os.cpu_count() or 1)
    print(f"bpms warmup: the filters ({', '.join(names)}) are ready ({seconds:.1f} s)",
          file=sys.stderr)
    return 0
