"""The ``bpms`` command line. Each module in :mod:`bpms.commands` adds one sub-command.

A command module defines ``register(subparsers) -> argparse.ArgumentParser`` (its options)
and ``run(args) -> int`` (what it does; set as the parser's default ``run``); a parser given no
description shows the module's docstring, line breaks kept. Errors meant for the user are
raised as :class:`CliError` and printed as one line; the exit status is then 2.

Command modules are found by name without importing them; only the command asked for is
imported (all of them only for ``bpms --help``), and a module's ``register`` imports nothing
heavy, so that every command starts quickly and imports only what it uses.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import re
import sys

import bpms
import bpms.commands
from bpms.commands import CliError

#: What ``bpms`` with no arguments runs.
DEFAULT_COMMAND = "gui"

#: Commands that also keep a rotating log file in the per-user log folder.
LOGGED_COMMANDS = frozenset({"gui", "record"})

_ROLE = re.compile(r":[a-z]+(?::[a-z]+)?:`~?([^`]+)`")  # :func:`x`, :py:mod:`~a.b`
_LITERAL = re.compile(r"``(.+?)``|`([^`\n]+)`", re.S)  # a double-backtick span may wrap


def command_names() -> list[str]:
    """The sub-commands: every public module of :mod:`bpms.commands`, sorted (not imported)."""
    return sorted(info.name for info in pkgutil.iter_modules(bpms.commands.__path__)
                  if not info.name.startswith("_"))


def command_summary(name: str) -> str | None:
    """The one-line ``help=`` that command ``name``'s ``register`` gives ``add_parser``, read
    from the module's source without importing it; None when it is not a plain string."""
    import ast
    import importlib.util

    spec = importlib.util.find_spec(f"bpms.commands.{name}")
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return None
    try:
        with open(spec.origin, encoding="utf-8") as f:
            tree = ast.parse(f.read(), spec.origin)
    except (OSError, SyntaxError, ValueError):
        return None
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "add_parser" and node.args
                and isinstance(node.args[0], ast.Constant) and node.args[0].value == name):
            for kw in node.keywords:
                if kw.arg == "help":  # a string literal, not an f-string, a name, a call
                    value = kw.value.value if isinstance(kw.value, ast.Constant) else None
                    return value if isinstance(value, str) else None
    return None


def plain_text(text: str | None) -> str | None:
    """Help text without reStructuredText markup (the module docstrings the commands show):
    ``:func:`a.b``` → ``a.b``, double and single backticks dropped."""
    if not text:
        return text
    text = _ROLE.sub(lambda m: m.group(1), text)
    return _LITERAL.sub(lambda m: m.group(1) or m.group(2), text)


def _plain_help(parser: argparse.ArgumentParser) -> None:
    """:func:`plain_text` for a parser's description, epilog, every option's help and the
    same for its sub-commands (``bpms config show``, ``bpms extract raw`` ...)."""
    parser.description = plain_text(parser.description)
    parser.epilog = plain_text(parser.epilog)
    for action in parser._actions:
        if isinstance(action.help, str):
            action.help = plain_text(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = plain_text(choice.help)
            for sub in action.choices.values():
                _plain_help(sub)


class _VersionAction(argparse.Action):
    """``bpms --version``: ``bpms 0.2.0``, from a git checkout ``bpms 0.2.0 (commit …)``
    (:func:`bpms.analysis.stamp.bpms_version`, asked only when the option is given)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from bpms.analysis.stamp import bpms_version

        print(f"bpms {bpms_version()}")
        parser.exit()


class _Parser(argparse.ArgumentParser):
    """argparse's parser, except that a bad option value is one line (``bpms replay: error:
    argument --speed: 'nan' is not a finite number``), without the usage before it: the
    usage says nothing about the value (issue 43.4). Other errors (a missing argument) keep
    the usage."""

    def error(self, message: str):
        if message.startswith("argument "):
            self.exit(2, f"{self.prog}: error: {message}\n")
        super().error(message)


def build_parser(only: str | None = None, *, overview: bool = False) -> argparse.ArgumentParser:
    """The argument parser with every sub-command, or only the command ``only``.

    ``overview``: for ``bpms --help``, list the commands with the help line their modules'
    source gives, without importing them (a module whose line cannot be read is imported)."""
    from bpms.docs_location import docs_hint

    parser = _Parser(
        prog="bpms",
        description="BPMS Suite: Body Pose Measurement System acquisition, filtering and analysis.",
        epilog=f"'bpms COMMAND --help' explains a command.\n{docs_hint()}",
        formatter_class=argparse.RawDescriptionHelpFormatter,  # the path stays on one line
    )
    parser.add_argument("--version", action=_VersionAction, nargs=0,
                        help="show the version (with the commit when run from a git checkout)")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in command_names() if only is None else [only]:
        summary = command_summary(name) if overview else None
        if summary is not None:
            sub.add_parser(name, help=summary)
            continue
        module = importlib.import_module(f"bpms.commands.{name}")
        command = module.register(sub)
        command.set_defaults(run=module.run)
        if command.description is None:
            command.description = module.__doc__
            command.formatter_class = argparse.RawDescriptionHelpFormatter
        if command.epilog is None:
            command.epilog = docs_hint()  # the pages that help texts name are there
    _plain_help(parser)  # the docstrings' markup is for the API reference
    return parser


def _command_in(argv: list[str]) -> str | None:
    """The sub-command named in ``argv`` (the first word that is not an option), if any."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    asks_help = {"-h", "--help", "--version"} & set(argv)
    command = _command_in(argv)
    if command is None and not asks_help:
        argv = [*argv, DEFAULT_COMMAND]
        command = DEFAULT_COMMAND
    known = command in command_names()
    # Only the command asked for is imported; the overview of all of them imports none.
    parser = build_parser(command if known else None, overview=not known)
    args = parser.parse_args(argv)
    if getattr(args, "run", None) is None:  # e.g. only -v given to a bare parser
        parser.print_help()
        return 2
    from bpms.logsetup import configure_logging

    configure_logging(args.verbose, args.command,
                      to_file=getattr(args, "log_file", args.command in LOGGED_COMMANDS))
    try:
        return int(args.run(args) or 0)
    except (CliError, ImportError) as exc:
        from bpms.extras import MissingExtraError

        if not isinstance(exc, (CliError, MissingExtraError)):
            raise  # not a missing extra: a bug, with its traceback
        print(f"bpms {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bpms {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
