"""Review's jobs and previews when another recording opens while one of them is finishing: nothing of the old
recording reaches the new one (a job's ``finished`` may already wait in the GUI thread's queue)."""

import pytest

from flexvox_app.gui.models.jobs import run_reconstruction
from flexvox_app.gui.models.review_jobs import JobsModel
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_app.gui.models.review_preview import PreviewModel
from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core import render_scene, simulate_video, write_simulation
from flexvox_core.design import design_code
from flexvox_core.methods import Method

from .model_helpers import QueuedRunner, Settings


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    """Two small recordings of different sizes."""
    d = tmp_path_factory.mktemp("two")
    code = design_code((2, 2)).code
    return (write_simulation(d / "a.zarr", simulate_video(render_scene("balls", 16, 24, 32), code)),
            write_simulation(d / "b.zarr", simulate_video(render_scene("balls", 16, 40, 48), code)))


def models(first):
    runner, settings = QueuedRunner(), Settings()
    playback = PlaybackModel(settings)
    jobs = JobsModel(runner, settings, None, playback)
    preview = PreviewModel(runner, settings, playback, jobs)
    s = ReviewSession.open(first)
    playback.set_session(s)
    jobs.set_session(s)
    return runner, playback, jobs, preview


def reopen(playback, jobs, path):
    s = ReviewSession.open(path)
    playback.set_session(s)
    jobs.set_session(s)
    return s


def test_a_preview_of_the_recording_before_is_not_shown_on_the_next(two):
    runner, playback, jobs, preview = models(two[0])
    preview.request_preview(Method("diffusion"), Method("diffusion"), False)
    preview.cancel()  # as ReviewModel does before the next recording opens
    reopen(playback, jobs, two[1])
    runner.deliver()
    assert playback.shown is None


def test_an_export_finishing_after_another_recording_opened_is_said_not_kept(two, tmp_path):
    runner, playback, jobs, _ = models(two[0])
    s1 = jobs.session
    shown = run_reconstruction(s1.frames[:2], s1.code, Method("diffusion"), chunk_frames=2)
    shown.extra["preview"] = True
    playback.set_shown(shown)
    said = []
    jobs.status.connect(said.append)
    jobs.export(tmp_path / "out.npy")  # a preview: the export reconstructs every frame, then writes
    jobs.cancel()  # too late: the worker is past its last check
    reopen(playback, jobs, two[1])
    runner.deliver()
    assert jobs.results == [] and playback.shown is None  # nothing of a.zarr in b.zarr's results
    assert (tmp_path / "out.npy").exists() and said[-1].startswith("exported out.npy: ")
    assert said[-1].endswith(" of a.zarr")
