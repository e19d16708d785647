"""The main window's session commands: Start/Stop Data, Reset Zero, the filter and its
gains, the angle unit and which angles are shown. Mixed into
:class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

import numpy as np

from bpms.gui.modes import ModeError

#: Reset Zero warns when an IMU turned more than this during the averaging window, deg.
RESET_MOTION_DEG = 5.0


class SessionCommands:
    """What the menus, toolbar and panels ask of the session."""

    def set_data(self, on: bool) -> None:
        """Start Data / Stop Data."""
        if on == self.runner.data_on:
            return
        if on:
            try:
                session = self.runner.start_data()
            except ModeError as exc:
                self.statusBar().showMessage(str(exc), 10000)
                self.event_log.add(f"cannot start data: {exc}", "warning")
                return
            if session is not self.model.session:
                self.model.attach(session)
                self.health_panel.set_listening(self._listening())
            self.model.set_data_on(True)
            self.event_log.add("data started")
        else:
            self.runner.stop_data()
            self.model.set_data_on(False)
            self.event_log.add("data stopped")
        self.status_panel.set_streaming(self.runner.data_on)
        self._update_toolbar()

    def reset_zero(self) -> None:
        """Reset Zero at the next frame (stand in the calibration pose); warns when an IMU
        turned during the averaging window that ends there."""
        if self.runner.session is None or not self.runner.data_on:
            return
        self.runner.session.reset_zero()
        self.statusBar().showMessage("Reset Zero requested", 3000)
        self.event_log.add("Reset Zero")
        moved = self._motion_in_window_deg()
        if moved is not None and moved[0] > RESET_MOTION_DEG:
            self.event_log.add(f"Reset Zero: the subject moved during its window "
                               f"({moved[0]:.0f}° on IMU {moved[1]}); stand still in the "
                               "calibration pose and press again", "warning")

    def _motion_in_window_deg(self) -> tuple[float, int] | None:
        """Largest rotation of one IMU's filter DCM over the last Reset Zero window, deg."""
        if len(self._recent_R) < 2:
            return None
        R = np.asarray(self._recent_R)  # [n, 18, 3, 3]
        rel = np.einsum("ikj,nikl->nijl", R[0], R)  # R0^T R_n
        trace = np.clip((np.trace(rel, axis1=2, axis2=3) - 1.0) / 2.0, -1.0, 1.0)
        angles = np.degrees(np.arccos(trace))
        angles = np.where(np.isfinite(angles), angles, 0.0).max(axis=0)
        k = int(np.argmax(angles))
        return float(angles[k]), k

    def _sensor_angles_toggled(self) -> None:
        """View ▸ Sensor angles (uncorrected): the table and the angle plots show ``euler``
        (checked) or the output angles ``euler_output`` (unchecked, the default)."""
        sensor = self.actions_by_name["sensor_angles"].isChecked()
        self.table_model.set_show_output(not sensor)
        self.readout.reset()  # other angles: their continuous readout starts again
        self.statusBar().showMessage("angles shown: " + ("sensor angles (uncorrected)" if sensor
                                     else "output angles (after Reset Zero)"), 3000)

    def _corrected_toggled(self) -> None:
        """The original's v key: the session's output angles corrected by Reset Zero or not
        (what is shown, recorded and streamed), from the next frame."""
        on = self.actions_by_name["corrected"].isChecked()
        if self.runner.session is not None:
            self.runner.session.set_corrected_output(on)
        self.options.pose.corrected_output = on  # a new session (UDP restart) follows
        self.event_log.add("Reset Zero correction of the output angles "
                           + ("on (segment angles)" if on else "off (sensor angles)"))

    def _lsl_toggled(self) -> None:
        """Stream to LSL on/off (SessionRunner.set_lsl); the reason when it cannot start."""
        action = self.actions_by_name["lsl"]
        on = action.isChecked()
        why = self.runner.set_lsl(on)
        if why:
            action.setChecked(False)
            self.statusBar().showMessage(f"LSL: {why}", 10000)
            self.event_log.add(f"LSL streaming not started: {why}", "warning")
            return
        action.setChecked(self.runner.lsl_on)
        self.event_log.add("LSL streaming " + ("on" if self.runner.lsl_on else "off"))

    def _set_gains(self, gains: dict) -> None:
        """A gain the panel accepted; the session checks it again (the panel logs the change,
        or the refusal with the range)."""
        if self.runner.session is not None:
            try:
                self.runner.session.set_gains(**gains)
            except ValueError as exc:  # outside the valid range: refused, said why
                self.statusBar().showMessage(str(exc), 8000)
                self.gains_panel.refuse(str(exc))
                return
            for name, value in gains.items():
                setattr(self.options.filter, name, value)

    def select_filter(self, algorithm: str) -> None:
        """Switch the attitude filter of all 18 IMUs (Reset Zero is kept)."""
        if self.runner.session is not None:
            self.runner.session.select_filter(algorithm)
        self.options.filter.algorithm = algorithm
        self.statusBar().showMessage(f"filter: {algorithm}", 3000)
        self.event_log.add(f"filter re-initialised: {algorithm} on all 18 IMUs")

    def set_angle_unit(self, unit: str) -> None:
        self.table_model.set_angle_unit(unit)
        self.joint_model.set_angle_unit(unit)
        self.options.display.angle_unit = unit

    def _toggle_unit(self) -> None:
        self.unit_combo.setCurrentText("rad" if self.unit_combo.currentText() == "deg" else "deg")
