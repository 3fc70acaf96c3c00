"""Review's jobs model alone, without Qt: full reconstructions, their lines, what closing would lose."""

import numpy as np
import pytest

from flexvox_app.gui.models.jobs import short_estimate
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.review_jobs import JobsModel, Line
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core.accuracy import NotEstimable, estimate_recording, refusal
from flexvox_core.methods import Method

from .conftest import FRAMES
from .model_helpers import Settings, TurnedRunner, without_ground_truth


@pytest.fixture(scope="module")
def captured(recording, tmp_path_factory):
    """The test recording without its ground truth."""
    return without_ground_truth(recording, tmp_path_factory.mktemp("captured"))


def jobs_on(recording):
    """The jobs model on ``recording``, its signals recorded in ``jobs.events``."""
    playback = PlaybackModel(Settings())
    j = JobsModel(TurnedRunner(), Settings(), None, playback)
    session = ReviewSession.open(recording)
    playback.set_session(session)
    j.events = []
    for name in ("result_changed", "export_changed", "progress_changed", "jobs_changed", "result_added",
                 "estimate_changed"):
        getattr(j, name).connect(lambda *args, name=name: j.events.append((name, *args)))
    j.set_session(session)
    return j


@pytest.fixture
def jobs(recording):
    """The jobs model on the test recording (with ground truth)."""
    return jobs_on(recording)


def test_a_new_session_empties_the_lines_and_the_progress_each_with_its_signal(jobs):
    assert jobs.events == [("progress_changed", 0, 1), ("result_changed", Line()), ("export_changed", Line())]
    assert jobs.truth is not None and jobs.results == [] and not jobs.busy


def test_opening_reads_none_of_the_ground_truth_and_the_job_reads_it_for_its_psnr(recording, monkeypatch):
    from flexvox_core.metrics import psnr
    from flexvox_core.recording.verified_rows import VerifiedRows

    reads = []
    real = VerifiedRows.read
    monkeypatch.setattr(VerifiedRows, "read", lambda self, a, b: reads.append((self.label, a, b)) or real(self, a, b))
    jobs = jobs_on(recording)  # a 1-s VGA recording's truth is 295 MB: not read on the GUI thread at open
    assert not any("ground truth" in label for label, *_ in reads), reads
    handle = jobs.reconstruct(Method("rebin"))
    assert not any("ground truth" in label for label, *_ in reads)  # submitted, not yet run
    jobs.runner.turn()  # the job, off the GUI thread in the app
    assert any("ground truth" in label for label, *_ in reads)
    truth = ReviewSession.open(recording).recording.ground_truth
    assert handle.result.psnr == pytest.approx(psnr(np.asarray(truth), handle.result.video), abs=1e-9)


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


def lines(jobs):
    return [e[1].text for e in jobs.events if e[0] == "result_changed"]


def test_without_ground_truth_the_result_line_and_label_say_the_estimate_made_off_the_gui_thread(captured):
    jobs = jobs_on(captured)
    assert jobs.truth is None
    method = Method("diffusion")
    assert refusal(method) is None  # the default diffusion (nc) is offered
    handle = jobs.reconstruct(method)
    jobs.runner.turn()
    r = handle.result
    assert [h.name for h in jobs.runner.handles] == ["reconstruct", "estimate"]
    est = r.estimate
    assert est is not None and r.no_estimate is None and r.psnr is None
    assert est.psnr == pytest.approx(estimate_recording(captured, method).psnr, abs=1e-3)  # the core's estimate
    pending = lines(jobs)[-2]  # said while it runs
    base = pending.removesuffix("; estimating its PSNR from the recording …")
    assert pending != base and base.startswith(f"{method.label()}: 48 sub-frames in ") and "estimated" not in base
    assert jobs.result_line == Line(f"{base}; {est.line()}") and est.line().startswith("estimated PSNR ")
    assert jobs.events[-1] == ("estimate_changed", r)
    assert r.label().endswith(f", {short_estimate(est)})") and short_estimate(est).startswith(
        f"estimated PSNR {est.psnr:.2f} dB (± {est.half_width:.2f} dB)")


def test_a_refused_method_is_not_estimated_and_keeps_why(captured):
    jobs = jobs_on(captured)
    method = Method("rebin", interpolate=False)  # refused (interpolated re-binning is estimated)
    jobs.reconstruct(method)
    jobs.runner.turn()
    r = jobs.results[0]
    assert [h.name for h in jobs.runner.handles] == ["reconstruct"] and r.estimate is None
    assert r.no_estimate == in_gui_words(refusal(method)) and r.no_estimate.startswith(
        "re-binning without interpolation")
    assert "estimat" not in jobs.result_line.text and "estimat" not in r.label()


def test_where_the_recording_has_ground_truth_the_true_psnr_stays_and_nothing_is_estimated(jobs):
    jobs.reconstruct(Method("diffusion"))
    jobs.runner.turn()
    r = jobs.results[0]
    assert [h.name for h in jobs.runner.handles] == ["reconstruct"] and r.estimate is None and r.no_estimate is None
    assert f"; PSNR vs ground truth {r.psnr:.2f} dB" in jobs.result_line.text and "estimat" not in jobs.result_line.text


def test_an_estimate_refused_by_the_recording_says_why_and_one_left_running_is_dropped(captured, monkeypatch):
    jobs = jobs_on(captured)

    def refused(*args, **kwargs):
        raise NotEstimable("cannot estimate the accuracy of diffusion: it copies 40% of the probed samples")

    monkeypatch.setattr("flexvox_app.gui.models.review_jobs.estimate_recording", refused)
    jobs.reconstruct(Method("diffusion"))
    jobs.runner.turn()
    r = jobs.results[0]
    assert r.estimate is None and "it copies 40% of the probed samples" in r.no_estimate
    assert "estimat" not in jobs.result_line.text and jobs.events[-1] == ("estimate_changed", r)
    jobs.reconstruct(Method("diffusion", time=2.0))
    jobs.runner.turn(only=("reconstruct",))  # its estimate waits
    waiting = jobs.runner.handles[-1]
    assert waiting.name == "estimate" and not waiting.token.cancelled
    jobs.set_session(jobs.session)  # a recording opens
    assert waiting.token.cancelled


def test_an_estimate_cancelled_while_it_runs_stops_at_its_next_check(captured, monkeypatch):
    jobs = jobs_on(captured)
    seen = []

    def cancelled_midway(*args, progress, **kwargs):
        def report(done, total):
            seen.append((done, total))
            jobs.cancel_estimates()  # a recording opens, or the window closes, while the probe runs
            progress(done, total)

        return estimate_recording(*args, progress=report, **kwargs)

    monkeypatch.setattr("flexvox_app.gui.models.review_jobs.estimate_recording", cancelled_midway)
    monkeypatch.setattr("flexvox_app.gui.models.review_jobs.chunk_frames_for", lambda *args: 1)  # a check a frame
    jobs.reconstruct(Method("diffusion"))
    jobs.runner.turn()
    handle = jobs.runner.handles[-1]
    assert handle.name == "estimate" and handle.outcome == "cancelled" and handle.token.cancelled
    assert seen == [(1, FRAMES)]  # stopped after the probe's first chunk (the reconstruction given: one run)
    assert jobs.results[0].estimate is None


def test_reconstruct_with_an_auto_knob_runs_the_choice_and_says_what_it_chose_and_cost(captured):
    jobs = jobs_on(captured)
    method = Method("diffusion")
    jobs.events.clear()
    handle = jobs.reconstruct(method, auto_knob="time")
    assert lines(jobs) == ["choosing diffusion's time by the estimated PSNR …"]
    jobs.runner.turn()
    r = handle.result
    choice = r.extra["choice"]
    assert [h.name for h in jobs.runner.handles] == ["reconstruct"]  # the choice's estimate: no second job
    assert r.method == choice.method and r.method.time == choice.value and r.estimate is choice.estimate
    text = jobs.result_line.text
    assert text.startswith(f"{r.method.label()}: 48 sub-frames in ")
    assert f"; chose time {choice.value:g} for diffusion by the estimated PSNR" in text
    assert choice.cost() in text and text.endswith(choice.estimate.line())
    assert jobs.progress[0] == jobs.progress[1] == len(choice.candidates)  # the progress counted candidates


def test_an_auto_knob_with_ground_truth_keeps_the_true_psnr_and_chooses_without_reading_it(jobs):
    handle = jobs.reconstruct(Method("diffusion"), auto_knob="time")
    jobs.runner.turn()
    r = handle.result
    assert f"; PSNR vs ground truth {r.psnr:.2f} dB" in jobs.result_line.text
    assert "chose time" in jobs.result_line.text and "estimated PSNR NN" not in jobs.result_line.text
    assert not jobs.result_line.text.endswith(r.extra["choice"].estimate.line())
