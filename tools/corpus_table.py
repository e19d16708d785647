"""The closing table of the hostile-input corpus (issue 43): per damage class, the files and
doors run, and the runs that went wrong, by what went wrong. Used by tools/hostile_corpus.py
and bench/hostile_input.py."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Row:
    """One line of the closing table: a damage class's files, the doors run on them and what
    went wrong."""

    files: set[str] = field(default_factory=set)
    doors: set[str] = field(default_factory=set)
    runs: int = 0
    tracebacks: int = 0
    hangs: int = 0
    exit0_missing: int = 0
    frames_wrong: int = 0
    other: int = 0


def classify(verdict) -> str | None:
    """What went wrong in ``verdict`` for the table: ``traceback``, ``hang``, ``exit0_missing``
    (exit 0 without the output asked for, or without the frames it had), ``frames_wrong``
    (frames lost, or slots added, beyond the damaged ones), ``other``; None when correct."""
    if verdict.ok:
        return None
    if verdict.traceback:
        return "tracebacks"
    if verdict.outcome.hang:
        return "hangs"
    text = "; ".join(verdict.problems)
    if "exit 0 without" in text or (verdict.outcome.code == 0 and (
            "no frame count" in text or "not reported skipped" in text)):
        return "exit0_missing"
    if "expected" in text and ("frames" in text or "datagrams" in text or "rows" in text) \
            and not text.startswith("exit "):
        return "frames_wrong"
    return "other"


def table(verdicts: list) -> str:
    """The closing table (issue 43): per damage class, files × doors, runs, and the runs with
    a traceback, a hang, exit 0 with missing output, frames lost or added beyond the damaged
    ones, anything else wrong."""
    rows: dict[str, Row] = {}
    for v in verdicts:
        row = rows.setdefault(v.case.damage, Row())
        row.files.add(v.case.name)
        row.doors.add(v.command)
        row.runs += 1
        what = classify(v)
        if what is not None:
            setattr(row, what, getattr(row, what) + 1)
    lines = ["| damage | files × doors | runs | tracebacks | hangs | exit 0, output missing | "
             "frames lost or added | other |", "|---|---|---|---|---|---|---|---|"]
    total = Row()
    for name, r in sorted(rows.items()):
        lines.append(f"| {name} | {len(r.files)} × {len(r.doors)} | {r.runs} | {r.tracebacks} | "
                     f"{r.hangs} | {r.exit0_missing} | {r.frames_wrong} | {r.other} |")
        total.files |= {f"{name}/{f}" for f in r.files}
        total.doors |= r.doors
        for key in ("runs", "tracebacks", "hangs", "exit0_missing", "frames_wrong", "other"):
            setattr(total, key, getattr(total, key) + getattr(r, key))
    lines.append(f"| **all** | {len(total.files)} × {len(total.doors)} | {total.runs} | "
                 f"{total.tracebacks} | {total.hangs} | {total.exit0_missing} | "
                 f"{total.frames_wrong} | {total.other} |")
    return "\n".join(lines)
