"""The options form: a dialog generated from the Options dataclasses (one tab per section,
help text with units on each field), checked like an options file, saved to a file or as
the user's default."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from PyQt6.QtCore import QRect, Qt
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QLineEdit,
    QScrollArea,
    QSizePolicy,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.safety import guard_wheel
from bpms.gui.screen_fit import fit_dialog
from bpms.gui.widgets import label
from bpms.io import defaults
from bpms.io.options import Options, options_from_dict, save_options
from bpms.io.problems import FileProblem


def _field_text(value: Any) -> str:
    return ", ".join(str(v) for v in value) if isinstance(value, list) else str(value)


def _parse_field(text: str, default: Any) -> Any:
    """The form's text → a value of the default's type (bad text is left for
    ``options_from_dict`` to report)."""
    text = text.strip()
    try:
        if isinstance(default, bool):
            return text.lower() in ("true", "1", "yes", "on")
        if isinstance(default, int):
            return int(text)
        if isinstance(default, float):
            return float(text)
        if isinstance(default, list):
            items = [t.strip() for t in text.split(",") if t.strip()]
            if default and isinstance(default[0], float):
                return [float(t) for t in items]
            return items
    except ValueError:
        return text
    return text


class _FormScroll(QScrollArea):
    """A scroll area whose page is as tall as its wrapped rows need at the current width
    (QScrollArea alone ignores height-for-width, squeezing word-wrapped rows together)."""

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        page = self.widget()
        layout = page.layout() if page is not None else None
        if layout is not None and layout.hasHeightForWidth():
            page.setMinimumHeight(layout.heightForWidth(self.viewport().width()))


class OptionsDialog(QDialog):
    """A form generated from the Options dataclasses (help text with units on each field).

    ``options()`` checks the values like the options file does; ``problems`` lists what was
    rejected (factory values used instead).
    """

    def __init__(self, options: Options, parent: QWidget | None = None,
                 available: QRect | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("BPMS options")
        self.base = options
        self.editors: dict[tuple[str, str], QWidget] = {}
        self.defaults: dict[tuple[str, str], Any] = {}
        tabs = QTabWidget()
        self.tabs = tabs
        self.scrolls: dict[str, QScrollArea] = {}
        for name, section in options.sections().items():
            page = QWidget()
            # Name and help above the field, the form's whole width: a plain column lays the
            # wrapped help out at its full height (a form layout's wrapped rows clipped
            # two-line help texts)
            form = QVBoxLayout(page)
            for f in dataclasses.fields(section):
                value = getattr(section, f.name)
                help_text = f.metadata.get("help", "")
                if isinstance(value, bool):
                    editor: QWidget = QCheckBox()
                    editor.setChecked(value)
                elif "choices" in f.metadata:
                    editor = QComboBox()
                    editor.addItems([str(c) for c in f.metadata["choices"]])
                    editor.setCurrentText(str(value))
                else:
                    editor = QLineEdit(_field_text(value))
                editor.setToolTip(help_text)
                self.editors[(name, f.name)] = editor
                self.defaults[(name, f.name)] = f.default if f.default is not dataclasses.MISSING \
                    else f.default_factory()  # type: ignore[misc]
                title = label(f"<b>{f.name}</b> <small>{help_text}</small>")
                title.setBuddy(editor)
                guard_wheel(editor)
                policy = QSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Fixed)
                policy.setHeightForWidth(True)
                title.setSizePolicy(policy)
                form.addWidget(title)
                form.addWidget(editor)
                form.addSpacing(4)
            form.addStretch(1)
            scroll = _FormScroll()
            scroll.setWidget(page)
            scroll.setWidgetResizable(True)
            scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
            self.scrolls[name] = scroll
            tabs.addTab(scroll, name)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                                   | QDialogButtonBox.StandardButton.Cancel)
        self.save_button = buttons.addButton("Save as…", QDialogButtonBox.ButtonRole.ActionRole)
        self.save_button.clicked.connect(self._save_as)
        self.default_button = buttons.addButton("Save as default",
                                                QDialogButtonBox.ButtonRole.ActionRole)
        self.default_button.setToolTip("Use these options whenever none are given "
                                       "(bpms config shows where they are kept)")
        self.default_button.clicked.connect(self.save_as_default)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addWidget(tabs)
        layout.addWidget(buttons)
        fit_dialog(self, 640, 560, available)  # never taller than the screen: the tabs scroll
        self.problems: list[FileProblem] = []

    def form_data(self) -> dict[str, dict[str, Any]]:
        data: dict[str, dict[str, Any]] = {}
        for (section, key), editor in self.editors.items():
            default = self.defaults[(section, key)]
            if isinstance(editor, QCheckBox):
                value: Any = editor.isChecked()
            elif isinstance(editor, QComboBox):
                value = editor.currentText()
            else:
                assert isinstance(editor, QLineEdit)
                value = _parse_field(editor.text(), default)
            data.setdefault(section, {})[key] = value
        return data

    def options(self) -> Options:
        """The form's values, checked (bad ones replaced by factory values, in problems)."""
        options = options_from_dict(self.form_data(), "options form")
        self.problems = list(options.problems)
        options.source = self.base.source + " (edited)"
        return options

    def save(self, path: str | Path) -> Options:
        options = self.options()
        save_options(options, path)
        return options

    def save_as_default(self) -> Path:
        """Make the form's options the user's default (docs/configuration.md)."""
        return defaults.save_default_options(self.options())

    def _save_as(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save options", "options.toml",
                                              "TOML (*.toml)")
        if path:
            self.save(path)
