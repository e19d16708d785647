"""The ``bpms`` command line. Each module in :mod:`bpms.commands` adds one sub-command.

A command module defines ``register(subparsers) -> argparse.ArgumentParser`` whose parser sets
``run=callable(args) -> int``. Errors meant for the user are raised as :class:`CliError` and
printed as one line; the exit status is then 2.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys

import bpms
import bpms.commands
from bpms.commands import CliError

#: What ``bpms`` with no arguments runs.
DEFAULT_COMMAND = "gui"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bpms",
        description="BPMS Suite: Body Pose Measurement System acquisition, filtering and analysis.",
    )
    parser.add_argument("--version", action="version", version=f"bpms {bpms.__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(bpms.commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"bpms.commands.{info.name}")
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser()
    asks_help = {"-h", "--help", "--version"} & set(argv)
    if not asks_help and not [a for a in argv if not a.startswith("-")]:
        argv = [*argv, DEFAULT_COMMAND]
    args = parser.parse_args(argv)
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.run(args) or 0)
    except CliError as exc:
        print(f"bpms {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bpms {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
