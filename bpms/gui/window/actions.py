"""The main window's menus and toolbar: every command as a QAction with its shortcut, the
menu bar, the Layouts menu, the toolbar (Start/Stop, Reset Zero, Record, LSL, the plot drop
area) and the keys help. Mixed into :class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

from PyQt6.QtCore import QRect, Qt
from PyQt6.QtGui import QAction, QColor, QIcon, QKeySequence, QPainter, QPixmap
from PyQt6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QStyle,
    QTextBrowser,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.layouts import DEFAULT_LAYOUTS
from bpms.gui.pose_calibration_panel import open_pose_calibration
from bpms.gui.screen_fit import fit_dialog
from bpms.gui.view3d_keys import PLOT_BINDINGS, VIEW3D_BINDINGS, help_html


def record_icon(size: int = 16) -> QIcon:
    """A red disc (drawn: no font has to have a glyph for it)."""
    pixmap = QPixmap(size, size)
    pixmap.fill(QColor(0, 0, 0, 0))
    painter = QPainter(pixmap)
    painter.setRenderHint(QPainter.RenderHint.Antialiasing)
    painter.setPen(QColor("#8b1a1a"))
    painter.setBrush(QColor("#d62728"))
    painter.drawEllipse(2, 2, size - 4, size - 4)
    painter.end()
    return QIcon(pixmap)


class WindowActions:
    """``actions_by_name``, ``layouts_menu``, ``toolbar`` and its start/stop/record actions."""

    def _action(self, text: str, slot, keys: str | None = None, tip: str = "") -> QAction:
        action = QAction(text, self)
        if keys:
            action.setShortcut(QKeySequence(keys))
            action.setShortcutContext(Qt.ShortcutContext.WindowShortcut)
        if tip:
            action.setToolTip(tip)
            action.setStatusTip(tip)
        action.triggered.connect(lambda *_: slot())
        self.addAction(action)
        return action

    def _menus(self) -> None:
        self._make_actions()
        self._build_menu_bar()
        self._build_toolbar()

    def _make_actions(self) -> None:
        """``actions_by_name``: every command with its shortcut and tip."""
        a = self._action
        self.actions_by_name: dict[str, QAction] = {
            "data": a("Start/Stop Data", lambda: self.set_data(not self.runner.data_on),
                      "Ctrl+Space", "Start or stop the stream (play/pause a recording)"),
            "reset_zero": a("Reset Zero", self.reset_zero, "Ctrl+R",
                            "Stand in the calibration pose, then press"),
            "marker": a("Marker…", lambda: self.add_marker(), "Ctrl+M",
                        "A marker note at this frame: in the recording, the event log and "
                        "the LSL event stream"),
            "record": a("Start/Stop Logging", self.file_panel.toggle_logging, "Ctrl+L",
                        "Record raw and/or filtered files (Session dock)"),
            "plot": a("Plot selection", self.plot_selection, "Ctrl+P",
                      "A new plot of the selected table cells"),
            "joints": a("Joint angles plot", self.open_joint_plot, "Ctrl+J"),
            "view3d": a("New 3D view", self.open_3d_view, "Ctrl+3"),
            "tile": a("Tile plots", self.tile_plots,
                      tip="Every docked plot in view at once, in a grid under the table"),
            "browser": a("Browser 3D view", self.open_browser_view),
            "unit": a("Angles deg/rad", self._toggle_unit, "Ctrl+U"),
            "step_back": a("Previous frame", lambda: self.step_frames(-1), "Ctrl+Left",
                           "Playback, paused: one frame back"),
            "step_fwd": a("Next frame", lambda: self.step_frames(1), "Ctrl+Right",
                          "Playback, paused: one frame forward"),
            "step_back10": a("Back 1 s", lambda: self.step_frames(-50), "Ctrl+Shift+Left"),
            "step_fwd10": a("Forward 1 s", lambda: self.step_frames(50), "Ctrl+Shift+Right"),
            "save_layout": a("Save layout as…", self.save_layout_dialog, "Ctrl+Shift+S"),
            "quit": a("Close window", self.close, "Ctrl+Q"),
            "sensor_angles": a("Sensor angles (uncorrected)", self._sensor_angles_toggled,
                               tip="Table and plots show the sensor angles, without Reset "
                                   "Zero (off: the segment angles after Reset Zero)"),
            "corrected": a("Reset Zero correction of the output angles",
                           self._corrected_toggled, "V",
                           "The angles shown, recorded and streamed: segment angles after "
                           "Reset Zero (on) or the sensor angles (off); v in the table"),
            "drift": a("Drift check…", self.open_drift_check,
                       tip="Each segment's attitude change between the calibration pauses at "
                           "the start and the end of the recording (playback)"),
            "lsl": a("Stream to LSL", self._lsl_toggled,
                     tip="Stream the session as Lab Streaming Layer outlets (docs/lsl.md)"),
        }
        acts = self.actions_by_name
        acts["sensor_angles"].setCheckable(True)
        acts["corrected"].setCheckable(True)
        processor = getattr(self.runner.session, "processor", None)
        acts["corrected"].setChecked(bool(getattr(processor, "corrected_output", True)))
        # the original's v key, in the table (the 3D view keeps its own v: figure alignment)
        self.removeAction(acts["corrected"])
        acts["corrected"].setShortcutContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
        self.table_tabs.addAction(acts["corrected"])
        acts["lsl"].setCheckable(True)
        acts["lsl"].setChecked(self.runner.lsl_on)
        self.actions_by_name["view3d"].setEnabled(self.view3d_button.isEnabled())
        self.actions_by_name["browser"].setEnabled(self.browser_button.isEnabled())

    def _build_menu_bar(self) -> None:
        a = self._action
        acts = self.actions_by_name
        bar = self.menuBar()
        menu = bar.addMenu("&File")
        for key in ("record", "quit"):
            menu.addAction(acts[key])
        menu = bar.addMenu("&Data")
        for key in ("data", "reset_zero", "marker", "corrected", "lsl"):
            menu.addAction(acts[key])
        menu.addAction("Pose calibration…", lambda: open_pose_calibration(self))
        self._add_playback_actions(menu)
        menu = bar.addMenu("&View")
        for key in ("plot", "joints", "tile", "view3d", "browser", "unit", "sensor_angles"):
            menu.addAction(acts[key])
        menu.addSeparator()
        for dock in self.docks.values():
            menu.addAction(dock.toggleViewAction())
        self.layouts_menu = bar.addMenu("&Layouts")
        self.layouts_menu.aboutToShow.connect(self._fill_layouts_menu)
        self._fill_layouts_menu()
        help_menu = bar.addMenu("&Help")
        help_menu.addAction(a("Keys and mouse…", self.show_keys, "F1"))

    def _build_toolbar(self) -> None:
        acts = self.actions_by_name
        toolbar = self.addToolBar("Session")
        toolbar.setObjectName("toolbar")
        toolbar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.toolbar = toolbar
        icon = self.style().standardIcon
        sp = QStyle.StandardPixmap
        # icons from Qt's standard set (a font may lack the media glyphs)
        self.start_action = toolbar.addAction(icon(sp.SP_MediaPlay), "Start",
                                              lambda: self.set_data(True))
        self.start_action.setToolTip("Start Data (Ctrl+Space)")
        self.stop_action = toolbar.addAction(icon(sp.SP_MediaStop), "Stop",
                                             lambda: self.set_data(False))
        self.stop_action.setToolTip("Stop Data (Ctrl+Space)")
        acts["reset_zero"].setIcon(icon(sp.SP_BrowserReload))
        toolbar.addAction(acts["reset_zero"])
        self.record_action = toolbar.addAction(record_icon(), "Record",
                                               self.file_panel.toggle_logging)
        self.record_action.setToolTip("Start/Stop Logging (Ctrl+L)")
        toolbar.addAction(acts["lsl"])
        toolbar.addSeparator()
        self.drop_area.setMinimumWidth(300)
        toolbar.addWidget(self.drop_area)
        self._update_toolbar()

    def _fill_layouts_menu(self) -> None:
        menu = self.layouts_menu
        menu.clear()
        for name in DEFAULT_LAYOUTS:
            if name not in self.layout_store.names():
                menu.addAction(name.capitalize(), lambda n=name: self.apply_default_layout(n))
        saved = self.layout_store.names()
        if saved:
            menu.addSeparator()
            for name in saved:
                menu.addAction(name, lambda n=name: self.load_layout(n))
        menu.addSeparator()
        menu.addAction(self.actions_by_name["save_layout"])

    def _update_toolbar(self) -> None:
        on = self.runner.data_on
        self.start_action.setEnabled(not on)
        self.stop_action.setEnabled(on)
        self.actions_by_name["reset_zero"].setEnabled(on)
        self.record_action.setText("Stop recording" if self.file_panel.logging else "Record")

    def keys_html(self) -> str:
        """The F1 page: the window's shortcuts (from its actions), the 3D view's and the
        plots' keys and mouse (from their tables, :mod:`bpms.gui.view3d_keys`)."""
        rows = "".join(f"<tr><td><b>{act.shortcut().toString()}</b></td><td>{act.text()}"
                       "</td></tr>" for act in self.actions_by_name.values()
                       if not act.shortcut().isEmpty())
        window = f"<h3>Main window</h3><table cellspacing='2' cellpadding='2'>{rows}</table>"
        return (window + help_html("3D view (click it first)", VIEW3D_BINDINGS)
                + help_html("Plots", PLOT_BINDINGS))

    def show_keys(self, available: QRect | None = None) -> KeysDialog:
        """The F1 page (no taller than the screen, ``available`` overriding its available
        geometry; it scrolls)."""
        box = KeysDialog(self.keys_html(), self, available)
        box.open()
        self.keys_box = box
        return box


class KeysDialog(QDialog):
    """The F1 page in a scrolling text view, sized to its text but never beyond the screen
    (:func:`bpms.gui.screen_fit.fit_dialog`)."""

    def __init__(self, html: str, parent: QWidget | None = None,
                 available: QRect | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Keys and mouse")
        self._html = html
        self.view = QTextBrowser()
        self.view.setHtml(html)
        self.view.setOpenLinks(False)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addWidget(self.view)
        layout.addWidget(buttons)
        document = self.view.document()
        document.setTextWidth(560)
        height = int(document.size().height()) + 80  # the page, the button row, margins
        fit_dialog(self, 620, height, available)

    def text(self) -> str:
        """The page's HTML as given."""
        return self._html
