"""The plugin in napari's own viewer (``make_napari_viewer``), offscreen.

napari's canvas draws with OpenGL, which Qt's offscreen platform does not have (it has it only with an
X server, and even then never draws a QOpenGLWidget). napari asks OpenGL two things when a layer is
added — its extensions and its largest texture — so, where no OpenGL context can be made, the fixture
answers them for it; nothing is drawn offscreen anyway. Everything else is napari's: the viewer, its
plugin manager finding the installed manifest, the reader, the dock widgets, the worker.
"""

import pytest

pytest.importorskip("napari", reason="the napari extra is not installed: pip install 'flexvox[napari]'")

from flexvox_app.napari_plugin.widgets import MotionWidget, ReconstructWidget  # noqa: E402
from flexvox_core.methods import Method  # noqa: E402

pytestmark = pytest.mark.recording("fan", size=(24, 32), tile=(2, 2), scene_seed=3, noise_seed=1)

_NAPARI_GL_USERS = ("napari._vispy.layers.image", "napari._vispy.layers.base", "napari._vispy.layers.labels",
                    "napari._vispy.canvas")


@pytest.fixture
def viewer(qapp, monkeypatch, request):
    import importlib

    from qtpy.QtGui import QOpenGLContext

    if not QOpenGLContext().create():
        for name in _NAPARI_GL_USERS:
            module = importlib.import_module(name)
            for attr, answer in (("get_gl_extensions", lambda: "GL_ARB_texture_float"),
                                 ("get_max_texture_sizes", lambda: (16384, 2048))):
                if hasattr(module, attr):
                    monkeypatch.setattr(module, attr, answer)
    return request.getfixturevalue("make_napari_viewer")()


def test_napari_opens_a_recording_and_docks_reconstruct(viewer, qtbot, recording):
    viewer.open(str(recording), plugin="flexvox")
    assert [layer.name for layer in viewer.layers] == ["rec: coded frames", "rec: ground truth"]
    _, widget = viewer.window.add_plugin_dock_widget("flexvox", "Reconstruct")
    assert isinstance(widget, ReconstructWidget) and widget.recording_box.currentText() == str(recording.resolve())
    widget.method_box.setCurrentText("rebin")
    worker = widget.start(start_thread=False)
    with qtbot.waitSignal(worker.finished, timeout=60_000):
        worker.start()
    layer = viewer.layers[-1]
    assert layer.name == f"rec: {Method('rebin').label()}" and layer.data.shape == (24, 24, 32)
    viewer.dims.set_point(0, 5 / 60)
    assert round(viewer.layers[0]._data_slice.point[0]) == 1 and round(layer._data_slice.point[0]) == 5


def test_the_motion_widget_docks_with_the_methods_that_return_flow(viewer):
    _, widget = viewer.window.add_plugin_dock_widget("flexvox", "Motion-aware flow")
    assert isinstance(widget, MotionWidget)
    assert [widget.method_box.itemText(i) for i in range(widget.method_box.count())] == ["motion-aware"]
