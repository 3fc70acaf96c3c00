"""Helpers the GUI tests share: a widget as painted, and a reconstruction run through the Review workspace."""

import numpy as np
from PySide6.QtGui import QImage


def grab(widget) -> np.ndarray:
    """The widget as painted, (H, W, 3) uint8 RGB."""
    image = widget.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    h, w = image.height(), image.width()
    buf = np.frombuffer(image.constBits(), np.uint8, count=image.bytesPerLine() * h)
    return buf.reshape(h, image.bytesPerLine())[:, : 3 * w].reshape(h, w, 3).copy()


def reconstruct(qtbot, ws, method: str, position: float | None = None, **knobs):
    """Reconstruct with ``method`` (its ``knobs`` set in the form) and wait for the result, which it returns."""
    ws.form.set_method_name(method)
    if position is not None:
        ws.form.set_position(position)
    for name, value in knobs.items():
        ws.form.widget(name).setValue(value)
    n = len(ws.results)
    with qtbot.waitSignal(ws.result_added, timeout=30_000):
        ws.reconstruct_button.click()
    assert len(ws.results) == n + 1
    return ws.results[-1]


def truth_window(qtbot, settings):
    """The main window on a mock rig of the strobe scene (4x4 code, 120x160 at 15 Hz), its live preview off."""
    from flexvox_app.gui.application import build_window
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="strobe", subframes=17 * 16, seed=0, clock=VirtualClock())
    w = build_window(rig, settings=settings)
    qtbot.addWidget(w)
    w.capture.live_panel.preview_check.setChecked(False)
    return w
