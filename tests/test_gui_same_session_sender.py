"""The GUI's UDP client says "another sender on this session" in its status panel (issue
26.1) when a spoofer copies the real sender's session over a real UDP socket: a real window
(pytest-qt), the real receiver, the existing amber source line of the status panel."""

from __future__ import annotations

import socket
import time

from PyQt6.QtCore import QTimer
from test_gui_wiring import _window, recording_path  # noqa: F401  (a fixture)

from bpms.gui.modes import ModeConfig
from bpms.io.rawfile import read_raw
from bpms.io.udp.codec import MessageType, encode_raw_frame
from bpms.io.udp.sender import UdpForwarder


def test_the_status_panel_says_another_sender_on_this_session(qtbot, tmp_path,
                                                               recording_path):  # noqa: F811
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    window = _window(qtbot, tmp_path, ModeConfig(mode="udp", listen=f"127.0.0.1:{port}"))
    window.commands.set_data(True)
    raw = read_raw(recording_path).frames.tobytes()
    frames = [raw[i:i + 340] for i in range(0, len(raw), 340)]
    real = UdpForwarder([f"127.0.0.1:{port}"])
    spoofer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    state = {"k": 0}

    def tick() -> None:
        k = state["k"]
        real.send_frame(frames[k % len(frames)], k * 0.02)
        if k > 20:  # the spoofer joins: the real session's ids, 3 numbers ahead, other frames
            seq = real.next_seq(MessageType.RAW_FRAME) + 3
            spoofer.sendto(encode_raw_frame(
                frames[(k + 100) % len(frames)], session=real.session, seq=seq,
                suit_time=seq * 0.02, send_time=time.time(), sender=real.sender,
                epoch=real.epoch), ("127.0.0.1", port))
        state["k"] = k + 1

    timer = QTimer()
    timer.timeout.connect(tick)
    timer.start(20)
    try:
        qtbot.waitUntil(lambda: "another sender on this session" in
                        window.panels.health_panel.source_label.text(), timeout=15000)
    finally:
        timer.stop()
        real.close()
        spoofer.close()
    assert "#f0a000" in window.panels.health_panel.source_label.styleSheet()  # amber
    assert window.panels.health_panel.source_label.text().startswith(
        "another sender on this session (127.0.0.1:")
    window.commands.set_data(False)
    window.close()
