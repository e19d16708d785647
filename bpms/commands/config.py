"""``bpms config``: the options and calibration in force, where each comes from, and the
per-user folders; ``bpms config save-default --options FILE --calibration FILE`` makes files
your defaults (used by the GUI and every command when no file is given);
``bpms config forget-default`` removes them (the factory files are used again).

Precedence (docs/configuration.md): an explicit file > the recording's header > your default
> the factory files.
"""

from __future__ import annotations

import argparse

from bpms.commands import CliError


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("config", help="show the options/calibration in force; save defaults")
    p.add_argument("action", nargs="?", default="show",
                   choices=("show", "save-default", "forget-default"),
                   help="show (default), save-default or forget-default")
    p.add_argument("--options", metavar="options.toml",
                   help="show: as if given explicitly; save-default: make it the default")
    p.add_argument("--calibration", metavar="Calib.cfg",
                   help="show: as if given explicitly; save-default: make it the default")
    return p


def _show(args: argparse.Namespace) -> int:
    from bpms.io import userdirs
    from bpms.io.defaults import calibration_or_default, options_or_default

    options = options_or_default(args.options, announce=False)
    table = calibration_or_default(args.calibration, announce=False)
    opt_source = f"explicit file ({args.options})" if args.options else options.source
    cal_source = f"explicit file ({args.calibration})" if args.calibration else table.source
    if cal_source == "factory":
        cal_source = "factory (dissertation Table 2.2)"
    print(f"options:      {opt_source}")
    print(f"calibration:  {cal_source}")
    for problem in (*options.problems, *table.problems):
        print(f"  warning: {problem}")
    print(f"config folder:     {userdirs.config_dir()}")
    print(f"  default options:     {userdirs.default_options_path()}"
          f"{'' if userdirs.default_options_path().is_file() else '  (none saved)'}")
    print(f"  default calibration: {userdirs.default_calibration_path()}"
          f"{'' if userdirs.default_calibration_path().is_file() else '  (none saved)'}")
    print(f"recordings folder: {userdirs.recordings_dir()}")
    print(f"logs folder:       {userdirs.log_dir()}")
    print("precedence: explicit file > recording header > user default > factory "
          "(docs/configuration.md)")
    return 0


def _save(args: argparse.Namespace) -> int:
    from bpms.io.defaults import save_default_calibration, save_default_options

    if not args.options and not args.calibration:
        raise CliError("save-default needs --options FILE and/or --calibration FILE")
    try:
        if args.options:
            print(f"default options: {save_default_options(args.options)} "
                  f"(from {args.options})")
        if args.calibration:
            print(f"default calibration: {save_default_calibration(args.calibration)} "
                  f"(from {args.calibration})")
    except ValueError as exc:
        raise CliError(f"not saved: {exc}") from None
    except OSError as exc:
        raise CliError(f"not saved: {exc.strerror or exc}") from None
    return 0


def _forget(args: argparse.Namespace) -> int:
    from bpms.io import userdirs

    for path in (userdirs.default_options_path(), userdirs.default_calibration_path(),
                 userdirs.default_calibration_path().with_suffix(".json")):
        if path.is_file():
            path.unlink()
            print(f"removed {path}")
    return 0


def run(args: argparse.Namespace) -> int:
    return {"show": _show, "save-default": _save, "forget-default": _forget}[args.action](args)
