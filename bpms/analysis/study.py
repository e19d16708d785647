"""A batch's study sheet (``bpms batch --study SHEET.csv``): which recording is which subject,
trial and condition.

The sheet is a CSV file (UTF-8, a spreadsheet's BOM allowed) with a header row:

- ``file`` (required): the recording, relative to the batch's folder (or absolute);
- ``subject``, ``trial``: optional; missing or empty cells follow the file naming rules;
- ``condition`` and any other columns: carried as text into every table of the batch
  (``batch_rom.csv``, the Parquet files, the ``.mat`` files' ``study`` struct).

Only the sheet's recordings are processed; the others found under the folder are listed in
the summary. Without a sheet, the naming rules give subject and trial
(:func:`naming_rule`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

#: Column names the batch's own tables use: a sheet may not redefine them.
RESERVED = ("joint", "min_deg", "max_deg", "range_deg", "frames", "utc_start", "convention",
            "filter", "reset_zero", "bpms_version", "source_file", "time_s", "utc")
NAMING_RULE = ("subject: the first folder level under the batch's folder ('-' for files "
               "directly in it); trial: the file name without its suffix")


class StudySheetError(ValueError):
    """The sheet cannot be used (one line: what and where)."""


@dataclass
class Study:
    """The jobs' study columns: ``rows[resolved path] = {"subject": ..., "trial": ...,
    other columns...}``; ``columns``: the other columns in sheet order; ``source``: the sheet
    (``""``: the naming rules)."""

    rows: dict[Path, dict[str, str]] = field(default_factory=dict)
    columns: list[str] = field(default_factory=list)
    source: str = ""


def naming_rule(folder: str | Path, path: str | Path) -> tuple[str, str]:
    """(subject, trial) of ``path`` found under ``folder``: :data:`NAMING_RULE`."""
    rel = Path(path).relative_to(folder)
    return (rel.parts[0] if len(rel.parts) > 1 else "-"), Path(path).stem


def read_study_sheet(sheet: str | Path, folder: str | Path) -> Study:
    """The study sheet ``sheet`` for recordings under ``folder``. Raises
    :class:`StudySheetError` for a missing file column, a duplicate or reserved column, a
    recording listed twice or not found."""
    path = Path(sheet)
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            body = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise StudySheetError(f"{path}: cannot read the study sheet ({exc})") from None
    if not header:
        raise StudySheetError(f"{path}: empty study sheet (a header row with 'file' first)")
    names = [h.strip().lower() for h in header]
    if "file" not in names:
        raise StudySheetError(f"{path}: no 'file' column (columns: {', '.join(names)})")
    dup = sorted({n for n in names if names.count(n) > 1 or not n})
    bad = [n for n in names if n in RESERVED]
    if dup or bad:
        raise StudySheetError(f"{path}: column name(s) {', '.join(dup + bad) or 'empty'} "
                              "repeated, empty or used by the batch's tables")
    study = Study(columns=[n for n in names if n not in ("file", "subject", "trial")],
                  source=str(path))
    root = Path(folder)
    missing = []
    for line, cells in enumerate(body, start=2):
        if not any(c.strip() for c in cells):
            continue
        row = dict(zip(names, (c.strip() for c in cells), strict=False))
        target = Path(row.get("file", ""))
        target = (target if target.is_absolute() else root / target).resolve()
        if not row.get("file") or not target.is_file():
            missing.append(f"line {line}: {row.get('file') or '(empty)'}")
            continue
        if target in study.rows:
            raise StudySheetError(f"{path}: line {line}: {row['file']} listed twice")
        try:
            subject, trial = naming_rule(root.resolve(), target)
        except ValueError:
            subject, trial = "-", target.stem
        study.rows[target] = {"subject": row.get("subject") or subject,
                              "trial": row.get("trial") or trial,
                              **{c: row.get(c, "") for c in study.columns}}
    if missing:
        raise StudySheetError(f"{path}: {len(missing)} recording(s) not found under "
                              f"{folder}: {'; '.join(missing[:3])}"
                              + (" ..." if len(missing) > 3 else ""))
    if not study.rows:
        raise StudySheetError(f"{path}: lists no recording")
    return study
