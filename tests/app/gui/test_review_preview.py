"""Review's preview scheduling alone, without Qt: when a preview is wanted, and where it shows."""

import pytest

from flexvox_app.gui.models.review_jobs import JobsModel, Line
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_app.gui.models.review_preview import PreviewModel
from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core.methods import Method

from .conftest import SIZE
from .model_helpers import Settings, TurnedRunner


@pytest.fixture
def parts(recording):
    """Playback, jobs and the preview on the test recording, as Review's model puts them together."""
    runner, settings = TurnedRunner(), Settings()
    playback = PlaybackModel(settings)
    jobs = JobsModel(runner, settings, None, playback)
    preview = PreviewModel(runner, settings, playback, jobs)
    session = ReviewSession.open(recording)
    playback.set_session(session)
    jobs.set_session(session)
    wanted = []
    preview.preview_wanted.connect(lambda: wanted.append(playback.subframe))
    return playback, jobs, preview, wanted


def test_a_preview_is_wanted_when_playback_makes_one_due_and_the_switch_is_on(parts):
    playback, jobs, preview, wanted = parts
    playback.set_subframe(9)
    assert wanted == [9]
    preview.set_preview_on(False)
    playback.set_subframe(17)
    assert wanted == [9] and preview.settings["review/preview"] is False
    preview.set_preview_on(True)  # switching it on asks at once
    assert wanted == [9, 17]
    preview.shutdown()
    playback.set_subframe(25)
    preview.set_preview_on(True)
    assert wanted == [9, 17] and preview.request_preview(Method("rebin"), Method("rebin"), comparing=False) is None


def test_the_slider_s_preview_shows_beside_the_chosen_method_s_full_result(parts):
    playback, jobs, preview, _ = parts
    chosen = Method("rebin")
    jobs.reconstruct(chosen)
    jobs.runner.turn()
    full = jobs.results[0]
    assert playback.shown is full and playback.comparison is None
    slider = Method("diffusion")
    handle = preview.request_preview(slider, chosen, comparing=True)
    jobs.runner.turn()
    assert playback.shown is full and playback.comparison is handle.result  # beside, never in place of it
    assert handle.result.extra["preview"] and handle.result.video.shape == (24, *SIZE)
    assert preview.request_preview(chosen, chosen, comparing=False) is None  # the full result itself
    assert playback.comparison is None and playback.shown is full


def test_a_failed_preview_is_said_on_the_result_line(parts, monkeypatch):
    playback, jobs, preview, _ = parts

    def broken(*args, **kwargs):
        raise ValueError("the knob is out of range")

    monkeypatch.setattr("flexvox_app.gui.models.review_preview.run_reconstruction", broken)
    preview.request_preview(Method("rebin"), Method("rebin"), comparing=False)
    jobs.runner.turn()
    assert jobs.result_line == Line("preview failed: the knob is out of range") and playback.shown is None
