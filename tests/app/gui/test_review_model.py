"""The Review workspace's model without Qt: jobs run when the test turns the runner, as a window's event loop would."""

import numpy as np
import pytest

from flexvox_app.gui.models.review_model import Line, ReviewModel
from flexvox_core.methods import Method

from .conftest import FRAMES, SIZE
from .model_helpers import Settings, TurnedRunner


def recorded(m):
    """The names of the model's signals, in the order they fire (the old ``changed(part)`` names)."""
    events = []
    p, j = m.playback, m.jobs
    for name, signal in (("path", m.path_changed), ("opened", m.opened), ("frame", p.frame_changed),
                         ("playing", p.playing_changed), ("speed", p.speed_changed), ("shown", p.shown_changed),
                         ("comparison", p.comparison_changed), ("preview wanted", m.preview.preview_wanted),
                         ("result", j.result_changed), ("export", j.export_changed), ("progress", j.progress_changed),
                         ("jobs", j.jobs_changed), ("expected", j.expected_changed)):
        signal.connect(lambda *args, name=name: events.append(name))
    return events


@pytest.fixture
def model(recording):
    runner = TurnedRunner()
    m = ReviewModel(runner, Settings(), None)
    m.events = recorded(m)
    opened = []
    m.opened.connect(opened.append)
    m.open(recording)
    assert m.path_line == Line(f"opening {recording} …") and runner.names() == ["open"]
    runner.turn()
    assert opened == [m.session] and m.session.n_frames == FRAMES and m.path_line == Line(str(recording))
    assert m.settings["review/last_recording"] == str(recording)
    assert m.events[-2:] == ["opened", "preview wanted"]
    return m


def test_playback_advances_whole_camera_frames_until_a_result_is_shown(model):
    p = model.playback
    p.set_fps(16)
    assert model.settings["review/fps"] == 16 and p.speed() == 16.0
    p.set_playing(True)
    assert p.playing and p.interval_ms() == 500  # a camera frame of 8 sub-frames at 16 a second
    start = p.last_tick
    model.events.clear()
    p.tick(start + 1.0)
    assert p.subframe == 16 and model.events == ["frame"]  # no preview while playing
    p.set_real_time(True)
    assert p.speed() == 120.0 and p.interval_ms() == 67  # 15 Hz × 8, drawn at most 30 times a second
    p.set_playing(False)
    assert not p.playing and model.events[-1] == "preview wanted"


def test_a_preview_is_wanted_where_nothing_covers_the_frame_and_shows_what_the_form_asks(model):
    p, pv = model.playback, model.preview
    diffusion = Method("diffusion")
    model.events.clear()
    p.set_subframe(26)
    assert model.events == ["frame", "preview wanted"]
    handle = pv.request_preview(diffusion, diffusion, comparing=False)
    model.runner.turn()
    assert handle.outcome == "finished" and p.shown is handle.result and p.shown.extra["preview"]
    assert p.shown.first_frame == 2 and p.shown.video.shape == (24, *SIZE)
    model.events.clear()
    p.set_subframe(27)  # inside the preview: nothing to recompute
    assert model.events == ["frame"]
    p.set_subframe(2)
    assert model.events[-1] == "preview wanted"
    # A newer request supersedes one still running: only the newest is shown.
    older = pv.request_preview(Method("rebin"), Method("rebin"), comparing=False)
    newer = pv.request_preview(diffusion, diffusion, comparing=False)
    assert older.token.cancelled
    model.runner.turn()
    assert p.shown is newer.result and p.shown.method == diffusion


def test_reconstruct_reports_progress_and_the_result_and_cancel_keeps_nothing(model, naive_psnr):
    p, j, pv = model.playback, model.jobs, model.preview
    method = Method("diffusion")
    handle = j.reconstruct(method)
    assert j.busy and j.cancellable and j.reconstruct(method) is None  # one at a time
    assert j.result_line == Line(f"reconstructing with {method.label()} …") and j.progress == (0, FRAMES)
    added = []
    j.result_added.connect(added.append)
    model.runner.turn(only=("reconstruct",))
    r = handle.result
    assert added == [r] and j.results == [r] and p.shown is r and not j.busy
    assert j.progress == (FRAMES, FRAMES) and r.psnr > naive_psnr
    assert f"PSNR vs ground truth {r.psnr:.2f} dB" in j.result_line.text
    assert j.full_result_of(method) is r and j.export_candidate() is r
    assert j.closing_losses() == [f"1 reconstruction not exported is lost: {method.label()}"]
    # The chosen method's result is shown itself, never a preview of it.
    p.set_shown(None)
    assert pv.request_preview(method, method, comparing=False) is None and p.shown is r
    second = j.reconstruct(Method("rebin"))
    model.cancel()
    assert second.token.cancelled and not j.cancellable
    assert j.result_line == Line("cancelling … (the current chunk of frames finishes first)")
    model.runner.turn(only=("reconstruct",))
    assert second.outcome == "cancelled" and j.results == [r]
    assert j.result_line == Line("cancelled; nothing was kept") and j.progress == (0, FRAMES)


def test_export_writes_the_full_reconstruction_of_a_preview_and_asks_before_replacing(model, tmp_path):
    p, j, pv = model.playback, model.jobs, model.preview
    pv.request_preview(Method("rebin"), Method("rebin"), comparing=False)
    model.runner.turn()
    assert p.shown.extra["preview"]
    path = tmp_path / "out.npy"
    handle = j.export(path)
    assert j.job is handle and j.busy  # a reconstruction first: Cancel stops it
    model.runner.turn()
    written, result = j.exported
    assert written == path and not result.extra.get("preview") and j.results == [result]
    np.testing.assert_array_equal(np.load(path), result.video)
    assert j.export_line.text.startswith(f"wrote {path}: ") and j.unexported() == []
    asked = []
    assert j.export(path, ask=lambda p: asked.append(p) or False) is None
    assert asked == [path] and j.export_line == Line(f"not exported: {path} is kept (choose another path)")
    assert j.export(model.session.path, overwrite=True) is None and j.export_line.error
    assert "an output never replaces its input" in j.export_line.text


def test_nothing_to_export_and_after_shutdown_nothing_is_wanted_or_submitted(model):
    p, j, pv = model.playback, model.jobs, model.preview
    assert j.export("/nonexistent/x.npy") is None
    assert j.export_line == Line("nothing to export: reconstruct, or preview, first")
    p.set_playing(True)
    model.shutdown()
    model.events.clear()
    pv.want_preview()
    p.set_subframe(40)
    assert not p.playing and model.events == ["frame"]
    assert pv.request_preview(Method("rebin"), Method("rebin"), comparing=False) is None


def test_an_open_failure_is_said_in_words(recording, tmp_path):
    (tmp_path / "junk.zarr").mkdir()
    runner = TurnedRunner()
    m = ReviewModel(runner, Settings(), None)
    status = []
    m.status.connect(status.append)
    m.open(tmp_path / "junk.zarr")
    runner.turn()
    assert m.session is None and m.path_line.error and m.path_line.text.startswith("cannot open junk.zarr: ")
    assert status == [m.path_line.text]
