"""Every door uses the subject's profile (docs/subject.md, issue 47.3), against the simulated
subject's own dimensions: the live session of ``bpms record --subject`` and its MVN stream
(segment origins the subject's lengths apart, and the numbers ``bpms filter`` of the recording
gives), the BVH skeleton and the walked path (``bpms track``)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_lab_streams import decode_mvn
from waiting import receive_until_exit, wait_until

from bpms.analysis.bvh import CM_PER_M
from bpms.cli import main
from bpms.filter.body_model import POINT_NAMES
from bpms.filter.door import process_file
from bpms.firmware.sim.body import SKELETON, SubjectDimensions
from bpms.firmware.sim.motion import Still, Walk
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate
from bpms.io.rawfile import read_raw

ROOT = Path(__file__).resolve().parents[1]
TALL = SubjectDimensions.of_height(1.90)  # every length × 1.90 / 1.73


def _profile(dims: SubjectDimensions) -> str:
    return ",".join(["id=S9", f"height={dims.height}",
                     *(f"{k}={v!r}" for k, v in dims.lengths().items())])


def test_live_session_and_mvn_stream_use_the_profile(tmp_path):
    """``bpms record --sim --height 1.90 --subject ... --mvn``: the MVN segments' origins are
    the simulated subject's lengths apart (not the factory's), and ``bpms filter`` of the
    recording gives the positions the live stream sent."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    sock.bind(("127.0.0.1", 0))
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "bpms", "record", "--sim", "--height", "1.90", "--subject",
             _profile(TALL), "--mvn", f"127.0.0.1:{sock.getsockname()[1]}", "-o",
             str(tmp_path), "--name", "s", "--seconds", "2.5"],
            cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            env=os.environ.copy())
        grams = receive_until_exit(sock, proc, silence=40.0)
    finally:
        sock.close()
    assert proc.wait(30) == 0, proc.stderr.read().decode()
    poses = [decode_mvn(g) for g in grams if g[:6] == b"MXTP02"]
    poses = [p for p in poses if np.isfinite(p["pos_m"]).all()]
    assert len(poses) > 50
    last = poses[-1]
    pos = last["pos_m"]  # MVN segment origins, ids 1..23 (Pelvis first), metres
    for parent, child, length in ((8, 9, "arm"), (9, 10, "forearm"), (12, 13, "arm"),
                                  (13, 14, "forearm"), (15, 16, "thigh"), (16, 17, "shank"),
                                  (19, 20, "thigh"), (20, 21, "shank")):
        got = np.linalg.norm(pos[child] - pos[parent])
        assert got == pytest.approx(getattr(TALL, length), abs=1e-5), (child, length)
    raw = tmp_path / "Raw_s_1.bpmsraw"
    assert read_raw(raw).header["subject"]["segments_m"]["arm"] == pytest.approx(TALL.arm)
    batch = process_file(raw)
    assert "with subject S9" in batch.options_source
    ned = batch.joint_positions[last["sample"], POINT_NAMES.index("pelvis")]
    np.testing.assert_allclose(pos[0], ned * [1.0, -1.0, -1.0], atol=2e-5)  # NED → MVN z up


def _bvh_offsets(path: Path) -> dict[str, np.ndarray]:
    """JOINT name → the OFFSET of its first child (or End Site): its segment's vector, cm."""
    lines = [ln.strip() for ln in path.read_text(encoding="utf-8").splitlines()]
    lines = lines[:lines.index("MOTION")]
    out, joint = {}, None
    for k, line in enumerate(lines):
        if line.startswith("JOINT "):
            if joint is not None and joint not in out:
                out[joint] = np.array(lines[k + 2].split()[1:], dtype=float)
            joint = line.split()[1]
        elif line == "End Site" and joint not in out:
            out[joint] = np.array(lines[k + 2].split()[1:], dtype=float)
    return out


def test_bvh_skeleton_has_the_subjects_lengths(tmp_path):
    rec = simulate(seed=1, duration_s=2.0, subject=TALL)
    with_profile = rec.save_raw(tmp_path / "a.bpmsraw", subject_id="S9")
    plain = rec.save_raw(tmp_path / "b.bpmsraw")
    for raw, dims in ((with_profile, TALL), (plain, SubjectDimensions())):
        out = raw.with_suffix(".bvh")
        assert main(["export", "bvh", str(raw), "-o", str(out)]) == 0
        lengths = {k: np.linalg.norm(v) / CM_PER_M for k, v in _bvh_offsets(out).items()}
        got = sorted(round(v, 5) for v in lengths.values())
        want = {round(v, 5) for v in dims.lengths().values()}
        assert set(got) <= want and len(set(got)) >= 8, (got, want)
        assert round(dims.thigh, 5) in got and round(dims.forearm, 5) in got


def _steps(raw: Path, out: Path) -> np.ndarray:
    assert main(["track", str(raw), "-o", str(out), "--no-figure"]) == 0
    rows = out.read_text(encoding="utf-8").splitlines()[1:]
    return np.array([[float(v) for v in row.split(",")[4:6]] for row in rows])


def test_walked_path_steps_with_the_subjects_legs(tmp_path):
    """The same walk with and without the profile: the heel strikes are the same, and each
    step (ankle to ankle) is longer by the subject's scale, 1.90 / 1.73 (every length of the
    simulated subject scaled, the factory's being Table 2.4's)."""
    script = [Still("still", 2.0), Walk(steps=6), Still("still (end)", 1.0)]
    rec = simulate(seed=4, script=script, subject=TALL,
                   model=SensorModel(mounting_error_deg=0.0))
    tall = _steps(rec.save_raw(tmp_path / "a.bpmsraw", subject_id="S9"), tmp_path / "a.csv")
    plain = _steps(rec.save_raw(tmp_path / "b.bpmsraw"), tmp_path / "b.csv")
    assert len(tall) == len(plain) >= 4
    np.testing.assert_allclose(tall, plain * 1.90 / 1.73, atol=2e-4)  # 4-decimal CSV
    travel = np.linalg.norm(rec.truth.pelvis_position[-1, :2] - rec.truth.pelvis_position[0, :2])
    assert abs(np.linalg.norm(tall.sum(axis=0)) - travel) < abs(
        np.linalg.norm(plain.sum(axis=0)) - travel)


def _segment_lengths(points: np.ndarray) -> dict[str, float]:
    """Segment length (m) by the simulator's length names, from ``[21, 3]`` points."""
    index = {n: i for i, n in enumerate(POINT_NAMES)}
    return {length: float(np.linalg.norm(points[index[name]] - points[index[parent]]))
            for name, parent, _, _, length in SKELETON}


def test_3d_views_draw_the_subjects_lengths(tmp_path):
    """The samples a replay session (GUI playback, ``bpms replay``) hands the 3D views carry
    the profile's lengths, and the views draw them in every mode: the pose after Reset Zero,
    the ``v`` figure of the filter DCMs and the grey calibration pose before Reset Zero
    (these two used the factory's lengths)."""
    from bpms.filter.door import open_for_processing
    from bpms.gui.view3d_geometry import calibration_pose, pose_points
    from bpms.io.recordings import open_replay
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    raw = simulate(seed=2, duration_s=2.0, subject=TALL).save_raw(tmp_path / "r.bpmsraw",
                                                                    subject_id="S9")
    opened = open_for_processing(raw, for_replay=True)
    recording = open_replay(raw)
    session = LiveSession(ReplaySource(recording, speed=None,
                                       events=opened.replay_events(recording.events)),
                          opened.processor.options, opened.processor)
    sub = session.subscribe(maxlen=len(recording), lossless=True)
    session.start()
    try:
        assert wait_until(lambda: session.status().processed == len(recording), 30)
    finally:
        session.stop()
    sample = sub.drain()[-1]
    want = TALL.lengths()
    for points in (pose_points(sample, True), pose_points(sample, False),
                   calibration_pose(sample.body)):
        assert _segment_lengths(points) == pytest.approx(want, abs=1e-9)
    assert _segment_lengths(calibration_pose(None))["thigh"] == pytest.approx(0.43)


def test_gui_live_session_uses_the_profile(qtbot, tmp_path):
    """``bpms gui --subject`` (ModeConfig.subject) on the simulated 1.90 m subject: the live
    samples (table, plots, 3D views) have its lengths, the recordings' header stores the
    profile, and the user's options keep their own lengths; a bad profile is refused before
    any source opens."""
    from bpms.gui.layouts import LayoutStore
    from bpms.gui.main_window import MainWindow
    from bpms.gui.modes import ModeConfig, ModeError, SessionRunner
    from bpms.gui.view3d_geometry import pose_points
    from bpms.io.options import Options

    options = Options()
    runner = SessionRunner(ModeConfig(mode="sim", sim_options={"subject": TALL},
                                      subject=_profile(TALL), recording_dir=str(tmp_path)),
                           options)
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts"),
                        restore_last=False)
    qtbot.addWidget(window)
    session = runner.session
    assert session.header_extra["subject"]["id"] == "S9" and options.body.thigh == 0.43
    window.panels.status_panel.data_button.click()  # Start Data
    qtbot.waitUntil(lambda: window.model.latest is not None
                    and np.isfinite(window.model.latest.joint_positions).all(), timeout=20000)
    sample = window.model.latest
    for aligned in (True, False):
        assert _segment_lengths(pose_points(sample, aligned)) == pytest.approx(
            TALL.lengths(), abs=1e-9)
    bad = SessionRunner(ModeConfig(mode="sim", subject="height=1.8"), Options())
    with pytest.raises(ModeError, match="id is needed"):
        bad.prepare()
    assert bad.sim is None
