"""The device panel: each device's state, connect/disconnect, simulated or real, last error in words."""

from __future__ import annotations

import html

from PySide6.QtWidgets import (
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.rig_service import ROLES, RigService
from flexvox_app.gui.widgets.elided_label import ElidedLabel
from flexvox_app.gui.widgets.rich_text import AMBER, GREEN, GREY, RED
from rig_drivers.interfaces import DeviceState

STATE_COLOUR = {DeviceState.CLOSED: GREY, DeviceState.OPEN: AMBER, DeviceState.ENABLED: GREEN}


def _detail(service: RigService, role: str) -> str:
    dev = service.device(role)
    if dev is None or dev.state is not DeviceState.ENABLED:
        return ""
    rig = service.rig
    if role == "camera":
        return " · acquiring" if rig.camera.acquiring else ""
    if role == "projector":
        return f" · {rig.projector.run_state.value}"
    return " · running" if rig.sync is not None and rig.sync.running else ""


WIDTH = 240
"""The panel's fixed width (px): a state text that grows elides instead of pushing the workspaces sideways."""


class DevicePanel(QWidget):
    """One row per device of the rig; subscribes to the :class:`RigService`.

    Its width is fixed (:data:`WIDTH`); the state texts elide (the full text is their tooltip).
    """

    def __init__(self, service: RigService, parent: QWidget | None = None):
        super().__init__(parent)
        self.service = service
        simulated = service.simulated and "simulat" not in service.name.lower()
        box = QGroupBox(f"Rig: {service.name}" + (" (simulated)" if simulated else ""))
        grid = QGridLayout(box)
        self.rows: dict[str, dict] = {}
        for i, role in enumerate(ROLES):
            name = QLabel()
            name.setWordWrap(True)
            state = ElidedLabel()
            button = QPushButton()
            error = QLabel()
            error.setWordWrap(True)
            error.setStyleSheet(f"color: {RED}")
            grid.addWidget(QLabel(f"<b>{role}</b>"), 4 * i, 0)
            grid.addWidget(button, 4 * i, 1)
            grid.addWidget(state, 4 * i + 1, 0, 1, 2)
            grid.addWidget(name, 4 * i + 2, 0, 1, 2)
            grid.addWidget(error, 4 * i + 3, 0, 1, 2)
            button.clicked.connect(lambda _=False, r=role: self.toggle(r))
            self.rows[role] = {"name": name, "state": state, "button": button, "error": error}
        self.setFixedWidth(WIDTH)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addWidget(box)
        self.led_box = self._led_box()
        layout.addWidget(self.led_box)
        layout.addStretch(1)
        service.subscribe(self._on_change)
        self.destroyed.connect(lambda *_: service.unsubscribe(self._on_change))
        self.refresh()

    def _led_box(self) -> QGroupBox:
        """LED currents of a LightCrafter: red, green, blue PWM 0..255 and Apply (hidden for other projectors)."""
        box = QGroupBox("Projector LEDs")
        box.setToolTip("LED current as the PWM value the LightCrafter's LED driver takes: 0 = off, 255 = the most "
                       "current it gives. It sets the light in every open slot, and so the recording's "
                       "signal-to-noise; a rig profile's [projector] led_current sets it at connect.")
        row = QFormLayout()  # one colour a line: the panel is narrow
        self.led_spins = {}
        for colour in ("red", "green", "blue"):
            spin = QSpinBox()
            spin.setRange(0, 255)
            spin.setSuffix(" /255")
            spin.setAccessibleName(f"{colour} LED current (PWM, 0..255)")
            row.addRow(colour, spin)
            self.led_spins[colour] = spin
        self.led_apply = QPushButton("Apply")
        self.led_apply.clicked.connect(self.apply_led_currents)
        v = QVBoxLayout(box)
        v.addLayout(row)
        v.addWidget(self.led_apply)
        box.setVisible(self.service.has_led_control)
        self._load_led_currents()
        return box

    def _load_led_currents(self) -> None:
        values = self.service.led_currents()
        if values is not None:
            for spin, value in zip(self.led_spins.values(), values, strict=True):
                spin.setValue(int(value))

    def apply_led_currents(self) -> bool:
        """Send the three LED values to the projector (its row shows why when it cannot)."""
        return self.service.set_led_currents(*(spin.value() for spin in self.led_spins.values()))

    def toggle(self, role: str) -> None:
        """Connect a closed device, disconnect an open one."""
        dev = self.service.device(role)
        if dev is None:
            return
        if dev.state is DeviceState.CLOSED:
            if self.service.connect(role) and role == "projector" and self.service.has_led_control:
                self._load_led_currents()
        else:
            self.service.disconnect(role)

    def _on_change(self, role: str) -> None:
        self.refresh(role)

    def refresh(self, role: str | None = None) -> None:
        """Redraw one row (or all)."""
        for r in (role,) if role else ROLES:
            st = self.service.status(r)
            row = self.rows[r]
            kind = "simulated" if st.simulated else "real"
            row["name"].setText(f"{st.name} <i>({kind})</i>" if st.present else st.name)
            if not st.present:
                row["state"].setText("—")
                row["state"].setStyleSheet("")
                row["button"].setEnabled(False)
                row["button"].setText("Connect")
            elif self.service.held_by:  # opened and closed by its holder: held, whatever the moment's state
                row["state"].setText(f"● in use by {self.service.held_by}")
                row["state"].setStyleSheet(f"color: {AMBER}")
                row["button"].setEnabled(False)
                row["button"].setToolTip(f"in use by {self.service.held_by}: wait for it to end")
            else:
                colour = STATE_COLOUR[st.state]
                state = f"{st.state.value}{_detail(self.service, r)}"
                row["state"].setText(f"● {state}")
                row["state"].setStyleSheet(f"color: {colour}")
                row["button"].setEnabled(True)
                row["button"].setToolTip("")
                row["button"].setText("Connect" if st.state is DeviceState.CLOSED else "Disconnect")
            row["error"].setText(html.escape(in_gui_words(st.last_error)))
            row["error"].setVisible(bool(st.last_error))

    def state_text(self, role: str) -> str:
        """The state column's plain text (for tests and accessibility)."""
        return self.rows[role]["state"].text()
