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
