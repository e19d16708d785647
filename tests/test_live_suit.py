"""Live acquisition from the simulated suit over a real pseudo-terminal: recording, link loss,
the field recorder (`bpms record`) including kill -9 and a full disk."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest
from deadlines import scaled
from pty_suit import suit_pty
from waiting import wait_until

from bpms.filter.door import process_file
from bpms.firmware.sim.arbiter import Arbiter, Faults, MotionSource
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.options import Options, SerialOptions
from bpms.io.rawfile import read_raw
from bpms.pipeline.session import LiveSession
from bpms.pipeline.sources import SuitFrameSource

FRAME = 340


@pytest.fixture(scope="module")
def motion():
    return MotionSource.simulated(seed=5)


def test_record_30_s_holds_every_frame_and_replays_to_the_live_outputs(motion, tmp_path):
    # 30 s of suit data (1,500 frames), streamed as fast as the host reads them.
    arbiter = Arbiter(motion, realtime=False)
    with suit_pty(arbiter) as (_server, pty_path):
        # fast mode: thousands of frames per second, more than the default backlog bound lets
        # wait when the machine is busy (overload is tested in test_pipeline_health.py)
        session = LiveSession(SuitFrameSource(pty_path, SerialOptions()),
                              recording_dir=tmp_path, max_backlog=200_000)
        sub = session.subscribe(maxlen=200_000)
        session.source.connect()
        status = session.start_logging(raw=True, filtered=True, name="e2e")
        session.start()
        assert wait_until(lambda: arbiter.stats.motion_frames >= 1500, 30)
        session.source.stop_stream()  # Stop Data: the frames in flight still arrive
        assert wait_until(lambda: arbiter.stats.stops == 1, 5)
        assert wait_until(lambda: session.status().frames == arbiter.stats.motion_frames, 5)
        # and every frame read is filtered before the session stops (under load the filtering
        # thread runs behind the reader)
        done = wait_until(lambda: session.status().processed == arbiter.stats.motion_frames,
                          30)
        st = session.status()
        assert done, (st.frames, st.processed, st.not_filtered, arbiter.stats.motion_frames,
                      st.events)
        session.stop()
    recording = read_raw(status.raw_path)
    n = len(recording)
    assert n == arbiter.stats.motion_frames >= 1500  # every frame the suit sent
    expected = b"".join(motion.frame(j) for j in range(n))
    assert recording.frames.tobytes() == expected  # every frame, in order, stale one dropped
    live = np.array([s.euler for s in sub.drain()])
    replayed = process_file(status.raw_path)
    assert sub.dropped == 0 and len(live) == n
    np.testing.assert_array_equal(live, replayed.euler)


def test_link_loss_is_reported_and_the_stream_comes_back(motion, tmp_path):
    arbiter = Arbiter(motion, Faults(silence_at_s=2.0, silence_s=5.0))
    states = []
    with suit_pty(arbiter) as (_server, pty_path):
        serial = SerialOptions(link_lost_after_s=1.0, discovery_timeout_s=0.5)
        session = LiveSession(SuitFrameSource(pty_path, serial), recording_dir=tmp_path)
        status = session.start_logging(raw=True, filtered=False, name="loss")
        session.start()

        def state_is(wanted: str) -> bool:
            states.append(session.status().source.state)
            return states[-1] == wanted

        # Conditions with deadlines, not a fixed run time: lost (≈ 3 s in), back (≈ 7 s in),
        # then a second of frames after the return.
        assert wait_until(lambda: state_is("silent"), 30), states[-5:]
        assert wait_until(lambda: state_is("streaming"), 30), states[-5:]
        back = session.status().processed
        assert wait_until(lambda: session.status().processed >= back + 50, 30)
        session.stop()
    assert "silent" in states
    first_lost = states.index("silent")
    assert "streaming" in states[first_lost:]
    assert session.status().source.counters["links_lost"] == 1
    recording = read_raw(status.raw_path)  # one file, with a gap
    gaps = np.diff(recording.times)
    assert 4.0 < gaps.max() < 5.0 + 2.0  # back within 2 s of the suit's return
    assert (gaps[gaps < 1.0] < 0.5).all()
    # The frames before and after the gap are consecutive motion samples (the silenced ones
    # were never sent) and none is a stale repeat.
    n = len(recording)
    got = [recording.frame_bytes(k) for k in range(n)]
    bad = [k for k in range(n) if got[k] != motion.frame(k)]
    assert not bad


def bpms(*args: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "bpms", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kwargs)


def test_record_cli_survives_kill_9(tmp_path):
    proc = bpms("record", "--sim", "-o", str(tmp_path), "--name", "crash")
    raw = tmp_path / "Raw_crash_1.bpmsraw"
    # 50 kB of frame records (about 145), beside the session's events (≈ 20 kB at the start:
    # the number-changing ones are written twice)
    assert wait_until(lambda: raw.exists() and raw.stat().st_size > 70_000, 30)
    size = raw.stat().st_size
    assert wait_until(lambda: raw.stat().st_size > size, 30)  # at least one more flush
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=scaled(10))
    recording = read_raw(raw)
    assert len(recording) >= 100
    assert recording.decode().raw.shape == (len(recording), 18, 9)
    assert (np.diff(recording.times) >= 0).all()  # a burst shares one receive time


def test_record_cli_ctrl_c_closes_cleanly(tmp_path):
    proc = bpms("record", "--sim", "-o", str(tmp_path), "--name", "ctrlc", "--filtered")
    raw = tmp_path / "Raw_ctrlc_1.bpmsraw"
    out_lines: list[str] = []

    def read_stdout() -> None:
        for line in proc.stdout:
            out_lines.append(line)

    reader = threading.Thread(target=read_stdout, daemon=True)
    reader.start()
    # ≥ 120 frames flushed (348 bytes each, beside ≈ 10 kB of the session's events at the
    # start) and a status line printed, then Ctrl+C.
    assert wait_until(lambda: (raw.exists() and raw.stat().st_size > 55_000
                      and any(ln.startswith("t ") and "streaming" in ln for ln in out_lines))
                      or proc.poll() is not None, 60)
    assert proc.poll() is None
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=scaled(20))
    reader.join(timeout=10)
    out = "".join(out_lines)
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    lines = [line for line in out.splitlines() if line.startswith("t ")]
    assert lines and "Hz" in lines[-1] and "streaming" in lines[-1]
    recording = read_raw(tmp_path / "Raw_ctrlc_1.bpmsraw")
    assert recording.problems == [] and len(recording) >= 100
    assert "not filtered 0" in lines[-1] and "backlog" in lines[-1]
    filtered = read_filtered(tmp_path / "Filtered_ctrlc_1.csv")
    assert len(filtered.t) == len(recording) and not filtered.hole.any()


def test_record_cli_port_that_does_not_exist(tmp_path):
    proc = bpms("record", "/dev/does-not-exist", "-o", str(tmp_path))
    _, err = proc.communicate(timeout=scaled(30))
    assert proc.returncode == 2
    assert "cannot open /dev/does-not-exist" in err and "Traceback" not in err
    assert err.count("\n") == 1


@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("mount"), reason="needs root to "
                    "mount a tiny tmpfs")
def test_full_disk_stops_recording_and_streaming_goes_on(motion, tmp_path):
    disk = tmp_path / "small"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)]).returncode:
        pytest.skip("cannot mount a tmpfs here")
    session = None
    try:
        arbiter = Arbiter(motion, realtime=False)
        with suit_pty(arbiter) as (_server, pty_path):
            options = Options()
            options.logging.flush_interval_s = 0.05
            session = LiveSession(SuitFrameSource(pty_path), options, recording_dir=disk)
            status = session.start_logging(raw=True, filtered=False, name="full")
            session.start()
            assert wait_until(lambda: status.error is not None, 20)
            processed = session.status().processed
            assert wait_until(lambda: session.status().processed > processed + 200, 20)
            events = session.status().events
            session.stop()
        assert any("raw recording stopped" in e and "No space left" in e for e in events)
        recording = read_raw(status.raw_path)
        assert len(recording) > 100  # what was flushed before the disk filled is intact
    finally:
        # Unmount whatever happened: stop the session first (it holds files open on the
        # tmpfs), then a plain umount, else a lazy one so the mount never outlives the test.
        if session is not None:
            with contextlib.suppress(Exception):
                session.stop()
        if subprocess.run(["umount", str(disk)]).returncode:
            subprocess.run(["umount", "-l", str(disk)])
    assert not os.path.ismount(disk)
