"""The parts of :class:`bpms.gui.main_window.MainWindow`, one job each (mixins)."""
