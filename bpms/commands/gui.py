"""``bpms gui [--sim]`` (also ``bpms`` with no arguments): the desktop app (docs/gui.md).

Without a display it says so in one line and points to the headless commands (exit 2).
"""

from __future__ import annotations

import argparse

from bpms.commands import CliError
from bpms.commands._shared import number


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("gui", help="the desktop app (start-up window, data table, plots, 3D)",
                       description=__doc__)
    p.add_argument("--sim", action="store_true",
                   help="skip the start-up window: straight to the simulated suit")
    p.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0,
                   help="simulated suit's seed (default 0)")
    p.add_argument("--calibration-posture", default="neutral", metavar="POSTURE",
                   help="simulated subject's posture in its still windows: neutral (default), "
                        "suit or 'elbow_r=15,knee_r=10' (docs/simulated-suit.md)")
    p.add_argument("--mounting-error", type=number(float, 0, 45), default=None, metavar="DEG",
                   help="simulated IMUs' mounting misalignment, ° rms per axis (default 3)")
    p.add_argument("--functional", action="store_true",
                   help="the simulated subject begins with the functional-calibration movements")
    p.add_argument("--subject", default=None, metavar="PROFILE",
                   help="the subject's profile for the live body model and the recordings' "
                        "headers: 'id=S01,height=1.80,mass=75,thigh=0.46' or a TOML file "
                        "(docs/subject.md)")
    p.add_argument("--options", metavar="options.toml", help="options file to load")
    p.add_argument("--calibration", metavar="Calib.cfg", help="calibration file to load")
    p.add_argument("--recording-dir", metavar="DIR",
                   help="folder for recordings (default: the options' logging.directory, else "
                        "the per-user recordings folder)")
    return p


def run(args: argparse.Namespace) -> int:
    from bpms.commands.sim import subject_kwargs
    from bpms.gui.app import display_problem

    # the simulated subject's options, checked before anything opens (CliError: one line)
    sim_options = {k: v for k, v in subject_kwargs(args).items() if v not in (None, {}, False)}
    if args.subject:
        from bpms.io.subject import SubjectProfile

        try:
            SubjectProfile.parse(args.subject)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    problem = display_problem()
    if problem:
        raise CliError(problem)
    try:
        from bpms.gui import app
    except ImportError as exc:
        raise CliError(f"the desktop app cannot start: {exc}") from None
    return app.run(options_path=args.options, calibration_path=args.calibration,
                   simulated=args.sim, recording_dir=args.recording_dir, seed=args.seed,
                   sim_options=sim_options, subject=args.subject)
