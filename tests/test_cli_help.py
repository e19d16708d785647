"""Every ``--help`` is plain text: no reStructuredText markup from the docstrings."""

from __future__ import annotations

import contextlib
import io
import re

import pytest

from bpms.cli import command_names, main

MARKUP = re.compile(r"``|:(?:func|mod|class|meth|attr|data):|`[^`\s]")


def _help(*argv: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as done:
        main([*argv, "--help"])
    assert done.value.code == 0
    return out.getvalue()


@pytest.mark.parametrize("command", [None, *command_names()])
def test_help_has_no_markup(command):
    text = _help(*([command] if command else []))
    assert not MARKUP.search(text), MARKUP.search(text).group(0)
    if command:
        assert text.startswith("usage: bpms " + command)


@pytest.mark.parametrize(("command", "sub"), [("config", "show"), ("extract", "raw")])
def test_sub_command_help_has_no_markup(command, sub):
    assert not MARKUP.search(_help(command, sub))


def test_plain_text_keeps_the_words():
    from bpms.cli import plain_text

    assert plain_text("``bpms x``: see :func:`bpms.a.b` and :mod:`~bpms.c.d`, `e`") == (
        "bpms x: see bpms.a.b and bpms.c.d, e")
