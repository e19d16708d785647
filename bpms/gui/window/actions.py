"""The main window's menus and toolbar: every command as a QAction with its shortcut, the
menu bar, the Layouts menu, the toolbar (Start/Stop, Reset Zero, Record, LSL, the plot drop
area) and the keys help (:class:`WindowMenus`)."""

from __future__ import annotations

from PyQt6.QtCore import QRect, Qt
from PyQt6.QtGui import QAction, QColor, QIcon, QKeySequence, QPainter, QPixmap
from PyQt6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QMainWindow,
    QStyle,
    QTextBrowser,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.layouts import DEFAULT_LAYOUTS
from bpms.gui.modes import SessionRunner
from bpms.gui.pose_calibration_panel import PoseCalibrationDialog
from bpms.gui.screen_fit import fit_dialog
from bpms.gui.view3d_keys import PLOT_BINDINGS, VIEW3D_BINDINGS, help_html
from bpms.gui.window.commands import SessionCommands
from bpms.gui.window.dock_layout import DockLayouts
from bpms.gui.window.dynamic_docks import ViewDocks
from bpms.gui.window.mode_wiring import ModeControls
from bpms.gui.window.panels import WindowPanels


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


class WindowMenus:
    """The commands of ``window`` as actions, in its menu bar and toolbar:
    ``actions_by_name`` (every command with its shortcut), ``layouts_menu``, ``toolbar``
    and its ``start_action``, ``stop_action`` and ``record_action``. The actions call the
    parts given here; :meth:`update_toolbar` shows whether the data and the logging are
    on."""

    def __init__(self, window: QMainWindow, runner: SessionRunner, panels: WindowPanels,
                 commands: SessionCommands, views: ViewDocks, layouts: DockLayouts,
                 mode: ModeControls) -> None:
        self._window = window
        self._runner = runner
        self._panels = panels
        self._commands = commands
        self._views = views
        self._layouts = layouts
        self._mode = mode
        self.keys_box: KeysDialog | None = None
        self.pose_calibration_dialog: PoseCalibrationDialog | None = None
        self._make_actions()
        self._build_menu_bar()
        self._build_toolbar()

    def _action(self, text: str, slot, keys: str | None = None, tip: str = "") -> QAction:
        action = QAction(text, self._window)
        if keys:
            action.setShortcut(QKeySequence(keys))
            action.setShortcutContext(Qt.ShortcutContext.WindowShortcut)
        if tip:
            action.setToolTip(tip)
            action.setStatusTip(tip)
        action.triggered.connect(lambda *_: slot())
        self._window.addAction(action)
        return action

    def _make_actions(self) -> None:
        """``actions_by_name``: every command with its shortcut and tip."""
        a = self._action
        commands, views, layouts, mode = self._commands, self._views, self._layouts, self._mode
        runner, panels = self._runner, self._panels
        self.actions_by_name: dict[str, QAction] = {
            "data": a("Start/Stop Data", lambda: commands.set_data(not runner.data_on),
                      "Ctrl+Space", "Start or stop the stream (play/pause a recording)"),
            "reset_zero": a("Reset Zero", commands.reset_zero, "Ctrl+R",
                            "Stand in the calibration pose, then press"),
            "marker": a("Marker…", lambda: commands.add_marker(), "Ctrl+M",
                        "A marker note at this frame: in the recording, the event log and "
                        "the LSL event stream"),
            "record": a("Start/Stop Logging", panels.file_panel.toggle_logging, "Ctrl+L",
                        "Record raw and/or filtered files (Session dock)"),
            "plot": a("Plot selection", views.plot_selection, "Ctrl+P",
                      "A new plot of the selected table cells"),
            "joints": a("Joint angles plot", views.open_joint_plot, "Ctrl+J"),
            "view3d": a("New 3D view", views.open_3d_view, "Ctrl+3"),
            "tile": a("Tile plots", layouts.tile_plots,
                      tip="Every docked plot in view at once, in a grid under the table"),
            "browser": a("Browser 3D view", views.open_browser_view),
            "unit": a("Angles deg/rad", commands.toggle_unit, "Ctrl+U"),
            "step_back": a("Previous frame", lambda: mode.step_frames(-1), "Ctrl+Left",
                           "Playback, paused: one frame back"),
            "step_fwd": a("Next frame", lambda: mode.step_frames(1), "Ctrl+Right",
                          "Playback, paused: one frame forward"),
            "step_back10": a("Back 1 s", lambda: mode.step_frames(-50), "Ctrl+Shift+Left"),
            "step_fwd10": a("Forward 1 s", lambda: mode.step_frames(50), "Ctrl+Shift+Right"),
            "save_layout": a("Save layout as…", layouts.save_layout_dialog, "Ctrl+Shift+S"),
            "quit": a("Close window", self._window.close, "Ctrl+Q"),
            "sensor_angles": a("Sensor angles (uncorrected)", lambda: commands.show_sensor_angles(
                                   self.actions_by_name["sensor_angles"].isChecked()),
                               tip="Table and plots show the sensor angles, without Reset "
                                   "Zero (off: the segment angles after Reset Zero)"),
            "corrected": a("Reset Zero correction of the output angles",
                           lambda: commands.set_corrected_output(
                               self.actions_by_name["corrected"].isChecked()), "V",
                           "The angles shown, recorded and streamed: segment angles after "
                           "Reset Zero (on) or the sensor angles (off); v in the table"),
            "drift": a("Drift check…", mode.open_drift_check,
                       tip="Each segment's attitude change between the calibration pauses at "
                           "the start and the end of the recording (playback)"),
            "lsl": a("Stream to LSL", self._lsl_toggled,
                     tip="Stream the session as Lab Streaming Layer outlets (docs/lsl.md)"),
        }
        acts = self.actions_by_name
        acts["sensor_angles"].setCheckable(True)
        acts["corrected"].setCheckable(True)
        processor = getattr(runner.session, "processor", None)
        acts["corrected"].setChecked(bool(getattr(processor, "corrected_output", True)))
        # the original's v key, in the table (the 3D view keeps its own v: figure alignment)
        self._window.removeAction(acts["corrected"])
        acts["corrected"].setShortcutContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
        panels.table_tabs.addAction(acts["corrected"])
        acts["lsl"].setCheckable(True)
        acts["lsl"].setChecked(runner.lsl_on)
        acts["view3d"].setEnabled(panels.view3d_button.isEnabled())
        acts["browser"].setEnabled(panels.browser_button.isEnabled())

    def open_pose_calibration(self) -> PoseCalibrationDialog:
        """Data ▸ Pose calibration…: its dialog (one per window), shown and raised, for the
        window's live session while its data is on."""
        dialog = self.pose_calibration_dialog
        if dialog is None:
            runner = self._runner
            dialog = PoseCalibrationDialog(lambda: runner.session if runner.data_on else None,
                                           self._window)
            self.pose_calibration_dialog = dialog
        dialog.show()
        dialog.raise_()
        return dialog

    def _lsl_toggled(self) -> None:
        action = self.actions_by_name["lsl"]
        action.setChecked(self._commands.set_lsl(action.isChecked()))

    def _build_menu_bar(self) -> None:
        acts = self.actions_by_name
        bar = self._window.menuBar()
        menu = bar.addMenu("&File")
        for key in ("record", "quit"):
            menu.addAction(acts[key])
        menu = bar.addMenu("&Data")
        for key in ("data", "reset_zero", "marker", "corrected", "lsl"):
            menu.addAction(acts[key])
        menu.addAction("Pose calibration…", self.open_pose_calibration)
        self._mode.add_playback_actions(menu, acts)
        menu = bar.addMenu("&View")
        for key in ("plot", "joints", "tile", "view3d", "browser", "unit", "sensor_angles"):
            menu.addAction(acts[key])
        menu.addSeparator()
        for dock in self._panels.docks.values():
            menu.addAction(dock.toggleViewAction())
        self.layouts_menu = bar.addMenu("&Layouts")
        self.layouts_menu.aboutToShow.connect(self._fill_layouts_menu)
        self._fill_layouts_menu()
        help_menu = bar.addMenu("&Help")
        help_menu.addAction(self._action("Keys and mouse…", self.show_keys, "F1"))

    def _build_toolbar(self) -> None:
        acts = self.actions_by_name
        commands = self._commands
        toolbar = self._window.addToolBar("Session")
        toolbar.setObjectName("toolbar")
        toolbar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.toolbar = toolbar
        icon = self._window.style().standardIcon
        sp = QStyle.StandardPixmap
        # icons from Qt's standard set (a font may lack the media glyphs)
        self.start_action = toolbar.addAction(icon(sp.SP_MediaPlay), "Start",
                                              lambda: commands.set_data(True))
        self.start_action.setToolTip("Start Data (Ctrl+Space)")
        self.stop_action = toolbar.addAction(icon(sp.SP_MediaStop), "Stop",
                                             lambda: commands.set_data(False))
        self.stop_action.setToolTip("Stop Data (Ctrl+Space)")
        acts["reset_zero"].setIcon(icon(sp.SP_BrowserReload))
        toolbar.addAction(acts["reset_zero"])
        self.record_action = toolbar.addAction(record_icon(), "Record",
                                               self._panels.file_panel.toggle_logging)
        self.record_action.setToolTip("Start/Stop Logging (Ctrl+L)")
        toolbar.addAction(acts["lsl"])
        toolbar.addSeparator()
        drop_area = self._panels.drop_area
        drop_area.setMinimumWidth(300)
        toolbar.addWidget(drop_area)
        self.update_toolbar()

    def _fill_layouts_menu(self) -> None:
        menu = self.layouts_menu
        layouts = self._layouts
        store = layouts.layout_store
        menu.clear()
        for name in DEFAULT_LAYOUTS:
            if name not in store.names():
                menu.addAction(name.capitalize(),
                               lambda n=name: layouts.apply_default_layout(n))
        saved = store.names()
        if saved:
            menu.addSeparator()
            for name in saved:
                menu.addAction(name, lambda n=name: layouts.load_layout(n))
        menu.addSeparator()
        menu.addAction(self.actions_by_name["save_layout"])

    def update_toolbar(self) -> None:
        """Start or Stop enabled (and Reset Zero with the data on), Record or Stop
        recording."""
        on = self._runner.data_on
        self.start_action.setEnabled(not on)
        self.stop_action.setEnabled(on)
        self.actions_by_name["reset_zero"].setEnabled(on)
        self.record_action.setText("Stop recording" if self._panels.file_panel.logging
                                   else "Record")

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
        box = KeysDialog(self.keys_html(), self._window, available)
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
