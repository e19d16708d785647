"""``bpms calibrate`` against the simulated suit in-process."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bpms.cli import main
from bpms.firmware.sim.calibration_poses import changed_table
from bpms.io.calib_file import load_calibration, load_factory_calibration, save_legacy
from bpms.io.calib_modern import load_modern, modern_path

FAST = ["--sim", "--sim-speed", "0", "--yes", "--gyro-samples", "200",
        "--accel-samples", "100"]


def test_calibrate_one_imu_merges_into_the_existing_file(tmp_path, capsys):
    out = tmp_path / "Calib.cfg"
    existing = load_factory_calibration()
    existing.values[0, 13] = 123.0  # something of our own on another IMU
    save_legacy(existing, out)
    rc = main(["calibrate", *FAST, "--imu", "7", "--sweep-s", "60", "--ellipsoid",
               "--sim-move-gyro", "-o", str(out)])
    text = capsys.readouterr().out
    assert rc == 0
    assert "REFUSED: the suit moved" in text and "GYRO (attempt 2)" in text
    assert "SUMMARY (old vs new)" in text and "sphere residual" in text
    new = load_calibration(out)
    assert new.problems == []
    truth = changed_table()
    others = [i for i in range(18) if i != 7]
    assert np.array_equal(new.values[others], existing.values[others])
    gravity = truth.values[7, 0]
    assert abs(new.values[7, 0] - gravity) < 0.01 * gravity
    assert np.abs(new.values[7, 13:16] - truth.values[7, 13:16]).max() < 2.0
    modern = load_modern(modern_path(out))
    assert modern.problems == [] and 7 in modern.ellipsoids
    assert np.array_equal(modern.table.values, new.values)
    assert set(modern.provenance[7]) >= {"gyro", "accel", "mag", "quality"}


def test_calibrate_only_the_gyro(tmp_path, capsys):
    out = tmp_path / "sub" / "Calib.cfg"
    assert main(["calibrate", *FAST, "--imu", "2,3", "--sensor", "gyro", "-o", str(out)]) == 0
    new, factory = load_calibration(out), load_factory_calibration()
    assert np.array_equal(new.values[:, :13], factory.values[:, :13])
    assert not np.array_equal(new.values[2, 13:], factory.values[2, 13:])
    assert not np.array_equal(new.values[3, 13:], factory.values[3, 13:])
    text = capsys.readouterr().out
    assert "GYRO" in text and ": pose +z" not in text and "MAG:" not in text


def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys):
    for args, words in ((["--imu", "3,40"], "IMU ids run from 0 to 17"),
                        (["--sensor", "baro"], "unknown sensor 'baro'"),
                        (["--sweep-s", "0"], "argument --sweep-s: 0: must be more than 0"),
                        (["--existing", str(tmp_path / "nope.cfg")], "no such file")):
        try:
            rc = main(["calibrate", "--sim", *args, "-o", str(tmp_path / "C.cfg")])
        except SystemExit as stop:  # an option's value: argparse's one line (issue 43.4)
            rc = stop.code
        err = capsys.readouterr().err.strip()
        assert rc == 2 and words in err and len(err.splitlines()) == 1
    assert not (tmp_path / "C.cfg").exists()


def test_unwritable_output_keeps_the_calibration(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    rc = main(["calibrate", *FAST, "--imu", "1", "--sensor", "gyro",
               "-o", str(blocker / "Calib.cfg")])  # a file where a folder should be
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "saved to" in err
    saved = err.rsplit("saved to ", 1)[1].split(" instead")[0]
    new = load_calibration(saved)
    for path in (Path(saved), modern_path(saved)):
        path.unlink()
    assert new.problems == [] and not np.array_equal(
        new.values[1, 13:], load_factory_calibration().values[1, 13:])
