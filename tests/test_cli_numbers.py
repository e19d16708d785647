"""Every numeric option of every command is checked to be finite and in range (issue 43.4):
``nan``, ``inf`` and values out of range give argparse's one-line error and exit 2, never a
traceback or a command that never ends (``replay --speed nan`` looped for ever, ``monitor
--seconds nan`` never stopped, ``rom --reset-at inf`` ended in a traceback, ``track
--declination nan`` exited 0 with "path nan m").

The walk covers every option of every sub-command (nested ones too): an option whose type is
the bare ``float`` or ``int`` fails the test, so a new option cannot skip the check."""

from __future__ import annotations

import argparse

import pytest

from bpms.cli import build_parser, main

pytestmark = pytest.mark.timeout(120)


def _parsers(parser: argparse.ArgumentParser, name: str = "bpms"):
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, sub in action.choices.items():
                yield from _parsers(sub, f"{name} {sub_name}")


def _numeric_options():
    out = []
    for name, parser in _parsers(build_parser()):
        for action in parser._actions:
            if action.type in (float, int) or hasattr(action.type, "bounds"):
                out.append((name, action))
    return out


OPTIONS = _numeric_options()


def test_the_walk_finds_the_numeric_options():
    found = {(name, action.option_strings[0]) for name, action in OPTIONS}
    assert {("bpms replay", "--speed"), ("bpms replay", "--from"), ("bpms rom", "--reset-at"),
            ("bpms export", "--reset-at"), ("bpms monitor", "--seconds"),
            ("bpms track", "--declination"), ("bpms record", "--seconds"),
            ("bpms batch", "--workers")} <= found
    assert len(OPTIONS) >= 30


@pytest.mark.parametrize(("command", "action"), OPTIONS,
                         ids=[f"{n.split()[-1]}{a.option_strings[0]}" for n, a in OPTIONS])
def test_every_numeric_option_refuses_non_finite_and_out_of_range(command, action):
    assert action.type not in (float, int), f"{command} {action.option_strings[0]}: a bare " \
        "float/int type: use bpms.commands._shared.number"
    kind, low, high, above = action.type.bounds
    bad = ["nan", "inf", "-inf", "NaN", "1e400", "x"]
    if low is not None:
        bad.append(str(kind(low) - 1))
        if above:
            bad.append(str(kind(low)))
    if high is not None:
        bad.append(str(kind(high) + 1))
    for text in bad:
        with pytest.raises(argparse.ArgumentTypeError):
            action.type(text)
    good = low if low is not None and not above else (low + 1 if low is not None else 0)
    if high is not None:
        good = min(good, high)
    assert action.type(str(kind(good))) == kind(good)


@pytest.mark.parametrize("argv", [
    ["replay", "REC", "--udp", "127.0.0.1:9", "--speed", "nan"],
    ["replay", "REC", "--udp", "127.0.0.1:9", "--speed", "inf"],
    ["replay", "REC", "--udp", "127.0.0.1:9", "--from", "nan"],
    ["replay", "REC", "--udp", "127.0.0.1:9", "--from", "1e308"],  # an infinite frame index
    ["filter", "REC", "--reset-zero", "at 1e308"],
    ["record", "--sim", "--start-at", "1e308"],
    ["rom", "REC", "--reset-at", "nan"],
    ["rom", "REC", "--reset-at", "inf"],
    ["export", "bvh", "REC", "--reset-at", "nan"],
    ["monitor", "--seconds", "nan"],
    ["track", "REC", "--declination", "nan"],
    ["record", "--sim", "--seconds", "-1"],
    ["batch", "DIR", "--workers", "0"],
])
def test_the_reported_option_values_give_one_error_line_and_exit_2(capsys, argv):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err  # one line, without the usage
    assert err[0].startswith(f"bpms {argv[0]}") and "error: argument" in err[0], err


def test_replay_refuses_to_start_after_the_end(tmp_path, capsys):
    from bpms.firmware.sim.session import simulate
    from bpms.io.rawfile import new_header, write_raw

    rec = simulate(1.0, seed=1)
    path = tmp_path / "r.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header(source="test"))
    assert main(["replay", str(path), "--udp", "127.0.0.1:9", "--from", "1e7"]) == 2
    assert "--from 1e+07 s: the recording lasts 1.0 s" in capsys.readouterr().err


def test_replay_refuses_a_speed_too_slow_to_end(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "none.bpmsraw"), "--udp", "127.0.0.1:9",
                 "--speed", "1e-300"]) == 2
    assert "--speed must be 0" in capsys.readouterr().err
