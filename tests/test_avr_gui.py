"""The desktop app against the suit's firmware in the AVR simulator (pytest-qt, offscreen):
the start-up window in suit mode on the simulator's TCP port, GO, live frames, battery, and
a raw recording whose frames are the Python suit's motion samples in order."""

from __future__ import annotations

import pytest

from bpms.firmware.avr_build import build, missing_tools
from bpms.firmware.avr_suit import AvrSuit
from bpms.firmware.sim.arbiter import MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.rawfile import read_raw

pytestmark = pytest.mark.timeout(180)


@pytest.fixture(scope="module")
def avr_build():
    missing = missing_tools()
    if missing:
        pytest.skip(f"cannot build the AVR suit here: missing {', '.join(missing)}")
    return build()


def test_the_app_streams_and_records_the_firmware_suit(qtbot, tmp_path, avr_build) -> None:
    from bpms.gui.startup import StartupWindow

    motion = MotionSource.simulated(seed=5, duration_s=30.0)
    suit = AvrSuit(motion, build=avr_build, battery_v=3.35).start()
    server = TcpServer(suit).start()
    try:
        startup = StartupWindow(recording_dir=str(tmp_path))
        qtbot.addWidget(startup)
        startup.select_mode("suit")
        startup.port_combo.setEditText(server.url)
        with qtbot.waitSignal(startup.mainWindowOpened, timeout=30000) as blocker:
            startup.go_button.click()
        window = blocker.args[0]
        qtbot.addWidget(window)
        if not window.runner.data_on:
            window.panels.status_panel.data_button.click()  # Start Data
        qtbot.waitUntil(lambda: window.model.last_status is not None
                        and window.model.last_status.processed > 25, timeout=30000)
        status = window.model.last_status
        assert status.source.state == "streaming" and not status.source.simulated
        assert status.source.battery_v == pytest.approx(3.35, abs=0.01)
        panel = window.panels.file_panel
        panel.name_edit.setText("avrgui")
        panel.raw_box.setChecked(True)
        panel.filtered_box.setChecked(False)
        panel.log_button.click()
        qtbot.waitUntil(lambda: window.runner.session.status().recording is not None
                        and window.runner.session.status().recording.raw_records >= 50,
                        timeout=30000)
        panel.log_button.click()
        qtbot.waitUntil(lambda: not panel.busy and not panel.logging, timeout=15000)
        raw = read_raw(panel.last_recording.raw_path)
        window.close()
    finally:
        server.stop()
        final = suit.close()
    # consecutive motion samples, exactly the Python suit's counts (no stale frame, no gap)
    frames = raw.frames.tobytes()
    n = len(raw)
    assert n >= 50
    first = next(j for j in range(len(motion)) if motion.frame(j) == frames[:340])
    assert frames == b"".join(motion.frame(first + j) for j in range(n))
    assert final["counters"]["misrouted"] == final["counters"]["cut"] == 0
