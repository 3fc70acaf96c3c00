"""The plugin's dock widgets: reconstruct the open recording; show motion-aware's flow and [TR, SR] map.

Both are the same widget with a different set of methods: *Reconstruct* offers every registered
method (:mod:`flexvox_core.methods.registry`), *Motion-aware flow* those that return the flow and
the TR map (``MethodSpec.extras``) — no method is named here. Each method's options are built from
its :class:`~flexvox_core.methods.options.Option` list by kind (spin box, combo box, check box, a
text field for three numbers), checked by :class:`~flexvox_core.methods.Method` as everywhere else.

The reconstruction runs off the GUI thread in napari's ``thread_worker`` with a progress bar in
napari's activity dock (one step per camera frame, advanced after each chunk) and Cancel (stops at
the next chunk boundary: :func:`~app.napari_plugin.layers.reconstruction_steps`); the result is
added as layers (:func:`~app.napari_plugin.layers.result_layers`).
"""

from __future__ import annotations

import threading

from qtpy.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from app.napari_plugin import layers as fl
from flexvox_core.methods import DEFAULT, Method, chunk_plan, get, specs

_BIG = 1_000_000


def _fmt(value) -> str:
    if isinstance(value, tuple | list):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return "" if value is None else str(value)


class OptionsForm(QWidget):
    """One method's options, a widget per option by its kind; :meth:`values` for ``Method(name, **values)``."""

    def __init__(self, spec, parent=None):
        super().__init__(parent)
        self.spec = spec
        self.widgets: dict[str, QWidget] = {}
        form = QFormLayout(self)
        form.setContentsMargins(0, 0, 0, 0)
        for o in spec.options:
            w = self._widget(o)
            w.setToolTip(o.help or o.rule)
            w.setObjectName(o.name)
            self.widgets[o.name] = w
            form.addRow(o.label or o.name, w)

    @staticmethod
    def _widget(o) -> QWidget:
        if o.kind == "flag":
            w = QCheckBox()
            w.setChecked(bool(o.default))
        elif o.kind == "choice":
            w = QComboBox()
            w.addItems([str(c) for c in o.choices])
            w.setCurrentText(str(o.default))
        elif o.kind == "integer" and o.default is not None:
            w = QSpinBox()
            lo, hi, step = o.span or (0, _BIG, 1)
            w.setRange(int(lo), int(hi))
            w.setSingleStep(max(1, int(step)))
            w.setValue(int(o.default))
        elif o.kind == "number" and o.default is not None:
            w = QDoubleSpinBox()
            lo, hi, step = o.span or (0.0, float(_BIG), 0.1)
            w.setDecimals(3)
            w.setRange(float(lo), float(hi))
            w.setSingleStep(float(step))
            w.setValue(float(o.default))
        else:  # three numbers (a tensor, a division), or a number whose default is "the method decides"
            w = QLineEdit(_fmt(o.default))
            shown = o.shown_default if o.shown_default is not None else "the method's default"
            w.setPlaceholderText(f"empty: {shown}" if o.kind in ("number", "integer") else "a,b,c (empty: default)")
        return w

    def values(self, tile) -> dict:
        """The options as ``Method`` takes them (empty fields: None, the default).

        Raises
        ------
        ValueError
            A field whose text is not what its option's kind needs, naming the option and the rule.
        """
        from flexvox_core.divisions import parse_division
        from flexvox_core.methods.options import parse_triple

        out = {}
        for o in self.spec.options:
            w = self.widgets[o.name]
            if isinstance(w, QCheckBox):
                out[o.name] = w.isChecked()
            elif isinstance(w, QComboBox):
                out[o.name] = o.choices[w.currentIndex()]
            elif isinstance(w, QSpinBox | QDoubleSpinBox):
                out[o.name] = w.value()
            else:
                text = w.text().strip()
                if not text:
                    out[o.name] = None
                    continue
                try:
                    if o.kind == "triple":
                        out[o.name] = parse_triple(text, o.name)
                    elif o.kind == "division":
                        out[o.name] = parse_division(text.replace(",", "x"), tuple(tile))
                    else:
                        out[o.name] = float(text) if o.kind == "number" else int(text)
                except ValueError:
                    raise ValueError(f"`{o.name}` must be {o.rule}; got {text!r}") from None
        return out

    def set_value(self, name: str, value) -> None:
        """Set one option's field (tests, presets)."""
        w = self.widgets[name]
        if isinstance(w, QCheckBox):
            w.setChecked(bool(value))
        elif isinstance(w, QComboBox):
            w.setCurrentText(str(value))
        elif isinstance(w, QSpinBox | QDoubleSpinBox):
            w.setValue(value)
        else:
            w.setText(_fmt(value))


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
            path = fl.recording_of(getattr(layer, "metadata", None))
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
        worker = create_worker(fl.reconstruction_steps, path, method, chunk_frames=chunk, extras=self.extras,
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
        for data, kwargs, kind in fl.result_layers(output, method=method, recording=path, subframe_hz=subframe_hz,
                                                   K=K):
            added.append(getattr(self.viewer, f"add_{kind}")(data, **kwargs))
        where = " on the GPU" if getattr(output, "device", "cpu") == "cuda" else ""
        self.status.setText(f"{method.label()}{where}: added {len(added)} layer{'s' if len(added) > 1 else ''}")
        self.status.setToolTip("\n".join(layer.name for layer in added))

    def _failed(self, exc) -> None:
        if isinstance(exc, fl.Cancelled):
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
