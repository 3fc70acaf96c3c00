"""The Devices dock: the device panel, which folds to a narrow strip to give a small screen to the workspaces.

Open, it is the :class:`~flexvox_app.gui.widgets.device_panel.DevicePanel` under a header with a fold button (◂).
Folded, it is a strip :data:`STRIP_WIDTH` pixels wide: an unfold button (▸) and one coloured dot per
device (its state in the tooltip), so a device that drops out still shows. Whether it is folded persists
in the settings (``window/devices_folded``).
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QDockWidget, QHBoxLayout, QLabel, QSizePolicy, QToolButton, QVBoxLayout, QWidget

from flexvox_app.gui.models.rig_service import ROLES, RigService
from flexvox_app.gui.widgets.device_panel import STATE_COLOUR, DevicePanel
from flexvox_app.gui.widgets.rich_text import AMBER
from flexvox_app.gui.widgets.settings import AppSettings

STRIP_WIDTH = 28
"""The folded dock's width (px)."""
FOLDED_KEY = "window/devices_folded"


class DeviceDock(QDockWidget):
    """The device panel in a dock that folds (see the module docstring).

    Parameters
    ----------
    panel : DevicePanel
    service : RigService
    settings : AppSettings
    """

    folded_changed = Signal(bool)

    def __init__(self, panel: DevicePanel, service: RigService, settings: AppSettings, parent: QWidget | None = None):
        super().__init__("Devices", parent)
        self.setObjectName("devices")
        self.panel = panel
        self.service = service
        self.settings = settings
        self.setFeatures(QDockWidget.DockWidgetFeature.NoDockWidgetFeatures)
        self.setTitleBarWidget(QWidget())  # the header below has the title and the fold button

        self.fold_button = QToolButton()
        self.fold_button.setArrowType(Qt.ArrowType.LeftArrow)
        self.fold_button.setAutoRaise(True)
        self.fold_button.setToolTip("fold the Devices panel to a strip (more room for the workspaces)")
        header = QHBoxLayout()
        header.setContentsMargins(4, 2, 2, 0)
        header.addWidget(QLabel("<b>Devices</b>"))
        header.addStretch(1)
        header.addWidget(self.fold_button)
        self.open_body = QWidget()
        ov = QVBoxLayout(self.open_body)
        ov.setContentsMargins(0, 0, 0, 0)
        ov.setSpacing(0)
        ov.addLayout(header)
        ov.addWidget(panel, 1)

        self.unfold_button = QToolButton()
        self.unfold_button.setArrowType(Qt.ArrowType.RightArrow)
        self.unfold_button.setAutoRaise(True)
        self.unfold_button.setToolTip("show the Devices panel")
        self.dots: dict[str, QLabel] = {}
        self.strip = QWidget()
        sv = QVBoxLayout(self.strip)
        sv.setContentsMargins(2, 2, 2, 2)
        sv.addWidget(self.unfold_button, 0, Qt.AlignmentFlag.AlignHCenter)
        for role in ROLES:
            dot = QLabel("●")
            dot.setAlignment(Qt.AlignmentFlag.AlignHCenter)
            self.dots[role] = dot
            sv.addWidget(dot)
        sv.addStretch(1)
        self.strip.setFixedWidth(STRIP_WIDTH)

        body = QWidget()
        bv = QHBoxLayout(body)
        bv.setContentsMargins(0, 0, 0, 0)
        bv.setSpacing(0)
        bv.addWidget(self.open_body)
        bv.addWidget(self.strip)
        body.setSizePolicy(QSizePolicy.Policy.Fixed, QSizePolicy.Policy.Preferred)
        self.setWidget(body)
        self.fold_button.clicked.connect(lambda: self.set_folded(True))
        self.unfold_button.clicked.connect(lambda: self.set_folded(False))
        service.subscribe(self._on_change)
        self.destroyed.connect(lambda *_: service.unsubscribe(self._on_change))
        self._refresh_dots()
        self.set_folded(settings.get_bool(FOLDED_KEY, False))

    @property
    def folded(self) -> bool:
        """True when only the strip shows."""
        return self.strip.isVisibleTo(self)

    def set_folded(self, folded: bool) -> None:
        """Fold the panel to the strip, or open it."""
        folded = bool(folded)
        self.open_body.setVisible(not folded)
        self.strip.setVisible(folded)
        self.settings.set(FOLDED_KEY, folded)
        self.folded_changed.emit(folded)

    def _on_change(self, role: str) -> None:
        self._refresh_dots()

    def _refresh_dots(self) -> None:
        for role, dot in self.dots.items():
            st = self.service.status(role)
            if not st.present:
                dot.setStyleSheet("")
                dot.setText("—")
                dot.setToolTip(f"{role}: none")
                continue
            dot.setText("●")
            dot.setStyleSheet(f"color: {AMBER if self.service.held_by else STATE_COLOUR[st.state]}")
            dot.setToolTip(f"{role}: {self.panel.state_text(role).lstrip('● ')}")
