"""The Review workspace's model without Qt: jobs run when the test turns the runner, as a window's event loop would."""

import numpy as np
import pytest

from flexvox_app.gui.models.jobs import Cancelled, CancelToken
from flexvox_app.gui.models.review_model import Line, ReviewModel
from flexvox_core.methods import Method

from .conftest import FRAMES, SIZE


class Handle:
    def __init__(self, name):
        self.name = name
        self.token = CancelToken()
        self.outcome = None
        self.running = True
        self.result = None

    def cancel(self):
        self.token.cancel()


class TurnedRunner:
    """Jobs wait in a list; :meth:`turn` runs them one by one on this thread, then their callbacks."""

    def __init__(self):
        self.waiting = []

    def submit(self, name, fn, *, on_progress=None, on_finished=None, on_failed=None, on_cancelled=None,
               on_done=None):
        handle = Handle(name)
        self.waiting.append((handle, fn, on_progress, on_finished, on_failed, on_cancelled, on_done))
        return handle

    def names(self):
        return [job[0].name for job in self.waiting]

    def turn(self, only=None):
        """Run the jobs waiting (those named ``only``; the others are dropped), and those they submit."""
        while self.waiting:
            handle, fn, on_progress, on_finished, on_failed, on_cancelled, on_done = self.waiting.pop(0)
            if only is not None and handle.name not in only:
                continue
            try:
                handle.result = fn(handle.token, on_progress or (lambda done, total: None))
            except Cancelled:
                handle.outcome = "cancelled"
                if on_cancelled:
                    on_cancelled()
            except Exception as exc:  # noqa: BLE001 - as the job runner: every failure reported in words
                handle.outcome = "failed"
                if on_failed:
                    on_failed(str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}")
            else:
                handle.outcome = "finished"
                if on_finished:
                    on_finished(handle.result)
            handle.running = False
            if on_done:
                on_done()


class Settings(dict):
    def get_str(self, key, default=""):
        return self.get(key, default)

    get_int = get_bool = get_str

    def set(self, key, value):
        self[key] = value

    def remember_folder(self, path, key=""):
        self[key or "files/last_folder"] = str(path)


@pytest.fixture
def model(recording):
    runner = TurnedRunner()
    m = ReviewModel(runner, Settings(), None)
    m.events = []
    m.changed.connect(lambda part: m.events.append(part))
    m.preview_wanted.connect(lambda: m.events.append("preview wanted"))
    opened = []
    m.opened.connect(opened.append)
    m.open(recording)
    assert m.path_line == Line(f"opening {recording} …") and runner.names() == ["open"]
    runner.turn()
    assert opened == [m.session] and m.session.n_frames == FRAMES and m.path_line == Line(str(recording))
    assert m.settings["review/last_recording"] == str(recording)
    assert "session" in m.events and m.events[-1] == "preview wanted"
    return m


def test_playback_advances_whole_camera_frames_until_a_result_is_shown(model):
    model.set_fps(16)
    assert model.settings["review/fps"] == 16 and model.speed() == 16.0
    model.set_playing(True)
    assert model.playing and model.interval_ms() == 500  # a camera frame of 8 sub-frames at 16 a second
    start = model.last_tick
    model.events.clear()
    model.tick(start + 1.0)
    assert model.subframe == 16 and model.events == ["frame"]  # no preview while playing
    model.set_real_time(True)
    assert model.speed() == 120.0 and model.interval_ms() == 67  # 15 Hz × 8, drawn at most 30 times a second
    model.set_playing(False)
    assert not model.playing and model.events[-1] == "preview wanted"


def test_a_preview_is_wanted_where_nothing_covers_the_frame_and_shows_what_the_form_asks(model):
    diffusion = Method("diffusion")
    model.events.clear()
    model.set_subframe(26)
    assert model.events == ["frame", "preview wanted"]
    handle = model.request_preview(diffusion, diffusion, comparing=False)
    model.runner.turn()
    assert handle.outcome == "finished" and model.shown is handle.result and model.shown.extra["preview"]
    assert model.shown.first_frame == 2 and model.shown.video.shape == (24, *SIZE)
    model.events.clear()
    model.set_subframe(27)  # inside the preview: nothing to recompute
    assert model.events == ["frame"]
    model.set_subframe(2)
    assert model.events[-1] == "preview wanted"
    # A newer request supersedes one still running: only the newest is shown.
    older = model.request_preview(Method("rebin"), Method("rebin"), comparing=False)
    newer = model.request_preview(diffusion, diffusion, comparing=False)
    assert older.token.cancelled
    model.runner.turn()
    assert model.shown is newer.result and model.shown.method == diffusion


def test_reconstruct_reports_progress_and_the_result_and_cancel_keeps_nothing(model, naive_psnr):
    method = Method("diffusion")
    handle = model.reconstruct(method)
    assert model.busy and model.cancellable and model.reconstruct(method) is None  # one at a time
    assert model.result_line == Line(f"reconstructing with {method.label()} …") and model.progress == (0, FRAMES)
    added = []
    model.result_added.connect(added.append)
    model.runner.turn(only=("reconstruct",))
    r = handle.result
    assert added == [r] and model.results == [r] and model.shown is r and not model.busy
    assert model.progress == (FRAMES, FRAMES) and r.psnr > naive_psnr
    assert f"PSNR vs ground truth {r.psnr:.2f} dB" in model.result_line.text
    assert model.full_result_of(method) is r and model.export_candidate() is r
    assert model.closing_losses() == [f"1 reconstruction not exported is lost: {method.label()}"]
    # The chosen method's result is shown itself, never a preview of it.
    model.set_shown(None)
    assert model.request_preview(method, method, comparing=False) is None and model.shown is r
    second = model.reconstruct(Method("rebin"))
    model.cancel()
    assert second.token.cancelled and not model.cancellable
    assert model.result_line == Line("cancelling … (the current chunk of frames finishes first)")
    model.runner.turn(only=("reconstruct",))
    assert second.outcome == "cancelled" and model.results == [r]
    assert model.result_line == Line("cancelled; nothing was kept") and model.progress == (0, FRAMES)


def test_export_writes_the_full_reconstruction_of_a_preview_and_asks_before_replacing(model, tmp_path):
    model.request_preview(Method("rebin"), Method("rebin"), comparing=False)
    model.runner.turn()
    assert model.shown.extra["preview"]
    path = tmp_path / "out.npy"
    handle = model.export(path)
    assert model.job is handle and model.busy  # a reconstruction first: Cancel stops it
    model.runner.turn()
    written, result = model.exported
    assert written == path and not result.extra.get("preview") and model.results == [result]
    np.testing.assert_array_equal(np.load(path), result.video)
    assert model.export_line.text.startswith(f"wrote {path}: ") and model.unexported() == []
    asked = []
    assert model.export(path, ask=lambda p: asked.append(p) or False) is None
    assert asked == [path] and model.export_line == Line(f"not exported: {path} is kept (choose another path)")
    assert model.export(model.session.path, overwrite=True) is None and model.export_line.error
    assert "an output never replaces its input" in model.export_line.text


def test_nothing_to_export_and_after_shutdown_nothing_is_wanted_or_submitted(model):
    assert model.export("/nonexistent/x.npy") is None
    assert model.export_line == Line("nothing to export: reconstruct, or preview, first")
    model.set_playing(True)
    model.shutdown()
    model.events.clear()
    model.want_preview()
    model.set_subframe(40)
    assert not model.playing and model.events == ["frame"]
    assert model.request_preview(Method("rebin"), Method("rebin"), comparing=False) is None


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
