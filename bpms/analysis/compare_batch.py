"""``bpms batch --outputs compare``: each recording of a study against the optical file beside it
(docs/compare.md, "In a study").

Beside ``trial.bpmsraw`` the optical export is ``trial.csv`` / ``trial.tsv`` or
``trial_optical.csv`` / ``trial_optical.tsv`` (a Vicon Nexus CSV or a Qualisys TSV); a
``compare.map`` in the same folder is the map, else the default names. Per recording
``<trial>_compare.csv``, ``.md`` and ``_series.csv`` go beside its other outputs; the study's
table ``batch_compare.csv`` (one row per recording × segment) is collected afterwards.
"""

from __future__ import annotations

import csv
from pathlib import Path

from bpms.analysis.mocap_import import MocapExport, MocapFormatError

STUDY_TABLE = "batch_compare.csv"
MAP_NAME = "compare.map"
SEGMENT_COLUMNS = ("samples", "gaps", "rmse_total", "rmse_inclination", "rmse_heading",
                   "max_total", "trend_total", "pause_change")


def find_optical(raw: str | Path) -> MocapExport | None:
    """The optical export beside recording ``raw`` (see the module's text), read, or None."""
    from bpms.analysis.compare import read_optical
    from bpms.analysis.compare_map import CompareError

    raw = Path(raw)
    for stem in (raw.stem, f"{raw.stem}_optical"):
        for suffix in (".csv", ".tsv"):
            path = raw.with_name(stem + suffix)
            if path.is_file() and path != raw:
                try:
                    return read_optical(path)
                except (CompareError, MocapFormatError):
                    continue  # e.g. a filtered CSV of the same name
    return None


def compare_beside(raw: str | Path, stem: Path, options: str | None, reset_zero,
                   problems: list[str]) -> list[str]:
    """Compare ``raw`` with the optical file beside it; write ``<stem>_compare.csv``, ``.md``
    and ``_series.csv``; return the paths written. A missing optical file or one that cannot
    be compared is a line in ``problems``, not a failure of the recording."""
    from bpms.analysis.compare import CompareError, compare, load_recording
    from bpms.analysis.compare_report import markdown, write_csv, write_series_csv
    from bpms.filter.door import open_for_processing

    optical = find_optical(raw)
    if optical is None:
        problems.append(f"compare: no optical file beside {Path(raw).name}")
        return []
    mapping = Path(raw).with_name(MAP_NAME)
    try:
        opened = open_for_processing(raw, None, options, reset_zero=reset_zero)
        rec = load_recording(raw, opened)
        result = compare(rec, optical, mapping if mapping.is_file() else None,
                         recording_name=str(raw))
    except (CompareError, MocapFormatError, ValueError, OSError) as exc:
        problems.append(f"compare: {exc}".splitlines()[0])
        return []
    problems.extend(f"compare: {w}" for w in result.warnings)
    base = stem.with_name(f"{stem.name}_compare")
    written = [write_csv(base.with_suffix(".csv"), result),
               write_series_csv(base.with_name(base.name + "_series.csv"), result)]
    written.append(base.with_suffix(".md"))
    written[-1].write_text(markdown(result), encoding="utf-8")
    return [str(p) for p in written]


def write_study_table(out_dir: str | Path) -> Path | None:
    """``batch_compare.csv``: subject, trial, body, segment and the main figures of every
    ``*_compare.csv`` under ``out_dir`` (None when there is none)."""
    out_dir = Path(out_dir)
    files = sorted(out_dir.rglob("*_compare.csv"))
    if not files:
        return None
    path = out_dir / STUDY_TABLE
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["subject", "trial", "body", "segment", *SEGMENT_COLUMNS])
        for file in files:
            rows: dict[str, dict[str, str]] = {}
            with file.open(encoding="utf-8") as g:
                for row in csv.DictReader(g):
                    if row["section"] == "segment":
                        rows.setdefault(row["name"], {})[row["figure"]] = row["value"]
            subject = file.parent.name if file.parent != out_dir else "-"
            trial = file.name.removesuffix("_compare.csv")
            for name, figures in rows.items():
                body, _, segment = name.partition(" / ")
                w.writerow([subject, trial, body, segment,
                            *(figures.get(c, "") for c in SEGMENT_COLUMNS)])
    return path
