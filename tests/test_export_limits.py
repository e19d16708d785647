"""Exports are complete or refuse (issue 43.2, 43.3):

- a recording without one frame with joint angles (its Reset Zero events lost) is refused by
  every export format and ``convert``: exit 2, one line saying why, no file left behind;
- each format at a size past its limit: C3D past 65,535 frames is read in full
  (tests/test_c3d_events_analog.py); a ``.mat`` variable past 4 GiB is refused before a byte
  is written; the text formats (.sto, .mot, CSV, BVH) and Parquet have no length limit.
"""

from __future__ import annotations

import pytest

from bpms.firmware.sim.session import simulate
from bpms.io.rawfile import new_header, write_raw
from bpms.io.session_events import SessionEvent


@pytest.fixture(scope="module")
def without_zero(tmp_path_factory):
    """A format-version-2 file that stores its session's events but holds no Reset Zero (as
    when every Reset Zero record is damaged): with the recorded events, no angles."""
    folder = tmp_path_factory.mktemp("nozero")
    rec = simulate(3.0, seed=5)
    path = folder / "Raw_nozero_001.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header(calibration=rec.calibration.values),
              events=[SessionEvent("marker", 10, 1.7e9 + 0.2, {"text": "start"})])
    return path


@pytest.mark.parametrize("argv", [["export", "opensim"], ["export", "bvh"],
                                  ["export", "matlab"], ["export", "c3d"],
                                  ["convert", "-f", "mat"]])
def test_no_usable_frame_is_refused_and_nothing_is_left(without_zero, tmp_path, argv, capsys):
    from bpms.cli import main

    out = tmp_path / "out"
    out.mkdir()
    where = ([argv[0], str(without_zero), *argv[1:]] if argv[0] == "convert"
             else [*argv, str(without_zero)])
    assert main([*where, "-o", str(out / "x")]) == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"bpms {argv[0]}: ") and "no frame with joint angles" in last
    assert "Traceback" not in err
    assert list(out.iterdir()) == []


def test_the_same_file_exports_with_the_automatic_reset_zero(without_zero, tmp_path):
    from bpms.cli import main

    assert main(["export", "matlab", str(without_zero), "-o", str(tmp_path / "x"),
                 "--reset-zero", "auto"]) == 0


def test_a_mat_variable_past_4_gib_is_refused_before_writing(tmp_path):
    from bpms.analysis.binary_out import ExportMeta, MatWriter
    from bpms.analysis.mat5_stream import ExportLimitError

    # quaternions [N, 18, 4] float32: 288 bytes a frame; 4 GiB / 288 = 14.9 million frames
    path = tmp_path / "huge.mat"
    with pytest.raises(ExportLimitError, match="less than 4 GiB"):
        MatWriter(path, ExportMeta(0.0, n_frames=15_000_000))
    assert not path.exists()
    MatWriter(tmp_path / "ok.mat", ExportMeta(0.0, n_frames=1_000)).close()  # below: fine


def test_opensim_states_the_rows_it_leaves_out_and_the_mot_keeps_them(without_zero, tmp_path,
                                                                     capsys):
    """Reset Zero only at 1.0 s: the 50 frames before it have no segment orientation."""
    import numpy as np

    from bpms.cli import main

    assert main(["export", "opensim", str(without_zero), "-o", str(tmp_path / "x"),
                 "--reset-at", "1.0"]) == 0
    assert "50 of 150 frames left out of the .sto files" in capsys.readouterr().err
    lines = (tmp_path / "x_joint_angles.mot").read_text().split("endheader\n")[1].splitlines()
    rows = np.array([[float(v) for v in ln.split("\t")] for ln in lines[1:]])
    assert rows.shape[0] == 150 and np.isnan(rows[:50, 1:]).all()
    assert np.isfinite(rows[50:, 1:]).all()
