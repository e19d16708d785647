"""Sub-commands of ``bpms``: one module each, found automatically by :mod:`bpms.cli`."""


class CliError(Exception):
    """A problem the user can fix (bad path, no suit, bad argument): shown as one line."""
