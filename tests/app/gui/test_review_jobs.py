"""Review's jobs model alone, without Qt: full reconstructions, their lines, what closing would lose."""

import pytest

from flexvox_app.gui.models.review_jobs import JobsModel, Line
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core.methods import Method

from .conftest import FRAMES
from .model_helpers import Settings, TurnedRunner


@pytest.fixture
def jobs(recording):
    """The jobs model on the test recording, its signals recorded in ``jobs.events``."""
    playback = PlaybackModel(Settings())
    j = JobsModel(TurnedRunner(), Settings(), None, playback)
    session = ReviewSession.open(recording)
    playback.set_session(session)
    j.events = []
    for name in ("result_changed", "export_changed", "progress_changed", "jobs_changed", "result_added"):
        getattr(j, name).connect(lambda *args, name=name: j.events.append((name, *args)))
    j.set_session(session)
    return j


def test_a_new_session_empties_the_lines_and_the_progress_each_with_its_signal(jobs):
    assert jobs.events == [("progress_changed", 0, 1), ("result_changed", Line()), ("export_changed", Line())]
    assert jobs.truth is not None and jobs.results == [] and not jobs.busy


def test_a_reconstruction_says_its_progress_and_ends_shown_with_its_jobs_signal(jobs):
    method = Method("rebin")
    jobs.events.clear()
    handle = jobs.reconstruct(method)
    assert jobs.events == [("progress_changed", 0, FRAMES),
                           ("result_changed", Line(f"reconstructing with {method.label()} …")), ("jobs_changed",)]
    assert jobs.closing_losses() == ["the reconstruction running stops; what it computed is lost"]
    jobs.runner.turn()
    r = handle.result
    assert jobs.events[-2:] == [("result_added", r), ("jobs_changed",)] and jobs.playback.shown is r
    assert jobs.flow_result() is None  # re-binning gives no flow
    assert jobs.closing_losses() == [f"1 reconstruction not exported is lost: {method.label()}"]


def test_a_failed_reconstruction_is_said_in_red_and_after_shutdown_nothing_starts(jobs, monkeypatch):
    def broken(*args, **kwargs):
        raise ValueError("no memory for 6 frames")

    monkeypatch.setattr("flexvox_app.gui.models.review_jobs.run_reconstruction", broken)
    jobs.reconstruct(Method("rebin"))
    jobs.runner.turn()
    assert jobs.result_line == Line("reconstruction failed: no memory for 6 frames", error=True)
    assert jobs.results == [] and not jobs.busy
    jobs.shutdown()
    assert jobs.reconstruct(Method("rebin")) is None and jobs.runner.waiting == []
