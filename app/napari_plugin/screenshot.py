"""The README's napari picture: a recording and its motion-aware reconstruction, flow and TR map.

``python -m flexvox_app.napari_plugin.screenshot docs/screenshots/napari.png`` (``make napari-screenshot``)
simulates the drummer scene with photon and read noise (as ``flexvox simulate`` would), opens it
in napari through the plugin's reader, runs the *Motion-aware flow* dock widget and saves the
window. napari draws with OpenGL, which Qt's offscreen platform lacks: run it on a desktop or under
a virtual X server (``xvfb-run -a env QT_QPA_PLATFORM=xcb ...``, Mesa's software OpenGL).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

SUBFRAME = 37
"""The sub-frame shown (inside camera frame 2 of 4)."""


def make(out: Path) -> Path:
    """Write the screenshot to ``out`` (PNG) and return it."""
    import napari
    from qtpy.QtCore import QEventLoop
    from qtpy.QtWidgets import QApplication

    from flexvox_app.cli.main import main
    from flexvox_app.napari_plugin.widgets import MotionWidget

    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "drummer.zarr"
        code = main(["simulate", "drummer", "--frames", "4", "--size", "180x240", "-o", str(rec),
                     "--effects", "photon_noise,read_noise.sigma=2"])
        if code:
            raise SystemExit(code)
        viewer = napari.Viewer(show=True, title="flexvox in napari")
        viewer.window.resize(1500, 900)
        viewer.open(str(rec), plugin="flexvox")
        _, widget = viewer.window.add_plugin_dock_widget("flexvox", "Motion-aware flow")
        assert isinstance(widget, MotionWidget)
        worker = widget.start(start_thread=False)
        loop = QEventLoop()
        worker.finished.connect(loop.quit)
        worker.start()
        loop.exec_()
        viewer.layers.remove(next(x for x in viewer.layers if "ground truth" in x.name))
        order = ("coded frames", "motion-aware", "flow", "TR map")  # grid cells: top left, top right, ...
        ranked = sorted(viewer.layers, key=lambda x: next(i for i, w in enumerate(order) if w in x.name))
        for i, layer in enumerate(ranked):
            viewer.layers.move(viewer.layers.index(layer), i)
            layer.visible = True
        grid = viewer.canvas.grid
        grid.enabled, grid.shape, grid.spacing = True, (2, 2), 0.04
        viewer.dims.set_point(0, SUBFRAME / 240)
        QApplication.processEvents()
        viewer.reset_view()
        QApplication.processEvents()
        viewer.layers.selection.active = ranked[1]
        out.parent.mkdir(parents=True, exist_ok=True)
        viewer.screenshot(str(out), canvas_only=False, flash=False)
        viewer.close()
    return out


if __name__ == "__main__":  # pragma: no cover
    target = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/screenshots/napari.png")
    print(f"wrote {make(target)}")
