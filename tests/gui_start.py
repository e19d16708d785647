"""The start-up window's GO, as a user presses it: the main window it opens (pytest-qt)."""

from __future__ import annotations


def open_main_window(qtbot, startup):
    """Click ``startup``'s GO and return the MainWindow it opened (within 20 s), owned by
    ``qtbot`` so that it is closed after the test."""
    with qtbot.waitSignal(startup.mainWindowOpened, timeout=20000) as blocker:
        startup.go_button.click()
    window = blocker.args[0]
    qtbot.addWidget(window)
    return window
