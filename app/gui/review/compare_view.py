"""Compare tab of the Review workspace: two reconstructions side by side, views linked.

Each result in the lists is named by its label: method, time, where it ran and its score, the PSNR against the
ground truth where the recording has one, else the estimate from the recording alone once it is made
(``estimated PSNR NN.NN dB (± …)``; the whole estimate line is the item's tooltip, and a method the estimate does
not serve says ``no estimate: <why>`` there).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QComboBox, QFormLayout, QGridLayout, QWidget

from flexvox_app.gui.models.jobs import ReconstructionResult
from flexvox_app.gui.widgets.adaptive_split import AdaptiveSplit
from flexvox_app.gui.widgets.image_panel import ImagePanel


class CompareView(QWidget):
    """Pick two results (A, B); both show the same sub-frame, panned and zoomed together (side by side, or A above B
    where the view is narrow)."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.box_a = QComboBox()
        self.box_b = QComboBox()
        self.panel_a = ImagePanel("A")
        self.panel_b = ImagePanel("B")
        self.panel_b.view.setXLink(self.panel_a.view)
        self.panel_b.view.setYLink(self.panel_a.view)
        for box in (self.box_a, self.box_b):  # a result's label is long: each box takes the whole width
            box.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon)
        grid = QGridLayout(self)
        picks = QFormLayout()
        picks.addRow("A", self.box_a)
        picks.addRow("B", self.box_b)
        grid.addLayout(picks, 0, 0, 1, 2)
        grid.addWidget(AdaptiveSplit(self.panel_a, self.panel_b), 1, 0, 1, 2)  # A above B in a narrow view
        grid.setRowStretch(1, 1)
        self._results: list[ReconstructionResult] = []
        self._truth = None
        self._K = 1
        self._s = 0
        self.box_a.currentIndexChanged.connect(lambda _: self.show_subframe(self._s))
        self.box_b.currentIndexChanged.connect(lambda _: self.show_subframe(self._s))
        self.show_subframe(0)

    def set_results(self, results: list[ReconstructionResult], K: int, truth=None) -> None:
        """The full reconstructions to choose from (newest last: A = the one before, B = newest)."""
        self._results = list(results)
        self._K = K
        self._truth = truth
        for box in (self.box_a, self.box_b):
            box.blockSignals(True)
            box.clear()
            box.addItems([""] * len(self._results))
            box.blockSignals(False)
        self.update_labels()
        n = len(self._results)
        if n:
            self.box_a.setCurrentIndex(max(0, n - 2))
            self.box_b.setCurrentIndex(n - 1)
        self.show_subframe(self._s)

    def update_labels(self) -> None:
        """Name each result again (an estimate came in), keeping A and B as chosen."""
        for box in (self.box_a, self.box_b):
            for i, r in enumerate(self._results):
                box.setItemText(i, f"{i + 1}. {r.label()}")
                box.setItemData(i, tooltip(r), Qt.ItemDataRole.ToolTipRole)
        self.show_subframe(self._s)

    def select(self, a: int, b: int) -> None:
        """Choose results ``a`` and ``b`` (indices into the list)."""
        self.box_a.setCurrentIndex(a)
        self.box_b.setCurrentIndex(b)

    def show_subframe(self, s: int) -> None:
        """Show sub-frame ``s`` of both results."""
        self._s = s
        for box, panel, name in ((self.box_a, self.panel_a, "A"), (self.box_b, self.panel_b, "B")):
            i = box.currentIndex()
            if not 0 <= i < len(self._results):
                panel.clear("run reconstructions to compare them here")
                panel.set_title(name)
                continue
            r = self._results[i]
            j = min(s, r.video.shape[0] - 1)
            panel.set_image(r.video[j], levels=(0, 1))
            score = ""
            if self._truth is not None:
                from flexvox_core.metrics import psnr

                score = f" · this sub-frame {psnr(self._truth[j], r.video[j]):.2f} dB"
            elif r.estimate is not None and np.isfinite(r.estimate.per_frame[j // self._K]):
                score = f" · this frame estimated PSNR {r.estimate.per_frame[j // self._K]:.2f} dB"
            panel.set_title(f"{name}: {r.label()}{score}")


def tooltip(r: ReconstructionResult) -> str:
    """A result's label, and its whole estimate line or why it has none."""
    if r.estimate is not None:
        return f"{r.label()}\n{r.estimate.line()}"
    if r.no_estimate:
        return f"{r.label()}\nno estimate: {r.no_estimate}"
    return r.label()
