"""Bad inputs and outputs fail fast with one line (issue 43.4): a named pipe or a device given
as a recording, a configuration file or an output; ``--force`` replaces only a regular file;
event times checked as frame indices are; integer times in legacy pickles bounded.

Each case would block for ever, crash or destroy something on 682dd18 (a named pipe called
``x.bpmsraw`` blocked ``filter`` and ``replay``; ``filter -o /dev/null --force`` unlinked the
device; a marker at time 1e308 stopped ``replay`` at its frame for ever; a 400-digit integer
time gave an OverflowError traceback). Devices and pipes are made here, in the test's folder."""

from __future__ import annotations

import os
import pickle
import socket
import stat
import sys

import numpy as np
import pytest

from bpms.cli import main
from bpms.firmware.sim.session import simulate
from bpms.io.paths import remove_regular_file
from bpms.io.rawfile import new_header, write_raw
from bpms.io.session_events import SessionEvent

pytestmark = pytest.mark.timeout(120)
N = 100  # frames of the recordings made here (2 s)
needs_fifo = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")


@pytest.fixture(scope="module")
def sim():
    rec = simulate(N * 0.02, seed=43)
    assert len(rec.t) == N
    return rec


def _recording(path, sim, events=()):
    write_raw(path, 1.7e9 + np.arange(N) * 0.02, sim.frames,
              new_header(calibration=sim.calibration.values, source="test"), list(events))
    return path


def _char_device(path):
    """A character device node with /dev/null's numbers (1, 3), made here; skip without the
    privilege (root, as in a container or on a lab machine, where the defect did harm)."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, AttributeError, OSError) as exc:
        pytest.skip(f"cannot make a device node here ({exc})")
    return path


def _one_error_line(capsys, command):
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith(f"bpms {command}: "), err
    assert "Traceback" not in "\n".join(err)
    return err[-1]


@needs_fifo
@pytest.mark.parametrize("argv", [["filter"], ["replay", "--udp", "127.0.0.1:9"], ["rom"],
                                  ["convert"], ["extract", "raw", "--imu", "all"]])
def test_a_named_pipe_is_refused_as_a_recording(tmp_path, capsys, argv):
    """The open would wait for a writer for ever: refused before it."""
    fifo = tmp_path / "x.bpmsraw"
    os.mkfifo(fifo)
    command, *rest = argv
    if command == "extract":
        rest = ["raw", str(fifo), "--imu", "all", "-o", str(tmp_path / "x.csv")]
    else:
        rest = [str(fifo), *rest] + (["-o", str(tmp_path / "o")] if command != "replay" else [])
    assert main([command, *rest]) == 2
    assert "a named pipe, not a file" in _one_error_line(capsys, command)


@needs_fifo
def test_a_named_pipe_as_options_or_calibration_is_a_warning(tmp_path, sim, capsys):
    rec = _recording(tmp_path / "r.bpmsraw", sim)
    fifo = tmp_path / "options.toml"
    os.mkfifo(fifo)
    for flag in ("--options", "--calibration"):
        assert main(["filter", str(rec), "-o", str(tmp_path / "f.csv"), "--force", flag,
                     str(fifo)]) == 0
        err = capsys.readouterr().err
        assert "cannot be read (a named pipe, not a file)" in err and "warning" in err


def test_force_never_replaces_a_device(tmp_path, sim, capsys):
    rec = _recording(tmp_path / "r.bpmsraw", sim)
    device = _char_device(tmp_path / "null")
    for argv in (["filter", str(rec), "-o", str(device), "--force"],
                 ["extract", "raw", str(rec), "--imu", "all", "-o", str(device), "--force"]):
        assert main(argv) == 2
        assert "is a device, not a file" in _one_error_line(capsys, argv[0])
        assert stat.S_ISCHR(os.stat(device).st_mode)  # still the device node
        assert os.stat(device).st_rdev == os.makedev(1, 3)


@needs_fifo
def test_force_never_replaces_a_named_pipe_or_a_folder(tmp_path, sim, capsys):
    rec = _recording(tmp_path / "r.bpmsraw", sim)
    fifo = tmp_path / "out.csv"
    os.mkfifo(fifo)
    folder = tmp_path / "folder.csv"
    folder.mkdir()
    (folder / "keep").write_text("kept")
    for target, kind in ((fifo, "a named pipe"), (folder, "a folder")):
        assert main(["filter", str(rec), "-o", str(target), "--force"]) == 2
        assert f"is {kind}, not a file" in _one_error_line(capsys, "filter")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert (folder / "keep").read_text() == "kept"


def test_force_replaces_a_regular_file(tmp_path, sim, capsys):
    rec = _recording(tmp_path / "r.bpmsraw", sim)
    out = tmp_path / "f.csv"
    out.write_text("old")
    assert main(["filter", str(rec), "-o", str(out)]) == 2  # without --force: refused
    assert out.read_text() == "old"
    assert main(["filter", str(rec), "-o", str(out), "--force"]) == 0
    assert out.read_text().startswith("# ")


def test_remove_regular_file_leaves_anything_else(tmp_path):
    folder = tmp_path / "d"
    folder.mkdir()
    with pytest.raises(OSError, match="a folder, not a file"):
        remove_regular_file(folder)
    assert folder.is_dir()
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "p")
        with pytest.raises(OSError, match="a named pipe"):
            remove_regular_file(tmp_path / "p")
        assert stat.S_ISFIFO(os.stat(tmp_path / "p").st_mode)
    remove_regular_file(tmp_path / "missing")  # nothing there: fine
    (tmp_path / "f").write_text("x")
    remove_regular_file(tmp_path / "f")
    assert not (tmp_path / "f").exists()


def _replay_raw_datagrams(path) -> tuple[int, int]:
    """``bpms replay PATH --speed 0`` to a socket here: (exit code, RAW_FRAME datagrams)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
    sock.bind(("127.0.0.1", 0))
    try:
        host, port = sock.getsockname()
        code = main(["replay", str(path), "--speed", "0", "--udp", f"{host}:{port}"])
        sock.settimeout(0.0)
        raw = 0
        while True:
            try:
                g = sock.recv(65535)
            except (BlockingIOError, TimeoutError):
                break
            raw += len(g) > 5 and g[5] == 1
        return code, raw
    finally:
        sock.close()


@pytest.mark.parametrize("when", [1e308, -1e300, 2.0 ** 40])
def test_an_event_at_an_absurd_time_does_not_stop_replay(tmp_path, sim, when):
    """A marker whose time no clock gives (valid CRC): replay sends every frame and ends."""
    rec = _recording(tmp_path / "r.bpmsraw", sim,
                     [SessionEvent("marker", 40, when, {"text": "far"}),
                      SessionEvent("note", 60, when, {"text": "also"})])
    assert _replay_raw_datagrams(rec) == (0, N)


def _legacy(path, records: list, protocol: int = 0):
    path.write_bytes(b"".join(pickle.dumps(r, protocol=protocol) for r in records))
    return path


@pytest.mark.parametrize("protocol", [0, 2])
def test_a_400_digit_integer_time_is_a_bad_record(tmp_path, sim, capsys, protocol):
    from bpms.filter.door import process_file
    from bpms.io.rawfile import RawFileError

    frames = [bytes(sim.frames[k * 340:(k + 1) * 340]) for k in range(20)]
    only_huge = _legacy(tmp_path / "huge.txt", [[10 ** 400, f.decode("latin1")] for f in frames],
                        protocol)
    for argv in (["filter", str(only_huge), "-o", str(tmp_path / "f.csv")],
                 ["rom", str(only_huge), "-o", str(tmp_path / "rom"), "--no-figures"],
                 ["export", "bvh", str(only_huge), "-o", str(tmp_path / "b")],
                 ["replay", str(only_huge), "--udp", "127.0.0.1:9"],
                 ["convert", str(only_huge), "-o", str(tmp_path / "cv")]):
        assert main(argv) == 2, argv
        assert "no readable frame" in _one_error_line(capsys, argv[0])
    with pytest.raises(RawFileError, match="not a time"):
        process_file(only_huge)
    mixed = _legacy(tmp_path / "mixed.txt", [[10 ** 400, frames[0].decode("latin1")]]
                    + [[1.7e9 + 0.02 * k, f.decode("latin1")] for k, f in enumerate(frames)],
                    protocol)
    assert main(["filter", str(mixed), "-o", str(tmp_path / "m.csv"), "--force"]) == 0
    err = capsys.readouterr().err
    assert ": 20 frames filtered" in err and "integer of 1329 bits, not a time" in err


@pytest.mark.skipif(sys.platform == "win32", reason="no named pipes")
def test_the_regular_file_check_names_the_kind(tmp_path):
    from bpms.io.paths import special_kind

    os.mkfifo(tmp_path / "p")
    assert special_kind(tmp_path / "p") == "a named pipe"
    assert special_kind(tmp_path) is None and special_kind(tmp_path / "none") is None
    (tmp_path / "f").write_text("")
    assert special_kind(tmp_path / "f") is None


@pytest.mark.parametrize(("center", "why"), [
    ((1e300, 0.0, 0.0), "centre x 1e+300 is outside the sensor's readings"),
    ((0.0, 5000.0, 0.0), "centre y 5000 is outside the sensor's readings"),
    ((0.0, 0.0, None), "centre z"),  # inside the readings, outside the IMU's MzMin … MzMax
])
def test_an_implausible_ellipsoid_is_dropped_with_a_warning_naming_the_imu(
        tmp_path, sim, capsys, center, why):
    """Calib.json beside Calib.cfg: the IMU's min/max calibration is used instead, with one
    warning naming the IMU (a centre of 1e300 turned IMU 0 to NaN without a warning)."""
    from bpms.io.calib_file import save_legacy
    from bpms.io.calib_modern import ModernCalibration, modern_path, save_modern
    from bpms.io.filtered_file.reader import read_filtered
    from bpms.io.mag_ellipsoid import MagEllipsoid

    table = sim.calibration
    legacy = tmp_path / "Calib.cfg"
    save_legacy(table, legacy)
    imu = 2
    mm = table.mag_min_max[imu]
    c = mm.mean(axis=-1)
    c = np.array([c[k] if v is None and k < 2 else (mm[2, 1] + 50 if v is None else v)
                  for k, v in enumerate(center)])
    matrix = np.diag(200.0 / (mm[:, 1] - mm[:, 0]))
    save_modern(ModernCalibration(table, {imu: MagEllipsoid(c, matrix)}), modern_path(legacy))
    rec = _recording(tmp_path / "r.bpmsraw", sim)
    out = tmp_path / "f.csv"
    assert main(["filter", str(rec), "-o", str(out), "--calibration", str(legacy)]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and f"IMU {imu} ellipsoid" in warnings[0], "\n".join(warnings)
    assert why in warnings[0] and "min/max magnetometer calibration used" in warnings[0]
    angles = read_filtered(out)
    assert np.isfinite(angles.euler).all()
    reference = tmp_path / "plain.csv"  # the same Calib.cfg without a companion
    modern_path(legacy).unlink()
    assert main(["filter", str(rec), "-o", str(reference), "--calibration", str(legacy)]) == 0
    np.testing.assert_array_equal(angles.euler, read_filtered(reference).euler)


@needs_fifo
def test_a_named_pipe_is_refused_as_a_motion_capture_export(tmp_path):
    from bpms.analysis.mocap_import import MocapFormatError, read_qualisys, read_vicon

    fifo = tmp_path / "trial.csv"
    os.mkfifo(fifo)
    for reader in (read_vicon, read_qualisys):
        with pytest.raises(MocapFormatError, match="a named pipe, not a file"):
            reader(fifo)


def test_replay_ends_when_frames_fail_to_process(tmp_path, sim, capsys, monkeypatch):
    """A processing error used to leave replay waiting for ever for the frames it lost: it
    ends, says how many were not processed, and exits 1."""
    from bpms.commands import replay
    from bpms.filter.processor import BodyPoseProcessor

    rec = _recording(tmp_path / "r.bpmsraw", sim)
    real = BodyPoseProcessor.step_wire
    calls = []

    def failing(self, wire, *args, **kwargs):
        if len(wire) > 340:  # a batch of the replay, not the warm-up's single frames
            calls.append(1)
            if len(calls) == 1:  # the first batch of frames fails
                raise RuntimeError("planted processing error")
        return real(self, wire, *args, **kwargs)

    monkeypatch.setattr(BodyPoseProcessor, "step_wire", failing)
    monkeypatch.setattr(replay, "STALL_S", 0.5)
    code = main(["replay", str(rec), "--speed", "1000", "--udp", "127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "frames were not processed" in err and "planted processing error" in err


def test_calibrate_and_batch_never_replace_a_device(tmp_path, sim, capsys):
    """The calibration tool saved over /dev/null (an atomic rename onto the device node);
    batch given a device for its folder ended in a traceback."""
    device = _char_device(tmp_path / "null")
    assert main(["calibrate", "--sim", "--sim-speed", "0", "--sensor", "gyro",
                 "--gyro-samples", "20", "--yes", "-o", str(device)]) == 2
    assert "is a device, not a file" in _one_error_line(capsys, "calibrate")
    folder = tmp_path / "recordings"
    folder.mkdir()
    _recording(folder / "r.bpmsraw", sim)
    assert main(["batch", str(folder), "-o", str(device), "--workers", "1"]) == 2
    assert "is not a folder" in _one_error_line(capsys, "batch")
    assert stat.S_ISCHR(os.stat(device).st_mode)
    assert not (tmp_path / "null.json").exists()
