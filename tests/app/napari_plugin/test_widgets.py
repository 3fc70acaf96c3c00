"""The napari plugin in napari: the manifest, the reader through npe2, and the dock widgets.

The widgets are tested on napari's ``ViewerModel`` (the viewer without its OpenGL canvas), which runs
under Qt's offscreen platform anywhere; ``test_viewer.py`` adds napari's own ``make_napari_viewer``
where OpenGL is available.
"""

import numpy as np
import pytest

napari = pytest.importorskip("napari", reason="the napari extra is not installed: pip install 'flexvox[napari]'")

from napari.components import ViewerModel  # noqa: E402

from flexvox_app.napari_plugin.widgets import MotionWidget, ReconstructWidget  # noqa: E402
from flexvox_core.methods import Method, names, specs  # noqa: E402

pytestmark = pytest.mark.recording("fan", size=(24, 32), tile=(2, 2), scene_seed=3, noise_seed=1)


@pytest.fixture
def viewer(qtbot):
    from napari.plugins import _initialize_plugins

    _initialize_plugins()
    return ViewerModel()


def test_the_manifest_is_valid_and_installed():
    import npe2

    pm = npe2.PluginManager.instance()
    pm.discover()
    manifest = pm.get_manifest("flexvox")
    assert [r.command for r in manifest.contributions.readers] == ["flexvox.get_reader"]
    assert [w.display_name for w in manifest.contributions.widgets] == ["Reconstruct", "Motion-aware flow"]
    manifest.validate_imports()  # every python_name resolves


def test_napari_opens_a_recording_and_a_reconstruction_with_the_plugin(viewer, recording, tmp_path):
    from flexvox_app.cli.main import main

    assert main(["reconstruct", str(recording), "--method", "rebin", "-o", str(tmp_path / "v.zarr")]) == 0
    viewer.open(str(recording), plugin="flexvox")
    viewer.open(str(tmp_path / "v.zarr"), plugin="flexvox")
    assert [layer.name for layer in viewer.layers] == ["rec: coded frames", "rec: ground truth",
                                                       f"v: {Method('rebin').label()}"]
    frames, truth, video = viewer.layers
    assert frames.scale[0] == pytest.approx(1 / 15) and truth.scale[0] == video.scale[0] == pytest.approx(1 / 60)
    # one slider in seconds: at sub-frame 5 (inside camera frame 1) the frames layer shows frame 1
    viewer.dims.set_point(0, 5 / 60)
    assert round(frames._data_slice.point[0]) == 1 and round(video._data_slice.point[0]) == 5


def test_the_widget_offers_every_registered_method_with_its_options(viewer, qtbot, recording):
    widget = ReconstructWidget(viewer)
    qtbot.addWidget(widget)
    methods = [widget.method_box.itemText(i) for i in range(widget.method_box.count())]
    assert methods == list(names())
    for spec in specs():
        assert list(widget.forms[spec.name].widgets) == [o.name for o in spec.option_specs]
    assert not widget.run_button.isEnabled() and "open a flexvox recording" in widget.status.text()
    viewer.open(str(recording), plugin="flexvox")
    assert widget.recording_box.currentText() == str(recording.resolve()) and widget.run_button.isEnabled()
    widget.method_box.setCurrentText("diffusion")
    widget.forms["diffusion"].set_value("tensor", (0.2, 0.3, 1.0))
    widget.forms["diffusion"].set_value("time", 2.5)
    assert widget.method((2, 2)) == Method("diffusion", tensor=(0.2, 0.3, 1.0), time=2.5)
    assert widget.pages.currentWidget() is widget.forms["diffusion"]
    # A default that depends on the code is said in words, not as the number it is at K = 16 (the Review form's
    # field: the two front ends show one form).
    refine = widget.forms["motion-aware"].widgets["refine_time"]
    assert refine.text() == "default ((K/16)²)" and widget.method((2, 2)).name == "diffusion"
    assert Method("motion-aware", **widget.forms["motion-aware"].values((2, 2))).refine_time is None


def test_a_bad_option_is_named_and_nothing_starts(viewer, qtbot, recording):
    widget = ReconstructWidget(viewer)
    qtbot.addWidget(widget)
    viewer.open(str(recording), plugin="flexvox")
    widget.method_box.setCurrentText("diffusion")
    widget.forms["diffusion"].set_value("tensor", "1,2")
    assert widget.start() is None
    assert widget.status.text() == "not started: `tensor` must be three numbers separated by commas; got '1,2'"
    widget.forms["diffusion"].set_value("tensor", "-1,0.1,1")
    assert widget.start() is None and widget.status.text().startswith("not started: `tensor` must be")


def test_reconstruct_runs_off_the_gui_thread_and_adds_the_result(viewer, qtbot, recording):
    widget = ReconstructWidget(viewer)
    qtbot.addWidget(widget)
    viewer.open(str(recording), plugin="flexvox")
    widget.method_box.setCurrentText("rebin")
    widget.chunk_box.setValue(2)
    steps = []
    worker = widget.start(start_thread=False)
    worker.yielded.connect(steps.append)
    assert worker.pbar.total == 3 and not widget.run_button.isEnabled() and widget.cancel_button.isEnabled()
    with qtbot.waitSignal(worker.finished, timeout=60_000):
        worker.start()
    assert steps == [2, 2, 2]
    layer = viewer.layers[-1]
    assert layer.name == f"rec: {Method('rebin').label()}" and layer.data.shape == (24, 24, 32)
    assert layer.scale[0] == pytest.approx(1 / 60) and layer.metadata["flexvox"]["method"]["name"] == "rebin"
    assert widget.status.text() == f"{Method('rebin').label()}: added 1 layer" and widget.status.toolTip() == layer.name
    assert widget.worker is None and widget.run_button.isEnabled() and not widget.cancel_button.isEnabled()


def test_cancel_adds_nothing(viewer, qtbot, recording):
    widget = ReconstructWidget(viewer)
    qtbot.addWidget(widget)
    viewer.open(str(recording), plugin="flexvox")
    count = len(viewer.layers)
    worker = widget.start(start_thread=False)
    widget.cancel()  # before the first chunk: the worker stops at once
    with qtbot.waitSignal(worker.finished, timeout=60_000):
        worker.start()
    assert len(viewer.layers) == count and widget.status.text() == "cancelled; nothing was added"
    assert widget.worker is None and widget.run_button.isEnabled()


def test_a_failure_is_shown_not_raised(viewer, qtbot, recording):
    widget = ReconstructWidget(viewer)
    qtbot.addWidget(widget)
    viewer.open(str(recording), plugin="flexvox")
    worker = widget.start(start_thread=False)
    import shutil

    shutil.rmtree(recording / "frames" / "c")  # the frames' chunks vanish before the run reads them
    with qtbot.waitSignal(worker.finished, timeout=60_000):
        worker.start()
    assert widget.status.text().startswith("failed: ") and "rec.zarr" in widget.status.text()


@pytest.mark.recording(frames=3, size=(32, 40), tile=(4, 4), scene_seed=2, noise_seed=1, name="moving.zarr")
def test_the_motion_widget_adds_the_flow_wheel_and_the_tr_map(viewer, qtbot, recording):
    widget = MotionWidget(viewer)
    qtbot.addWidget(widget)
    offered = [widget.method_box.itemText(i) for i in range(widget.method_box.count())]
    assert offered == [s.name for s in specs() if {"flow", "tr"} <= set(s.extras)] and offered
    viewer.open(str(recording), plugin="flexvox")
    worker = widget.start(start_thread=False)
    with qtbot.waitSignal(worker.finished, timeout=120_000):
        worker.start()
    video, flow, tr = viewer.layers[-3:]
    assert video.name.startswith("moving: motion-aware") and video.data.shape == (48, 32, 40)
    assert flow.rgb and flow.data.shape == (48, 32, 40, 3) and flow.data.dtype == np.uint8
    assert tr.name == "moving: TR map (1 = high SR, 16 = high TR; SR = 1/TR)" and tuple(tr.contrast_limits) == (1, 16)
    assert tr.colormap.name == "viridis" and all(x.scale[0] == pytest.approx(1 / 240) for x in (video, flow, tr))
