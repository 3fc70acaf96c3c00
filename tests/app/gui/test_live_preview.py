"""The live motion-aware preview: it updates during live view and recording, says its resolution and rate,
and costs capture no frames."""

import re

import numpy as np
import pytest

from app.gui.capture.live_preview import FrameBuffer, LivePreview, preview_stride, reconstruct_preview
from app.gui.capture.workspace import CaptureWorkspace
from app.gui.models.rig_service import RigService
from flexvox_core.design import design_code
from flexvox_core.forward import tiled_code
from rig_drivers.interfaces import Frame

from .conftest import small_rig


def _frame(i, shape=(48, 64), value=0.5):
    return Frame(np.full(shape, value, np.float32), frame_id=i, timestamp_s=i / 60)


def test_the_stride_keeps_the_codes_layout():
    assert preview_stride((48, 64), (4, 4)) == 1
    s = preview_stride((1200, 1920), (3, 5), max_pixels=160 * 120)
    assert s % 15 == 1 and -(-1200 // s) * -(-1920 // s) <= 160 * 120
    code = design_code((3, 5)).code
    full = tiled_code(code, 120, 150)  # (K, H, W): the slots each pixel opens in
    np.testing.assert_array_equal(full[:, ::16, ::16], tiled_code(code, 8, 10))
    with pytest.raises(ValueError, match=r"`max_pixels` must be >= 1; got 0"):
        preview_stride((10, 10), (2, 2), 0)


def test_the_buffer_keeps_the_newest_consecutive_frames():
    b = FrameBuffer(3)
    for i in (0, 1, 2, 3):
        b.push(_frame(i))
    assert [f.frame_id for f in b.snapshot()] == [1, 2, 3]
    b.push(_frame(3))  # repeated: ignored
    b.push(_frame(7))  # a gap: a new run starts
    assert [f.frame_id for f in b.snapshot()] == [7] and b.version == 5


def test_a_preview_of_a_still_grey_scene_is_that_grey():
    code = design_code((2, 4)).code
    r = reconstruct_preview([_frame(i) for i in range(3)], code)
    assert r.video.shape == (8, 48, 64) and r.frame_id == 2 and r.n_frames == 3 and r.stride == 1
    np.testing.assert_allclose(r.video, 0.5, atol=0.02)


@pytest.fixture
def capture(qtbot, settings, runner):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    ws.resize(1300, 800)
    ws.code.rate.setValue(60.0)  # K = 16 at 60 Hz: a frame every 16.7 ms
    yield ws
    ws.shutdown()
    service.close()


def test_the_preview_updates_during_live_view_without_costing_frames(qtbot, capture):
    ws = capture
    assert ws.live_panel.preview_check.isChecked()
    jobs_at_once = []
    ws.live_panel.stream.frame.connect(lambda _: jobs_at_once.append(ws.live_panel.preview.runner.active))
    assert ws.start_live()
    qtbot.waitUntil(lambda: ws.live_panel.preview.runs >= 3, timeout=20_000)
    first = ws.live_panel.preview.result
    assert first.video.shape == (16, 48, 64)
    qtbot.waitUntil(lambda: ws.live_panel.preview.result is not first, timeout=10_000)  # keeps updating
    assert ws.live_panel.preview_panel.has_image() and ws.live_panel.preview_panel.image.image.shape == (48, 64)
    assert re.match(r"motion-aware preview: frame \d+, sub-frame \d+/16", ws.live_panel.preview_panel.title.text())
    assert re.match(r"preview: 64×48 \(every pixel\), [123] frames?, \d+\.\d Hz, \d\.\d\d s per run · \d+ of \d+ "
                    r"camera frames previewed \(newest wins\)", ws.live_panel.preview_label.text())
    assert ws.live_panel.preview.rate_hz > 0
    assert max(jobs_at_once) <= 1  # one reconstruction at a time, never a queue
    preview = ws.live_panel.preview
    assert preview.offered > preview.runs  # frames arrive faster than previews: the newest wins
    assert ws.live_panel.stats.received >= 20 and ws.live_panel.stats.dropped == 0
    ws.stop_live()
    assert not ws.live_panel.preview.enabled and ws.live_panel.preview_label.text().startswith("preview (stopped):")


def test_a_recording_with_the_preview_on_drops_nothing(qtbot, capture, tmp_path):
    ws = capture
    ws.record_panel.path_edit.setText(str(tmp_path / "run.zarr"))
    ws.record_panel.frames_box.setValue(60)  # one second at 60 Hz
    ws.record_panel.truth_check.setChecked(False)
    with qtbot.waitSignal(ws.recording_finished, timeout=30_000) as finished:
        assert ws.record()
    result = finished.args[0]
    assert ws.live_panel.preview.runs >= 1, "the preview ran during the recording"
    assert result.ok and result.frames_in_recording == 60
    assert result.stats.drops == 0 and result.stats.queue_drops == 0
    assert not ws.live_panel.preview.enabled


def test_newest_wins_one_run_at_a_time(qtbot):
    preview = LivePreview(rest_fraction=0.0)
    preview.set_code(design_code((2, 4)).code, (2, 4))
    preview.start()
    for i in range(30):
        preview.feed(_frame(i))
        assert preview.runner.active <= 1
    qtbot.waitUntil(lambda: not preview.busy and preview.runs >= 1, timeout=10_000)
    qtbot.waitUntil(lambda: preview.result is not None and preview.result.frame_id == 29, timeout=10_000)
    assert preview.runs < 30 and preview.offered == 30
    assert preview.shutdown(5000)


def test_the_preview_can_be_switched_off(qtbot, capture):
    ws = capture
    ws.live_panel.preview_check.setChecked(False)
    assert ws.start_live()
    qtbot.waitUntil(lambda: ws.live_panel.stats.received >= 5, timeout=10_000)
    assert ws.live_panel.preview.runs == 0 and ws.live_panel.preview_label.text() == "preview: off"
    assert not ws.settings.get_bool("capture/preview", True)
