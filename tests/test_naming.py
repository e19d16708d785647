"""Recording names: user name or time stamp, growing sequence, never overwrite."""

from __future__ import annotations

import re

from bpms.io.naming import RecordingNamer, safe_stem


def test_sequence_grows_and_prefixes(tmp_path):
    namer = RecordingNamer(tmp_path, "subject 01/suited")
    raw1, filt1 = namer.next_paths()
    assert raw1.name == "Raw_subject_01_suited_1.bpmsraw"
    assert filt1.name == "Filtered_subject_01_suited_1.csv"
    raw1.write_bytes(b"x")
    raw2, _ = namer.next_paths()
    assert raw2.name.endswith("_2.bpmsraw")


def test_existing_files_are_skipped(tmp_path):
    (tmp_path / "Filtered_walk_7.csv").write_text("x")
    raw, filtered = RecordingNamer(tmp_path, "walk").next_paths()
    assert raw.name == "Raw_walk_8.bpmsraw" and not filtered.exists()


def test_time_stamp_when_no_name(tmp_path):
    raw, _ = RecordingNamer(tmp_path).next_paths()
    assert re.fullmatch(r"Raw_\d{8}-\d{6}_1\.bpmsraw", raw.name)
    assert safe_stem("  ../..  ") == ""
