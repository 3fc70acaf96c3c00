"""Motion tab of the Review workspace: the flow (colour wheel or quiver) and the per-voxel resolution map."""

from __future__ import annotations

import numpy as np
from PySide6.QtWidgets import QButtonGroup, QHBoxLayout, QLabel, QRadioButton, QVBoxLayout, QWidget

from flexvox_app.gui.models.jobs import ReconstructionResult
from flexvox_app.gui.widgets.adaptive_split import AdaptiveSplit
from flexvox_app.gui.widgets.image_panel import ImagePanel
from flexvox_core.flow import flow_to_color, quiver_image

NO_FLOW = "no flow yet: reconstruct with motion-aware (or preview it) to see the flow and the resolution map"


class MotionView(QWidget):
    """Flow and resolution map of a motion-aware result at one sub-frame."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.color = QRadioButton("colour wheel")
        self.color.setToolTip("hue = direction, saturation = speed")
        self.quiver = QRadioButton("quiver")
        self.quiver.setToolTip("arrows ×3 over the reconstruction")
        self.color.setChecked(True)
        group = QButtonGroup(self)
        group.addButton(self.color)
        group.addButton(self.quiver)
        self.flow_panel = ImagePanel("optical flow")
        self.map_panel = ImagePanel("effective temporal resolution TR per voxel (SR = 1/TR)", colormap="viridis")
        self.note = QLabel(NO_FLOW)
        self.note.setWordWrap(True)
        top = QHBoxLayout()
        top.addWidget(self.color)
        top.addWidget(self.quiver)
        top.addStretch(1)
        panels = AdaptiveSplit(self.flow_panel, self.map_panel)  # one above the other in a narrow view
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addWidget(self.note)
        layout.addWidget(panels, 1)
        self._result: ReconstructionResult | None = None
        self._shown: ReconstructionResult | None = None
        self._n_subframes = 0
        self._top = 1.0
        self._K = 1
        self._s = 0
        self.color.toggled.connect(lambda _: self.show_subframe(self._s))
        self.flow_panel.clear(NO_FLOW)
        self.map_panel.clear("")

    def set_result(self, result: ReconstructionResult | None, K: int, *, shown: ReconstructionResult | None = None
                   ) -> None:
        """Show ``result`` (its flow, if it has one) for a code with K slots; ``shown`` is what the reconstruction
        panel shows (when it is another result, the note says so)."""
        self._result = result if result is not None and result.flow is not None else None
        self._shown = shown
        self._K = K
        if self._result is not None:
            mag = np.hypot(self._result.flow[..., 0], self._result.flow[..., 1])
            self._top = max(float(np.quantile(mag, 0.995)), 0.25)
        self.show_subframe(self._s)

    @property
    def mode(self) -> str:
        """"color" or "quiver"."""
        return "color" if self.color.isChecked() else "quiver"

    def set_length(self, n_subframes: int) -> None:
        """The recording's sub-frame count (the note says "sub-frame s/N", as the player does)."""
        self._n_subframes = int(n_subframes)

    def show_subframe(self, s: int) -> None:
        """Draw sub-frame ``s`` of the recording (if the result covers it)."""
        self._s = s
        r = self._result
        if r is None:
            self.note.setText(NO_FLOW)
            self.flow_panel.clear(NO_FLOW)
            self.map_panel.clear("")
            return
        i = s - r.first_frame * self._K
        kind = "preview" if r.extra.get("preview") else "full result"
        if not 0 <= i < r.video.shape[0]:
            first = r.first_frame + 1
            self.note.setText(f"sub-frame {s + 1} is outside this {kind} (frames {first}–"
                              f"{first + r.video.shape[0] // self._K - 1}): pause to preview it here")
            self.flow_panel.clear("outside the result")
            self.map_panel.clear("")
            return
        flow = r.flow[i]
        total = f"/{self._n_subframes}" if self._n_subframes else ""
        note = f"{r.method.label()} ({kind}) · sub-frame {s + 1}{total}"
        if self.mode == "color":
            note += f" · colour saturates at {self._top:.2f} px/sub-frame"
        if self._shown is not None and self._shown is not r:
            note += f" · the Frames tab shows {self._shown.method.label()}"
        self.note.setText(note)
        if self.mode == "color":
            self.flow_panel.set_image(flow_to_color(flow, max_magnitude=self._top))
            self.flow_panel.set_title("optical flow: colour wheel")
        else:
            step = max(6, min(flow.shape[:2]) // 20)
            self.flow_panel.set_image(quiver_image(r.video[i], flow, step=step))
            self.flow_panel.set_title("optical flow: quiver")
        self.map_panel.set_image(r.tr[i], levels=(1, self._K))
        self.map_panel.set_title(f"effective TR per voxel, 1 (high SR) … {self._K} (high TR)")
