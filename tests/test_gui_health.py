"""The link-light rule (issue 15.2) on hand-made timelines: no Qt, no waiting."""

from __future__ import annotations

from bpms.gui.health import LinkHealth


def _stream(h: LinkHealth, t0: float, t1: float, step: float = 0.05) -> float:
    t = t0
    while t < t1:
        h.frames_arrived(t)
        t += step
    return t


def test_grey_green_amber_red_and_one_loss_per_silence():
    h = LinkHealth()
    assert h.evaluate(0.0, 0.0, 0).colour == "grey"  # data off
    h.start(10.0)
    assert h.evaluate(10.2, 0.0, 0).state == "waiting for data"
    t = _stream(h, 10.3, 12.0)
    assert h.evaluate(t, 50.0, 0).colour == "green"
    assert h.evaluate(t, 44.0, 0).colour == "amber"  # below 45 Hz
    assert h.evaluate(t, 25.0, 0, nominal_hz=25.0).colour == "green"  # 0.5x playback
    assert h.evaluate(t, 3000.0, 0, nominal_hz=None).colour == "green"  # max speed
    # sensor errors: amber for a second after the counter grows
    assert h.evaluate(t + 0.01, 50.0, 3).colour == "amber"
    h.frames_arrived(t + 0.9)
    assert h.evaluate(t + 0.9, 50.0, 3).colour == "amber"
    h.frames_arrived(t + 1.1)
    assert h.evaluate(t + 1.1, 50.0, 3).colour == "green"
    # silence: red after 1 s, the loss reported once, then the recovery once
    last = t + 1.1
    assert h.evaluate(last + 0.95, 50.0, 3).colour == "green"
    red = h.evaluate(last + 1.0, 0.0, 3)
    assert red.colour == "red" and red.transition == "lost" and red.state == "no data"
    assert h.evaluate(last + 3.0, 0.0, 3).transition == ""
    h.frames_arrived(last + 3.1)
    back = h.evaluate(last + 3.1, 50.0, 3)
    assert back.colour == "green" and back.transition == "recovered"
    # the source's own "link lost" is red at once
    assert h.evaluate(last + 3.2, 50.0, 3, source_state="link lost").colour == "red"


def test_a_quick_stop_start_is_not_a_link_loss():
    h = LinkHealth()
    h.start(0.0)
    t = _stream(h, 0.1, 5.0)
    h.stop()
    assert h.evaluate(t + 0.5, 0.0, 0).colour == "grey"
    h.start(t + 0.6)  # Start again after 0.6 s: the old last frame is forgotten
    first = h.evaluate(t + 0.7, 0.0, 0)
    assert first.colour == "amber" and first.transition == ""
    h.frames_arrived(t + 0.9)
    assert h.evaluate(t + 0.9, 50.0, 0).transition == ""
    # no frame at all after a Start: red, but not a "link lost" (nothing was streaming)
    h.start(100.0)
    late = h.evaluate(101.5, 0.0, 0)
    assert late.colour == "red" and late.transition == "" and "since Start" in late.state


def test_a_paused_replay_is_grey_and_the_views_say_how_old_the_frame_is():
    from bpms.gui.health import stale_text

    h = LinkHealth()
    h.start(0.0)
    t = _stream(h, 0.1, 3.0)
    live = h.evaluate(t, 50.0, 0)
    assert live.live and stale_text(live) is None
    paused = h.evaluate(t + 2.4, 0.0, 0, source_state="paused")
    assert paused.colour == "grey" and paused.transition == ""  # never a link loss
    assert stale_text(paused) == "PAUSED · last frame 2 s ago"
    ended = h.evaluate(t + 75.0, 0.0, 0, source_state="ended")
    assert stale_text(ended) == "END OF THE RECORDING · last frame 1 min 15 s ago"
    lost = h.evaluate(t + 80.0, 0.0, 0)  # playing again but silent: red, and stale
    assert lost.colour == "red" and stale_text(lost).startswith("NO DATA · last frame")
    # Stop → Start forgets the last frame for the light, not for the views' age
    h.stop()
    h.start(t + 81.0)
    waiting = h.evaluate(t + 81.5, 0.0, 0)
    assert waiting.since_s is None and stale_text(waiting).startswith("WAITING FOR DATA")
    h.frames_arrived(t + 81.6)
    assert stale_text(h.evaluate(t + 81.6, 50.0, 0)) is None


def test_nothing_is_marked_before_anything_was_shown():
    from bpms.gui.health import stale_text

    h = LinkHealth()
    assert stale_text(h.evaluate(0.0, 0.0, 0)) is None
    h.start(0.0)
    assert stale_text(h.evaluate(5.0, 0.0, 0)) is None  # red "no data since Start"


def test_the_overlay_veils_its_view_and_goes_away(qtbot):
    from PyQt6.QtWidgets import QLabel

    from bpms.gui.stale import StaleOverlay

    view = QLabel("12.34")
    qtbot.addWidget(view)
    view.resize(300, 120)
    view.show()
    overlay = StaleOverlay(view)
    assert not overlay.isVisible() and not overlay.stale
    overlay.show_text("NO DATA · last frame 3 s ago")
    assert overlay.isVisible() and overlay.geometry() == view.rect()
    view.resize(400, 200)
    assert overlay.geometry() == view.rect()  # follows its view
    image = view.grab().toImage()
    box = overlay.box_rect()
    assert box.width() <= view.width() and image.pixelColor(box.center()).lightness() < 100
    overlay.show_text(None)
    assert not overlay.isVisible() and not overlay.stale
