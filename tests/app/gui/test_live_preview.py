"""The live motion-aware preview: it updates during live view and recording, says its resolution and rate,
and costs capture no frames."""

import re

import numpy as np
import pytest

from flexvox_app.capture.live_preview import (
    FrameBuffer,
    PixelCost,
    PreviewReconstructor,
    Region,
    preview_region,
    reconstruct_preview,
)
from flexvox_app.gui.capture.live_preview import LivePreview
from flexvox_app.gui.capture.workspace import CaptureWorkspace
from flexvox_app.gui.models.rig_service import RigService
from flexvox_core.design import design_code
from flexvox_core.forward import capture as capture_frames
from flexvox_core.forward import tiled_code
from flexvox_core.simulate.scenes import render_scene
from rig_drivers.interfaces import Frame

from .conftest import small_rig


def _frame(i, shape=(48, 64), value=0.5):
    return Frame(np.full(shape, value, np.float32), frame_id=i, timestamp_s=i / 60)


def test_the_region_is_the_whole_frame_when_it_fits_else_whole_tiles_at_full_resolution():
    assert preview_region((48, 64), (4, 4), 48 * 64) == Region(0, 48, 0, 64)
    r = preview_region((480, 640), (3, 5), 160 * 120)
    assert r.y0 % 3 == 0 and r.x0 % 5 == 0 and r.pixels <= 160 * 120 and r.shape[0] % 3 == 0
    assert abs(r.centre[0] - 240) <= 3 and abs(r.centre[1] - 320) <= 5  # the frame's centre by default
    corner = preview_region((480, 640), (4, 4), 100 * 100, centre=(0, 1000))  # clamped inside the frame
    assert corner.y0 == 0 and corner.x1 == 640
    tiny = preview_region((480, 640), (4, 4), 10)
    assert tiny.shape == (32, 32)  # never below MIN_SIDE
    # The crop is a capture of the same code: its pixel (y, x) opens as the code's (y mod m, x mod n).
    code = design_code((3, 5)).code
    full = tiled_code(code, 480, 640)
    np.testing.assert_array_equal(r.crop(full), tiled_code(code, *r.shape))
    with pytest.raises(ValueError, match=r"`max_pixels` must be > 0; got 0"):
        preview_region((10, 10), (2, 2), 0)


def test_the_region_follows_the_measured_cost_of_a_pixel():
    cost = PixelCost(runs=3)
    assert cost.pixels_for(0.6, default=19200) == 19200  # before any run
    cost.add(0.3, 64 * 48)  # 0.3 s for 3072 pixels: 6144 fit in 0.6 s
    assert cost.pixels_for(0.6, default=1) == pytest.approx(6144)
    for _ in range(3):
        cost.add(3.0, 64 * 48)  # a busy machine: the region shrinks ...
    assert cost.pixels_for(0.6, default=1) == pytest.approx(614.4)
    for _ in range(2):
        cost.add(0.15, 32 * 32)  # ... and grows back with the next quick runs (the median of the last 3)
    assert cost.pixels_for(0.6, default=1) == pytest.approx(4096)


def test_the_fast_preview_reconstructs_the_whole_frame_with_nc():
    code = design_code((2, 4)).code
    r = reconstruct_preview([_frame(i) for i in range(3)], code, method="nc")
    assert r.method == "nc" and r.whole_frame and r.video.shape == (8, 48, 64)
    np.testing.assert_allclose(r.video, 0.5, atol=1e-5)
    with pytest.raises(ValueError, match=r"`method` must be one of motion-aware, nc; got 'gap-tv'"):
        reconstruct_preview([_frame(0)], code, method="gap-tv")


def test_the_preview_method_is_chosen_in_the_panel_and_kept(qtbot, capture):
    ws = capture
    panel = ws.live_panel
    panel.preview_method.setCurrentIndex(panel.preview_method.findData("nc"))
    assert panel.preview.method == "nc" and ws.settings.get_str("capture/preview_method") == "nc"
    assert ws.start_live()
    qtbot.waitUntil(lambda: panel.preview.result is not None, timeout=20_000)
    assert panel.preview.result.method == "nc" and panel.preview.result.whole_frame
    assert panel.preview_label.text().startswith("nc preview on the CPU: 64×48 (the whole frame)")
    assert panel.preview_panel.title.text().startswith("nc preview: camera frame")
    ws.stop_live()
    with pytest.raises(ValueError, match=r"`method` must be one of motion-aware, nc; got 'rebin'"):
        panel.preview.set_method("rebin")


def test_a_run_started_before_a_change_neither_costs_nor_shows():
    preview = LivePreview()
    preview.set_code(design_code((2, 4)).code, (2, 4))
    preview.start()
    stale = reconstruct_preview([_frame(0)], design_code((2, 4)).code)
    before = preview._generation
    preview.set_method("nc")  # the operator switched while a motion-aware run was going
    preview._on_result(stale, before)
    assert preview.result is None and preview.runs == 0 and preview.cost.pixels_for(0.6, default=-1) == -1
    preview._on_result(stale, preview._generation)  # a run of the current generation counts
    assert preview.result is stale and preview.runs == 1
    assert preview.shutdown(5000)


def test_the_whole_frame_comes_back_once_it_fits_again():
    preview = LivePreview(budget_s=0.6)
    preview.set_code(design_code((4, 4)).code, (4, 4))
    preview.region = preview_region((480, 640), (4, 4), 0.85 * 480 * 640)  # a region left by a busy spell
    preview.cost.add(0.01, 100 * 100)  # quick runs now: millions of pixels fit in the budget
    assert preview._next_region((480, 640)).covers((480, 640))
    preview.region = preview_region((480, 640), (4, 4), 100 * 100)
    preview.cost.clear()
    preview.cost.add(0.6, 110 * 110)  # about the same size fits: the region stays where it is
    assert preview._next_region((480, 640)) == preview.region
    assert preview.shutdown(5000)


def test_a_busy_machine_previews_a_region_never_a_subsampled_frame(qtbot):
    preview = LivePreview(rest_fraction=0.0, budget_s=0.6)
    preview.set_code(design_code((2, 4)).code, (2, 4))
    preview.cost.add(6.0, 64 * 48)  # as if the last run had taken 6 s for the whole frame
    preview.start()
    preview.set_centre(40, 60)
    preview.feed(_frame(0))
    qtbot.waitUntil(lambda: preview.result is not None, timeout=10_000)
    r = preview.result
    assert not r.whole_frame and r.region.pixels < 64 * 48 and r.video.shape[1:] == r.region.shape
    assert r.region.y1 == 48 and r.region.x1 == 64  # around the operator's point, inside the frame
    assert re.search(r"a region of the 64×48 frame at full resolution, as the whole frame would take about "
                     r"\d+\.\d s a run, over the 0\.6 s budget; it grows when runs get faster: drag it on the "
                     r"live view",
                     preview.text()), preview.text()
    assert preview.shutdown(5000)


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
    # The frame before the newest, over the window of all three.
    assert r.video.shape == (8, 48, 64) and r.frame_id == 1 and r.n_frames == 3 and r.whole_frame
    np.testing.assert_allclose(r.video, 0.5, atol=0.02)
    alone = reconstruct_preview([_frame(0)], code)  # a single frame: shown alone
    assert alone.frame_id == 0 and alone.n_frames == 1
    np.testing.assert_allclose(alone.video, 0.5, atol=0.02)


def _moving(i, shape=(48, 64)):
    truth = render_scene("balls", 8 * (i + 1), *shape)[8 * i: 8 * (i + 1)]
    return Frame(capture_frames(truth, design_code((2, 4)).code)[0], frame_id=i, timestamp_s=i / 15)


def test_a_preview_that_keeps_up_pushes_one_new_frame_and_reuses_the_rest():
    code = design_code((2, 4)).code
    frames = [_moving(i) for i in range(5)]
    rec = PreviewReconstructor()
    first = rec.run(frames[0:3], code)
    stream = rec._stream
    assert first.frame_id == 1 and stream.pushed == 3
    hits = stream.memo.hits
    second = rec.run(frames[1:4], code)  # the next camera frame arrived: one push, one frame reconstructed
    assert rec._stream is stream and stream.pushed == 4 and second.frame_id == 2
    assert stream.memo.hits > hits  # flow pairs of the earlier window found again
    fresh = reconstruct_preview(frames[1:4], code)  # the same picture as a run from scratch
    np.testing.assert_allclose(second.video, fresh.video, rtol=0, atol=1e-5)
    # Another region: a new stream.
    rec.run(frames[2:5], code, Region(0, 24, 0, 32))
    assert rec._stream is not stream and rec._stream.pushed == 3
    # Fallen behind by more than the window (frames 0-2, then 5-7): a new stream, the newest but one shown.
    rec = PreviewReconstructor()
    rec.run([_moving(i) for i in range(3)], code)
    first = rec._stream
    later = rec.run([_moving(i) for i in range(5, 8)], code)
    assert rec._stream is not first and later.frame_id == 6 and later.n_frames == 3


def test_a_float_camera_in_counts_is_previewed_not_refused():
    # A colour GenICam camera gives float32 counts 0-255: the preview scales them, it does not stop.
    code = design_code((2, 4)).code
    frames = [Frame(np.full((32, 32), 128.0, np.float32), frame_id=i, timestamp_s=i / 15) for i in range(3)]
    for method in ("motion-aware", "nc"):
        r = reconstruct_preview(frames, code, method=method)
        np.testing.assert_allclose(r.video, 0.5, atol=0.02)  # 128 of 256
    alone = reconstruct_preview(frames[:1], code)
    np.testing.assert_allclose(alone.video, 0.5, atol=0.02)


def test_a_float_camera_brightening_past_its_first_scale_is_not_clipped_white():
    # The stream's scale is fixed by its first frames (100 counts -> 128); frames of 200 counts later start a
    # new stream at 256, as a fresh run would show them, instead of saturating at 1 for the stream's life.
    code = design_code((2, 4)).code
    counts = [100.0] * 3 + [200.0] * 6
    frames = [Frame(np.full((32, 32), c, np.float32), frame_id=i, timestamp_s=i / 15) for i, c in enumerate(counts)]
    rec = PreviewReconstructor()
    for k in range(len(frames) - 2):
        run = frames[k:k + 3]
        got = rec.run(run, code)
        np.testing.assert_allclose(got.video.mean(), reconstruct_preview(run, code).video.mean(), atol=0.02)
    np.testing.assert_allclose(got.video, 200 / 256, atol=0.02)


@pytest.mark.parametrize("region", [Region(0, 100, 0, 100), Region(-4, 44, 0, 64), Region(8, 8, 0, 64),
                                    Region(16, 8, 0, 64)])
def test_a_region_outside_the_frame_is_refused_naming_it(region):
    with pytest.raises(ValueError, match=r"a preview region must be a non-empty part of the 48x64 frame "
                                         r"\(0 <= y0 < y1 <= 48, 0 <= x0 < x1 <= 64\); got Region\("):
        reconstruct_preview([_frame(i) for i in range(3)], design_code((2, 4)).code, region)


@pytest.mark.parametrize(("kw", "message"), [
    ({"budget_s": 0.0}, r"`budget_s` must be a positive finite number of seconds; got 0.0"),
    ({"budget_s": float("nan")}, r"`budget_s` must be a positive finite number of seconds; got nan"),
    ({"max_pixels": 0}, r"`max_pixels` must be a positive finite number; got 0"),
    ({"max_pixels": 0.5}, r"`max_pixels` must be at least 1; got 0.5"),
    ({"rest_fraction": -1.0}, r"`rest_fraction` must be a finite number >= 0; got -1.0"),
])
def test_bad_preview_settings_are_refused_when_made(qtbot, kw, message):
    with pytest.raises(ValueError, match=message):
        LivePreview(**kw)


@pytest.fixture(scope="session")
def compiled_motion_kernels():
    """Motion-aware's compiled kernels, compiled (or loaded from numba's cache) before a live view starts: in a
    fresh clone the first run compiles them for several seconds beside the camera's thread, a one-time cost
    that is not what the live view's tests measure."""
    from flexvox_core.design import design_code
    from flexvox_core.forward import capture as coded
    from flexvox_core.motion import motion_aware
    from flexvox_core.simulate.scenes import render_scene

    code = design_code((4, 4)).code
    motion_aware(coded(render_scene("balls", 48, 48, 64), code), code)


@pytest.fixture
def capture(qtbot, settings, runner, compiled_motion_kernels):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    ws.resize(1300, 800)
    ws.code.rate.setValue(60.0)  # K = 16 at 60 Hz: a frame every 16.7 ms
    ws.live_panel.preview.budget_s = 1e3  # the whole frame, however busy the machine (sizing: tested apart)
    ws.clear_calibration()  # “Record uncalibrated”: these recordings need no calibration
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
    title = ws.live_panel.preview_panel.title.text()
    assert re.match(r"motion-aware preview: camera frame \d+, sub-frame \d+/16", title)
    # What holds at any speed: the whole frame, a rate, a time per run, how many frames were previewed; how far
    # behind the camera it is shows only while the newest run's frame is known (the next run may be under way).
    line = re.match(r"motion-aware preview on the CPU: 64×48 \(the whole frame\), [123] frames?, \d+\.\d Hz, "
                    r"\d+\.\d\d s per run"
                    r"(?:, (\d+\.\d\d) s behind the camera)? · (\d+) of (\d+) camera frames previewed \(newest wins\)",
                    ws.live_panel.preview_label.text())
    assert line, ws.live_panel.preview_label.text()
    assert 1 <= int(line[2]) <= int(line[3])
    assert not ws.live_panel.region_roi.isVisible()  # the whole frame: no region drawn
    assert ws.live_panel.preview.rate_hz > 0
    assert max(jobs_at_once) <= 1  # one reconstruction at a time, never a queue
    preview = ws.live_panel.preview
    assert preview.offered > preview.runs  # frames arrive faster than previews: the newest wins
    stats = ws.live_panel.stats
    assert stats.received >= preview.offered  # every frame offered to the preview was shown live first
    assert stats.dropped == 0, f"{stats.dropped} of {stats.received + stats.dropped} camera frames dropped"
    ws.stop_live()
    assert not ws.live_panel.preview.enabled
    assert ws.live_panel.preview_label.text().startswith("motion-aware preview (stopped) on the CPU: ")


def test_a_recording_with_the_preview_on_drops_nothing(qtbot, capture, tmp_path):
    ws = capture
    ws.record_panel.frames_box.setValue(60)  # one second at 60 Hz
    ws.record_panel.truth_check.setChecked(False)
    # A second recording only when the first dropped frames: on CI's 2 cores the other test worker's threads alone
    # can delay the camera's thread by a period (16.7 ms) now and then; a preview that starves the camera drops
    # frames in every recording.
    for attempt in range(2):
        ws.record_panel.path_edit.setText(str(tmp_path / f"run{attempt}.zarr"))
        with qtbot.waitSignal(ws.recording_finished, timeout=30_000) as finished:
            assert ws.record()
        result = finished.args[0]
        if result.stats.drops == 0:
            break
    assert ws.live_panel.preview.runs >= 1, "the preview ran during the recording"
    assert result.ok and result.frames_in_recording == 60
    # titles count the recording's frames as the counters do ("frame 12 of 60"), not the camera's own numbers
    assert re.match(r"recording ended · last shown: frame \d+ of 60$", ws.live_panel.image_panel.title.text())
    assert re.match(r"motion-aware preview: frame \d+ of 60, sub-frame", ws.live_panel.preview_panel.title.text())
    assert result.stats.drops == 0 and result.stats.queue_drops == 0
    assert not ws.live_panel.preview.enabled


def test_newest_wins_one_run_at_a_time(qtbot):
    preview = LivePreview(rest_fraction=0.0)
    preview.set_code(design_code((2, 4)).code, (2, 4))
    preview.start()
    for i in range(30):
        preview.feed(_frame(i))
        assert preview.runner.active <= 1
    # Bounds against a hang, not timings: the first motion-aware run loads its kernels (tens of seconds under load).
    qtbot.waitUntil(lambda: not preview.busy and preview.runs >= 1, timeout=60_000)
    # Motion-aware shows the frame before the newest (its trajectories reach both ways).
    qtbot.waitUntil(lambda: preview.result is not None and preview.result.frame_id == 28, timeout=60_000)
    assert preview.runs < 30 and preview.offered == 30
    assert preview.shutdown(5000)


def test_the_preview_can_be_switched_off(qtbot, capture):
    ws = capture
    ws.live_panel.preview_check.setChecked(False)
    assert ws.start_live()
    qtbot.waitUntil(lambda: ws.live_panel.stats.received >= 5, timeout=10_000)
    assert ws.live_panel.preview.runs == 0 and ws.live_panel.preview_label.text() == "preview: off"
    assert not ws.settings.get_bool("capture/preview", True)


def test_on_the_gpu_the_preview_takes_the_whole_frame_every_run_and_says_so(qtbot):
    """LivePreview(device="cuda") (the tests' simulator stands in for the card): the whole frame from the first run,
    no rest between runs, all of motion-aware's stages, and the words say it runs on the GPU."""
    import numpy as np

    from flexvox_app.capture.live_preview import PreviewResult, Region
    from flexvox_app.gui.capture.live_preview import LivePreview

    preview = LivePreview(device="cuda")
    assert preview.device == "cuda" and preview.reconstructor.device == "cuda" and preview.rest_fraction == 0
    assert preview._next_region((480, 640)).covers((480, 640))
    from flexvox_app.capture.live_preview import preview_options

    # All the stages; the flow at the whole frame's scale, which the whole frame's default is.
    assert preview_options((480, 640), "cuda") == {"flow_scale": pytest.approx(1 / 3)}
    preview.enabled, preview.runs = True, 1
    preview.result = PreviewResult(np.zeros((16, 48, 64), np.float32), 3, 3, Region(0, 48, 0, 64), (48, 64), 0.01,
                                   (0.0, 1.0), "motion-aware", "cuda")
    assert preview.text().startswith("motion-aware preview on numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1: no GPU, "
                                     "slower than the CPU): 64×48 (the whole frame)")
    assert LivePreview().device == "cpu"  # auto never takes the simulator


def test_the_live_preview_line_says_where_it_runs():
    import numpy as np

    from flexvox_app.capture.live_preview import PreviewResult, Region
    from flexvox_app.gui.capture.live_preview import LivePreview

    preview = LivePreview(device="cpu")
    preview.enabled, preview.runs = True, 1
    preview.result = PreviewResult(np.zeros((16, 48, 64), np.float32), 3, 3, Region(0, 48, 0, 64), (48, 64), 0.01,
                                   (0.0, 1.0), "motion-aware", "cpu")
    assert preview.text().startswith("motion-aware preview on the CPU: 64×48 (the whole frame)"), preview.text()


def test_the_preview_region_shrunk_under_load_grows_back_when_runs_get_faster():
    from flexvox_app.capture.live_preview import PixelCost, preview_region

    cost, budget, shape = PixelCost(), 0.6, (120, 160)

    def run(pixels, load):  # a run: a large fixed part and a part per pixel, both slowed by the load
        return load * (0.45 + 5e-6 * pixels)  # idle, the whole 160×120 frame takes 0.55 s: it fits 0.6 s

    region = preview_region(shape, (4, 4), 160 * 120)
    for _ in range(6):  # under load the region shrinks
        cost.add(run(region.pixels, 3.0), region.pixels)
        region = preview_region(shape, (4, 4), cost.pixels_for(budget, 160 * 120))
    small = region.pixels
    assert small < 160 * 120 / 8
    for _ in range(8):  # the load falls: runs are quick again
        cost.add(run(region.pixels, 1.0), region.pixels)
        region = preview_region(shape, (4, 4), cost.pixels_for(budget, 160 * 120))
    assert region.covers(shape), (small, region)


def test_a_region_is_previewed_with_the_whole_frames_flow_scale():
    # A 96x96 region of a 240x320 frame: its flow runs at 2/3 (auto_flow_scale of the frame, as the recording's
    # reconstruction runs it), not at the region's own scale (1, full size), which shows a different picture.
    from flexvox_app.capture.live_preview import preview_options
    from flexvox_core.motion.streaming import StreamingMotionAware

    code = design_code((2, 4)).code
    truth = render_scene("balls", 24, 240, 320)
    frames = [Frame(f, frame_id=i, timestamp_s=i / 15) for i, f in enumerate(capture_frames(truth, code))]
    region = Region(72, 168, 112, 208)
    got = reconstruct_preview(frames, code, region).video
    assert preview_options((240, 320)) == {"flow_scale": pytest.approx(2 / 3), "refine_time": 0.0,
                                           "local_choice": False, "noise_aware": False}
    assert preview_options((240, 320), "cuda") == {"flow_scale": pytest.approx(2 / 3)}
    crop = np.stack([region.crop(f.image) for f in frames]).astype(np.float32)

    def stream(**scale):
        s = StreamingMotionAware(code, sample_range=(0.0, 1.0), refine_time=0.0, local_choice=False,
                                 noise_aware=False, **scale)
        out = [r for image in crop for r in s.push(image)]
        return np.clip(out[-1].video, 0.0, 1.0)

    np.testing.assert_array_equal(got, stream(flow_scale=2 / 3))
    assert np.abs(got - stream()).max() > 0.01  # the region's own scale: another picture
