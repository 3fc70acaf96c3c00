"""Review's method form offers "auto" for a knob the estimate can choose; the choice as a Qt-free job."""

import numpy as np
import pytest

import flexvox_core.accuracy as accuracy
from flexvox_app.gui.models.choice_job import choice_lines, run_choice
from flexvox_app.gui.models.jobs import Cancelled, CancelToken
from flexvox_core.methods import Method


@pytest.fixture
def form(qtbot, settings):
    from flexvox_app.gui.review.method_form import MethodForm

    f = MethodForm(settings, offer_auto=True)
    qtbot.addWidget(f)
    return f


def test_auto_is_offered_only_by_a_workspace_that_runs_it(qtbot, settings):
    from flexvox_app.gui.review.method_form import MethodForm

    settings.set("review/auto", True)
    plain = MethodForm(settings)
    qtbot.addWidget(plain)
    plain.set_method_name("diffusion")
    assert plain.auto_box.isHidden() and plain.auto_knob() is None and plain.widget("time").isEnabled()


def test_auto_is_offered_where_the_estimate_offers_the_method_and_chooses_the_time(form, settings):
    form.set_method_name("diffusion")
    assert not form.auto_box.isHidden() and form.auto_box.isEnabled()
    assert form.auto_box.text() == "choose the diffusion time n by the estimate (auto)"
    assert form.auto_knob() is None  # unchecked
    form.auto_box.setChecked(True)
    assert form.auto_knob() == "time" and not form.widget("time").isEnabled()
    assert settings.get_bool("review/auto", False)
    form.set_method_name("gap-tv")  # no knob to choose: the box hides, nothing is chosen
    assert form.auto_box.isHidden() and form.auto_knob() is None
    assert form.auto_refusal() == "gap-tv has no knob to choose by the estimate"
    form.set_method_name("diffusion")
    form.auto_box.setChecked(False)
    assert form.widget("time").isEnabled() and form.auto_knob() is None


def test_auto_for_a_method_the_estimate_refuses_is_greyed_with_why(form, monkeypatch):
    form.set_method_name("diffusion")
    form.auto_box.setChecked(True)
    monkeypatch.setitem(accuracy.REFUSED, "diffusion", "made up for diffusion")
    form.widget("solver").setCurrentText("steady")  # any change of a knob asks the estimate again
    assert not form.auto_box.isEnabled() and form.auto_knob() is None
    assert form.auto_box.toolTip() == "the estimate refuses diffusion: made up for diffusion"
    assert form.widget("time").isEnabled()  # not chosen: the operator sets it
    monkeypatch.setitem(accuracy.REFUSED, "rebin", "made up here")
    form.set_method_name("rebin")
    assert form.auto_box.text() == "choose the division by the estimate (auto)"
    assert form.auto_box.toolTip() == "the estimate refuses rebin: made up here" and form.slider.isEnabled()


def test_the_choice_job_returns_the_chosen_reconstruction_with_the_choice(recording):
    from flexvox_core.capture_reader import open_capture

    reader = open_capture(recording)
    frames, code = reader.input(Method("diffusion"))
    truth = reader.recording.ground_truth[:]
    done = []
    result = run_choice(frames, code, Method("diffusion"), "time", truth=truth, device="cpu",
                        progress=lambda d, t: done.append((d, t)))
    choice = result.extra["choice"]
    assert list(dict.fromkeys(done)) == [(i, 5) for i in range(6)]  # within each candidate, and after it
    assert result.method == choice.method and result.method.time == choice.value
    assert np.array_equal(result.video, reader.run(choice.method).video) and result.psnr > 15
    lines = choice_lines(result)
    assert lines[0].startswith(f"chose time {choice.value:g} for diffusion by the estimated PSNR")
    assert len(lines) == 7 and lines[-1].startswith("choosing cost ")
    token = CancelToken()
    with pytest.raises(Cancelled):
        run_choice(frames, code, Method("diffusion"), "time", cancel=token, device="cpu",
                   progress=lambda d, t: token.cancel())
