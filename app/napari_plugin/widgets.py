"""The plugin's dock widgets: reconstruct the open recording; show motion-aware's flow and [TR, SR] map.

Both are the same widget with a different set of methods: *Reconstruct* offers every registered
method (:mod:`flexvox_core.methods.registry`), *Motion-aware flow* those that return the flow and
the TR map (``MethodSpec.extras``) — no method is named here. Each method's options are the shared
options form of the Review workspace (:class:`~flexvox_app.gui.widgets.options_form.OptionsForm`, a field per
option by its kind; the tensor and the division as text), checked by :class:`~flexvox_core.methods.Method`
as everywhere else.

The reconstruction runs off the GUI thread in napari's ``thread_worker`` with a progress bar in
napari's activity dock (one step per camera frame, advanced after each chunk) and Cancel (stops at
the next chunk boundary: :func:`~flexvox_app.napari_plugin.layers.reconstruction_steps`); the result is
added as layers (:func:`~flexvox_app.napari_plugin.layers.result_layers`). The widgets are qtpy's, over the same
PySide6 as the form.
"""

from __future__ import annotations

import threading

from qtpy.QtWidgets import (
    QComboBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.gui.widgets.options_form import OptionsForm
from flexvox_app.napari_plugin import layers
from flexvox_core.methods import DEFAULT, Method, chunk_plan, get, specs


class ReconstructWidget(QWidget):
    """Reconstruct a recording open in the viewer with a registered method and its options."""

    title = "Reconstruct"
    extras = False

    def __init__(self, napari_viewer, parent=None):
        super().__init__(parent)
        self.viewer = napari_viewer
        self.worker = None
        self._cancel: threading.Event | None = None
        self.recording_box = QComboBox()
        self.method_box = QComboBox()
        self.pages = QStackedWidget()
        self.forms: dict[str, OptionsForm] = {}
        for spec in self.offered():
            self.method_box.addItem(spec.name)
            self.method_box.setItemData(self.method_box.count() - 1, spec.title, 3)  # Qt.ToolTipRole
            form = OptionsForm(spec)
            self.forms[spec.name] = form
            self.pages.addWidget(form)
        if DEFAULT in self.forms:
            self.method_box.setCurrentText(DEFAULT)
        self.method_box.currentIndexChanged.connect(self.pages.setCurrentIndex)
        self.pages.setCurrentIndex(self.method_box.currentIndex())
        self.chunk_box = QSpinBox()
        self.chunk_box.setRange(1, 100_000)
        self.chunk_box.setValue(16)
        self.chunk_box.setToolTip("camera frames per chunk: memory follows the chunk; Cancel stops between chunks")
        self.run_button = QPushButton(self.title)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.run_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel)

        top = QFormLayout()
        top.addRow("recording", self.recording_box)
        top.addRow("method", self.method_box)
        buttons = QHBoxLayout()
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addWidget(self.pages)
        chunk = QFormLayout()
        chunk.addRow("frames per chunk", self.chunk_box)
        layout.addLayout(chunk)
        layout.addLayout(buttons)
        layout.addWidget(self.status)
        layout.addStretch(1)

        events = self.viewer.layers.events
        events.inserted.connect(self.refresh_recordings)
        events.removed.connect(self.refresh_recordings)
        self.refresh_recordings()

    # ------------------------------------------------------------------ what is offered
    def offered(self):
        """The methods this widget offers (all registered ones)."""
        return specs()

    def refresh_recordings(self, *_) -> None:
        """List the recordings the viewer's layers came from (newest first); keep the choice when it is still there."""
        current = self.recording_box.currentText()
        paths = []
        for layer in reversed(list(self.viewer.layers)):
            path = layers.recording_of(getattr(layer, "metadata", None))
            if path and path not in paths:
                paths.append(path)
        self.recording_box.blockSignals(True)
        self.recording_box.clear()
        self.recording_box.addItems(paths)
        if current in paths:
            self.recording_box.setCurrentText(current)
        self.recording_box.blockSignals(False)
        self.run_button.setEnabled(bool(paths) and self.worker is None)
        if not paths and self.worker is None:
            self.status.setText("open a flexvox recording (File > Open, a .zarr folder) to reconstruct it")

    def method(self, tile) -> Method:
        """The chosen method with the form's options (``ValueError`` naming a bad option)."""
        name = self.method_box.currentText()
        return Method(get(name).name, **self.forms[name].values(tile))

    # ------------------------------------------------------------------ running
    def start(self, *, start_thread: bool = True):
        """Reconstruct the chosen recording off the GUI thread; returns napari's worker (None when refused)."""
        from napari.qt.threading import create_worker

        from flexvox_core.recording import open_recording

        path = self.recording_box.currentText()
        if not path or self.worker is not None:
            return None
        try:
            rec = open_recording(path)
            method = self.method(rec.attrs["tile"])
        except ValueError as exc:
            self.status.setText(f"not started: {exc}")
            return None
        rates, K = rec.attrs["rates"], rec.K
        chunk = self.chunk_box.value()
        chunks = len(chunk_plan(rec.n_frames, chunk, method.overlap(K)))
        self._cancel = cancel = threading.Event()
        # napari's bar advances one step per yield: one per chunk.
        worker = create_worker(layers.reconstruction_steps, path, method, chunk_frames=chunk, extras=self.extras,
                               cancel=cancel, _start_thread=False, _ignore_errors=True,  # shown in the panel
                               _progress={"total": chunks, "desc": f"flexvox: {method.label()}"})
        worker.returned.connect(lambda out: self._done(out, method, path, rates["subframe_hz"], K))
        worker.errored.connect(self._failed)
        worker.aborted.connect(cancel.set)  # napari's own cancel (the activity dock) quits the worker only
        worker.aborted.connect(self._cancelled)
        worker.finished.connect(self._finished)
        self.worker = worker
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.status.setText(f"reconstructing {rec.n_frames} frames with {method.label()} ...")
        if start_thread:
            worker.start()
        return worker

    def cancel(self) -> None:
        """Stop the running reconstruction at the next chunk boundary; nothing is added."""
        if self.worker is None:
            return
        if self._cancel is not None:
            self._cancel.set()
        self.worker.quit()
        self.status.setText("cancelling ...")

    def _done(self, output, method, path, subframe_hz, K) -> None:
        added = []
        for data, kwargs, kind in layers.result_layers(output, method=method, recording=path, subframe_hz=subframe_hz,
                                                   K=K):
            added.append(getattr(self.viewer, f"add_{kind}")(data, **kwargs))
        where = " on the GPU" if getattr(output, "device", "cpu") == "cuda" else ""
        self.status.setText(f"{method.label()}{where}: added {len(added)} layer{'s' if len(added) > 1 else ''}")
        self.status.setToolTip("\n".join(layer.name for layer in added))

    def _failed(self, exc) -> None:
        if isinstance(exc, layers.Cancelled):
            self._cancelled()
        else:
            self.status.setText(f"failed: {exc}")

    def _cancelled(self) -> None:
        self.status.setText("cancelled; nothing was added")

    def _finished(self) -> None:
        self.worker = None
        self._cancel = None
        self.cancel_button.setEnabled(False)
        self.run_button.setEnabled(self.recording_box.count() > 0)


class MotionWidget(ReconstructWidget):
    """Motion-aware's flow (colour wheel) and [TR, SR] map as layers, with its reconstruction."""

    title = "Show flow and TR map"
    extras = True
    NEEDS = ("flow", "tr")

    def offered(self):
        """The methods that return the flow and the TR map (their ``extras``)."""
        return tuple(s for s in specs() if set(self.NEEDS) <= set(s.extras))
