"""The parts of :class:`bpms.gui.main_window.MainWindow`, one job and its own state each,
wired together in ``MainWindow`` (docs/main-window.md, "How the window is built")."""
