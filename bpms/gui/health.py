"""Health at a glance: the link light, the REC indicator and the numbers beside them.

:class:`LinkHealth` is the rule (no Qt): given what the GUI saw, it says

- grey  "stopped": data is off (Stop Data), "paused" / "end of the recording" (the replay
  says so: paused from the slider, or at the end of the file);
- red   "no data": data is on and no frame arrived for :data:`SILENT_S` (1 s), or the source
  itself reports a lost link;
- amber "degraded": the rate is below :data:`DEGRADED_HZ` (45 Hz, scaled by the playback
  speed) or the suit flagged sensor errors in the last second;
- green "streaming".

Times are ``time.monotonic()`` seconds of the GUI thread. A Stop → Start restarts the clock,
so a quick Stop → Start is never a link loss; a loss is only reported after frames had arrived
since the last Start.

:func:`stale_text` turns an evaluation into what every view writes over data that is not
live (link lost, no data, paused, stopped): the state and the age of the last frame shown.

:class:`HealthPanel` shows it: a coloured light, the time since the last frame, the rate, the
error counter, the battery (a warning below :data:`LOW_BATTERY_V`), a red REC indicator with
the elapsed time, file name and folder, and SIMULATED for a simulated source. Beside them:
frames not filtered (red when any: holes in the filtered file), the processing backlog and
the display samples skipped, each on its own line (:mod:`bpms.pipeline.health`); a recording
write error in red until logging stops; why the source is down (red) and its warning (amber,
e.g. another UDP sender); the UDP client's listening address; the IMUs whose magnetometer or
acceleration is disturbed now (amber).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from PyQt6.QtWidgets import QFormLayout, QGroupBox, QLabel, QWidget

from bpms.gui.widgets import label, row
from bpms.pipeline.session import LiveStatus

#: No frame for this long (data on) = red, s.
SILENT_S = 1.0
#: Below this rate (at 1× speed) = amber, Hz.
DEGRADED_HZ = 45.0
#: Sensor error flags within this time = amber, s.
ERROR_HOLD_S = 1.0
#: The suit's single LiFePO4 cell (2.6-3.6 V, cut-off 2.6 V) is nearly empty below this, V.
LOW_BATTERY_V = 3.0

COLOURS = {"grey": "#9e9e9e", "green": "#2e9e44", "amber": "#f0a000", "red": "#d62728"}
RED_TEXT = "color: white; background: #d62728; font-weight: bold; padding: 1px 4px"
AMBER_TEXT = "color: black; background: #f0a000; font-weight: bold; padding: 1px 4px"


@dataclass(frozen=True)
class Health:
    """One evaluation: ``colour`` grey/green/amber/red, ``state`` a few words, ``since_s`` the
    time since the last frame since Start (None before the first), ``transition``
    "lost"/"recovered"/"" when the link was lost or came back at this evaluation; ``age_s``
    the age of the newest frame shown at all, s (across Stop → Start; None before any)."""

    colour: str
    state: str
    since_s: float | None
    transition: str = ""
    age_s: float | None = None

    @property
    def live(self) -> bool:
        """The views show live data (streaming, possibly degraded)."""
        return self.colour == "green" or self.state.startswith("degraded")


#: Replay states in which no frame comes by design (grey, never a loss).
_PAUSED_STATES = {"paused": "paused", "ended": "end of the recording"}


def _age(seconds: float) -> str:
    s = int(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s // 60 % 60:02d} min"


def stale_text(health: Health) -> str | None:
    """The line a view shows over data that is not live ("NO DATA · last frame 4 s ago"), or
    None while it is live or before anything was shown. Whole seconds: the line changes once
    a second at most."""
    if health.live or health.age_s is None:
        return None
    return f"{health.state.upper()} · last frame {_age(health.age_s)} ago"


class LinkHealth:
    """The link-light rule, fed once per display tick."""

    def __init__(self, silent_s: float = SILENT_S, degraded_hz: float = DEGRADED_HZ) -> None:
        self.silent_s = silent_s
        self.degraded_hz = degraded_hz
        self.last_frame: float | None = None
        self.last_shown: float | None = None  # the newest frame at all (Start does not forget)
        self.started: float | None = None
        self._last_error_t: float | None = None
        self._error_bits: int | None = None
        self._lost = False

    def start(self, now: float | None = None) -> None:
        """Start Data pressed: forget the previous stream's last frame."""
        self.started = time.monotonic() if now is None else now
        self.last_frame = None
        self._lost = False

    def stop(self) -> None:
        """Stop Data pressed: grey, and no loss to report."""
        self.started = None
        self._lost = False

    def frames_arrived(self, now: float | None = None) -> None:
        self.last_frame = time.monotonic() if now is None else now
        self.last_shown = self.last_frame

    def evaluate(self, now: float, rate_hz: float, error_bits: int,
                 source_state: str = "streaming", nominal_hz: float | None = 50.0) -> Health:
        """The light now. ``nominal_hz`` the expected rate (None: any rate is fine, e.g. a
        replay at maximum speed); ``error_bits`` the session's growing error counter;
        ``source_state`` the source's own word (a replay's "paused" / "ended" is grey)."""
        if self._error_bits is not None and error_bits > self._error_bits:
            self._last_error_t = now
        self._error_bits = error_bits
        since = None if self.last_frame is None else now - self.last_frame
        age = None if self.last_shown is None else now - self.last_shown
        if self.started is None:
            return Health("grey", "stopped", since, age_s=age)
        if source_state in _PAUSED_STATES:
            self._lost = False
            return Health("grey", _PAUSED_STATES[source_state], since, age_s=age)
        reference = self.last_frame if self.last_frame is not None else self.started
        silent = now - reference >= self.silent_s
        if silent or source_state == "link lost":
            transition = "lost" if (not self._lost and self.last_frame is not None) else ""
            self._lost = self._lost or self.last_frame is not None
            if self.last_frame is None:
                return Health("red", "no data since Start", since, transition, age)
            return Health("red", "no data" if source_state != "link lost" else "link lost",
                          since, transition, age)
        transition = "recovered" if self._lost else ""
        self._lost = False
        if self.last_frame is None:
            return Health("amber", "waiting for data", since, transition, age)
        low = nominal_hz is not None and rate_hz < self.degraded_hz * nominal_hz / 50.0
        errors = self._last_error_t is not None and now - self._last_error_t < ERROR_HOLD_S
        if low or errors:
            why = " and ".join(w for w, on in (("low rate", low), ("sensor errors", errors))
                               if on)
            return Health("amber", f"degraded ({why})", since, transition, age)
        return Health("green", "streaming", since, transition, age)


def _clock(seconds: float) -> str:
    s = int(seconds)
    return f"{s // 3600:d}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else \
        f"{s // 60:02d}:{s % 60:02d}"


class HealthPanel(QGroupBox):
    """The status area's top: link light and state, time since the last frame, rate, error
    counter, battery, REC indicator; SIMULATED for a simulated source."""

    def __init__(self, simulated: bool = False, parent: QWidget | None = None,
                 listening: str | None = None) -> None:
        super().__init__("Health", parent)
        form = QFormLayout(self)
        # a narrow dock puts a long value under its name instead of scrolling sideways
        form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        self.light = QLabel()
        self.light.setFixedSize(18, 18)
        self.state_label = label("stopped", wrap=False, style="font-weight: bold")
        self.simulated_label = label(
            "SIMULATED", wrap=False, tip="The data come from the simulated suit, not a suit",
            style="background: #6a3d9a; color: white; font-weight: bold; padding: 1px 6px")
        self.simulated_label.setVisible(simulated)
        form.addRow(row(self.light, self.state_label, self.simulated_label,
                        grow=self.state_label))
        self.labels: dict[str, QLabel] = {}
        for key, title in (("since", "Last frame"), ("rate", "Rate"), ("errors", "Errors"),
                           ("battery", "Battery"), ("not_filtered", "Not filtered"),
                           ("backlog", "Backlog"), ("skipped", "Display skipped"),
                           ("disturbance", "Disturbed")):
            self.labels[key] = label("–")
            form.addRow(title, self.labels[key])
        self.labels["not_filtered"].setToolTip(
            "Frames received (and recorded raw) that the filters never saw: holes in the "
            "filtered file, each marked")
        self.labels["backlog"].setToolTip("Frames waiting for the processing thread")
        self.labels["skipped"].setToolTip(
            "Processed samples the display did not take (nothing is missing from any file)")
        self.labels["disturbance"].setToolTip(
            "IMUs whose magnetometer (mag: field off the earth's or turned) or acceleration "
            "(acc: over 0.2 g) is disturbed now (docs/filters.md)")
        self.listening_label = label(listening or "", selectable=True,
                                     tip="The UDP client's socket (host:port)")
        form.addRow("Listening on" if listening else "", self.listening_label)
        self.listening_label.setVisible(bool(listening))
        self.source_label = label()  # why the source is down (red) / its warning (amber)
        self.source_label.setVisible(False)
        form.addRow(self.source_label)
        self.rec_error_label = label(style=RED_TEXT)
        self.rec_error_label.setVisible(False)
        form.addRow(self.rec_error_label)
        self.rec_label = label(selectable=True)
        form.addRow(self.rec_label)
        #: the REC state for the window's status bar (always in view, whatever the docks)
        self.rec_badge = label(wrap=False, tip="Logging: elapsed time (the files are in the "
                                               "Status panel)")
        self.rec_badge.setVisible(False)
        #: the link light again, for the status bar (in view whatever the docks)
        self.link_badge = QLabel()
        self.link_badge.setFixedSize(14, 14)
        self.colour = ""
        self.battery_low = False
        self._rec_started: float | None = None
        self._rec_key: object = None
        self.set_colour("grey")

    def set_colour(self, colour: str) -> None:
        if colour == self.colour:
            return
        self.colour = colour
        tip = {"grey": "data off", "green": "streaming",
               "amber": "degraded: rate below 45 Hz or sensor errors in the last second",
               "red": "no frame for 1 s"}[colour]
        for light, radius in ((self.light, 9), (self.link_badge, 7)):
            light.setStyleSheet(f"background: {COLOURS[colour]}; border-radius: {radius}px; "
                                "border: 1px solid #444")
            light.setToolTip("Link: " + tip)

    def _set(self, key: str, text: str, style: str = "") -> None:
        shown = self.labels[key]
        if shown.text() != text:
            shown.setText(text)
        if shown.styleSheet() != style:
            shown.setStyleSheet(style)

    def show_health(self, health: Health, st: LiveStatus | None, now: float) -> None:
        self.set_colour(health.colour)
        if self.state_label.text() != health.state:
            self.state_label.setText(health.state)
        self._set("since", "–" if health.since_s is None else f"{health.since_s:.1f} s ago",
                  "color: #d62728" if health.colour == "red" else "")
        if st is None:
            return
        self._set("rate", f"{st.rate_hz:.1f} Hz")
        self._set("errors", f"{st.error_bits} sensor error flags",
                  "color: #d62728" if health.colour == "amber" and st.error_bits else "")
        volts = st.source.battery_v
        self.battery_low = volts is not None and volts < LOW_BATTERY_V
        if volts is None:
            self._set("battery", "–")
        elif self.battery_low:
            self._set("battery", f"{volts:.2f} V — LOW, charge the suit",
                      "color: white; background: #d62728; font-weight: bold")
        else:
            self._set("battery", f"{volts:.2f} V")
        self._set("not_filtered", f"{st.not_filtered} frames"
                  + (" — holes in the filtered file" if st.not_filtered else ""),
                  RED_TEXT if st.not_filtered else "")
        self._set("backlog", f"{st.processing_backlog} frames")
        self._set("skipped", f"{st.display_skipped} samples")
        self.show_source(st, health.colour == "red")
        self.show_recording(st, now)

    def set_listening(self, address: str | None) -> None:
        """The UDP client's listening address (host:port), when it changes (a new session)."""
        if address and self.listening_label.text() != address:
            self.listening_label.setText(address)

    def show_disturbance(self, mag: int | None, acc: int | None) -> None:
        """How many IMUs' magnetometer / acceleration is disturbed now (None: not known)."""
        if mag is None or acc is None:
            self._set("disturbance", "–")
            return
        self._set("disturbance", f"mag {mag} IMU{'' if mag == 1 else 's'}, acc {acc} "
                  f"IMU{'' if acc == 1 else 's'}", AMBER_TEXT if mag or acc else "")

    def show_source(self, st: LiveStatus, down: bool) -> None:
        """The source's reason (red) while the link is down, else its warning (amber)."""
        src = st.source
        if (down or src.state != "streaming") and src.reason:
            text, style = f"{src.state}: {src.reason}", RED_TEXT
        elif src.warning:
            text, style = src.warning, AMBER_TEXT
        else:
            text, style = "", ""
        if self.source_label.text() != text:
            self.source_label.setText(text)
            self.source_label.setStyleSheet(style)
            self.source_label.setVisible(bool(text))

    def show_recording(self, st: LiveStatus, now: float) -> None:
        rec = st.recording
        error = f"recording write error: {rec.error}" if rec is not None and rec.error else ""
        if self.rec_error_label.text() != error:
            self.rec_error_label.setText(error)
            self.rec_error_label.setVisible(bool(error))
        if rec is None:
            self._rec_started, self._rec_key = None, None
            if self.rec_label.text():
                self.rec_label.setText("")
                self.rec_label.setStyleSheet("")
                self.rec_badge.setVisible(False)
                self.rec_badge.setText("")
            return
        if rec is not self._rec_key:
            self._rec_key, self._rec_started = rec, now
        path: Path | None = rec.raw_path or rec.filtered_path
        names = ", ".join(p.name for p in (rec.raw_path, rec.filtered_path) if p is not None)
        folder = str(path.parent) if path is not None else "–"
        clock = _clock(now - (self._rec_started or now))
        text = (f"REC {clock}  {names}  in {folder}"
                + (f"  — error: {rec.error}" if rec.error else ""))
        if self.rec_label.text() != text:
            self.rec_label.setText(text)
            self.rec_label.setStyleSheet(RED_TEXT)
            self.rec_badge.setText(f"REC {clock}" + ("  write error" if rec.error else ""))
            self.rec_badge.setStyleSheet(RED_TEXT)
            self.rec_badge.setVisible(True)

    @property
    def recording_text(self) -> str:
        return self.rec_label.text()
