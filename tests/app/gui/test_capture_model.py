"""The Capture workspace's model without Qt: the plan, the calibration, who holds the devices, the refusals."""

import subprocess
import sys

import numpy as np
import pytest

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.gui.models.capture_model import Action, CaptureModel, Cause, Holder, Refusal, RigHeld
from flexvox_calibration.capture_setup import CaptureCalibration

CALIBRATING = "a calibration is running in the Calibrate workspace"


class Elsewhere:
    """The Calibrate workspace as the model asks it: why it holds the rig (None: it does not)."""

    def __init__(self):
        self.reason = None

    def __call__(self):
        return self.reason


class Heard:
    """Every emission of the model's signals, in order."""

    def __init__(self, model):
        self.events = []
        for name in ("plan_changed", "calibration_changed", "holder_changed", "refusal_changed"):
            getattr(model, name).connect(lambda *args, name=name: self.events.append((name, *args)))

    def of(self, name):
        return [e[1:] for e in self.events if e[0] == name]


@pytest.fixture
def elsewhere():
    return Elsewhere()


@pytest.fixture
def model(elsewhere):
    return CaptureModel(CapturePlan(tile=(4, 4)), held_elsewhere=elsewhere)


def a_calibration():
    return CaptureCalibration(homography=np.diag([2.0, 2.0, 1.0]), source="test calibration", calibrated=True)


def bad_timing():
    plan = CapturePlan(tile=(4, 4), camera_hz=1000.0)
    assert not plan.timing().ok
    return plan


# ---------------------------------------------------------------------- the plan
def test_a_plan_change_reaches_the_model_and_its_signal(model):
    heard = Heard(model)
    plan = CapturePlan(tile=(3, 3), camera_hz=10.0)
    model.set_plan(plan)
    assert model.plan is plan and heard.of("plan_changed") == [(plan,)]
    assert heard.of("calibration_changed") == [] and heard.of("holder_changed") == []


def test_the_model_starts_with_the_default_plan_and_refuses_anything_else():
    assert CaptureModel().plan == CapturePlan()
    with pytest.raises(TypeError, match=r"`plan` must be a CapturePlan; got dict"):
        CaptureModel({"tile": (4, 4)})
    with pytest.raises(TypeError, match=r"`plan` must be a CapturePlan; got tuple"):
        CaptureModel().set_plan((4, 4))


# ---------------------------------------------------------------------- the calibration
def test_a_new_calibration_reaches_the_model_and_its_signal(model):
    heard = Heard(model)
    assert model.calibration is None and model.capture_calibration.source == "identity (uncalibrated)"
    assert not model.capture_calibration.calibrated
    cal = a_calibration()
    model.set_calibration(cal)
    assert model.calibration is cal and model.capture_calibration is cal
    model.set_calibration(None)
    assert model.calibration is None and model.capture_calibration.source == "identity (uncalibrated)"
    assert heard.of("calibration_changed") == [(cal,), (None,)]


def test_a_calibration_offered_during_a_recording_is_refused_in_words_never_ignored(model):
    model.set_calibration(cal := a_calibration())
    model.take(Holder.RECORDING)
    heard = Heard(model)
    assert model.refusal(Action.CALIBRATION) == Refusal(
        Action.CALIBRATION, "a recording is running: the calibration changes after it", Cause.HELD)
    with pytest.raises(RigHeld, match=r"^a recording is running: the calibration changes after it$"):
        model.set_calibration(None)
    assert model.calibration is cal and heard.events == []
    model.release(Holder.RECORDING)
    assert model.refusal(Action.CALIBRATION) is None
    model.set_calibration(None)
    assert model.calibration is None and heard.of("calibration_changed") == [(None,)]


def test_anything_but_a_calibration_is_refused(model):
    with pytest.raises(TypeError, match=r"`calibration` must be a CaptureCalibration or None; got str"):
        model.set_calibration("calibration.json")
    assert model.calibration is None


# ---------------------------------------------------------------------- who holds the devices
def test_the_holder_follows_the_live_view_a_recording_and_the_end(model):
    heard = Heard(model)
    assert model.holder is Holder.IDLE
    model.take(Holder.LIVE)
    assert model.holder is Holder.LIVE and model.live and not model.recording
    model.take(Holder.RECORDING)  # a recording takes the devices from the live view
    assert model.holder is Holder.RECORDING and model.recording and not model.live
    model.release(Holder.LIVE)  # the live view stopped for it: nothing changes
    assert model.holder is Holder.RECORDING
    model.release(Holder.RECORDING)
    assert model.holder is Holder.IDLE
    assert heard.of("holder_changed") == [(Holder.LIVE,), (Holder.RECORDING,), (Holder.IDLE,)]


def test_a_calibration_elsewhere_holds_the_rig_once_the_model_is_told(model, elsewhere):
    heard = Heard(model)
    elsewhere.reason = CALIBRATING
    assert model.holder is Holder.CALIBRATING  # asked when read
    model.refresh()
    model.refresh()  # told twice: said once
    elsewhere.reason = None
    model.refresh()
    assert model.holder is Holder.IDLE
    assert heard.of("holder_changed") == [(Holder.CALIBRATING,), (Holder.IDLE,)]


def test_a_recording_holds_the_rig_even_while_a_calibration_would(model, elsewhere):
    model.take(Holder.RECORDING)
    elsewhere.reason = CALIBRATING
    assert model.holder is Holder.RECORDING


def test_only_capture_s_own_uses_are_taken_or_released(model):
    for holder in (Holder.IDLE, Holder.CALIBRATING):
        with pytest.raises(ValueError, match=r"`holder` must be Holder.LIVE or Holder.RECORDING .*; got <Holder"):
            model.take(holder)
        with pytest.raises(ValueError, match=r"`holder` must be Holder.LIVE or Holder.RECORDING"):
            model.release(holder)
    assert model.holder is Holder.IDLE


# ---------------------------------------------------------------------- the refusals
def test_the_live_view_is_refused_during_a_recording_and_a_calibration(model, elsewhere):
    assert model.refusal(Action.LIVE) is None
    model.take(Holder.RECORDING)
    assert model.refusal(Action.LIVE) == Refusal(Action.LIVE, "cannot start: a recording is running", Cause.HELD)
    with pytest.raises(RigHeld, match=r"^cannot start: a recording is running$"):
        model.take(Holder.LIVE)
    model.release(Holder.RECORDING)
    elsewhere.reason = CALIBRATING
    with pytest.raises(RigHeld, match=rf"^cannot start: {CALIBRATING}$"):
        model.take(Holder.LIVE)
    assert model.holder is Holder.CALIBRATING


def test_a_recording_is_refused_for_its_timing_a_running_recording_and_a_calibration(model, elsewhere):
    model.set_plan(bad_timing())
    refusal = model.refusal(Action.RECORD)
    assert refusal.cause is Cause.SETTINGS
    assert refusal.text == "cannot record: " + "; ".join(bad_timing().timing().errors)
    model.set_plan(CapturePlan(tile=(4, 4)))
    model.take(Holder.RECORDING)
    assert model.refusal(Action.RECORD) == Refusal(Action.RECORD, "cannot record: a recording is running", Cause.HELD)
    model.release(Holder.RECORDING)
    elsewhere.reason = CALIBRATING
    assert model.refusal(Action.RECORD) == Refusal(Action.RECORD, f"cannot record: {CALIBRATING}", Cause.HELD)
    with pytest.raises(RigHeld, match=rf"^cannot record: {CALIBRATING}$"):
        model.take(Holder.RECORDING)


def test_check_shows_the_refusal_until_the_rig_is_free(model, elsewhere):
    heard = Heard(model)
    elsewhere.reason = CALIBRATING
    assert not model.check(Action.LIVE) and not model.check(Action.RECORD)
    assert model.shown(Action.LIVE).text == f"cannot start: {CALIBRATING}"
    assert model.shown(Action.RECORD).text == f"cannot record: {CALIBRATING}"
    model.recheck(settings_changed=True)  # a held rig's refusal stays until the rig is free
    assert model.shown(Action.LIVE) is not None
    elsewhere.reason = None
    model.refresh()
    assert model.shown(Action.LIVE) is None and model.shown(Action.RECORD) is None
    assert [(a, r is None) for a, r in heard.of("refusal_changed")] == [
        (Action.LIVE, False), (Action.RECORD, False), (Action.LIVE, True), (Action.RECORD, True)]
    assert model.check(Action.LIVE) and model.check(Action.RECORD)


def test_a_settings_refusal_stays_until_the_settings_change(model):
    model.refuse(Action.RECORD, "choose a recording path first (folder/name.zarr)")
    model.recheck()  # the rig is free, but the path is still missing
    assert model.shown(Action.RECORD) == Refusal(
        Action.RECORD, "choose a recording path first (folder/name.zarr)", Cause.SETTINGS)
    model.recheck(settings_changed=True, actions=(Action.LIVE,))  # another action's settings
    assert model.shown(Action.RECORD) is not None
    model.recheck(settings_changed=True, actions=(Action.RECORD,))
    assert model.shown(Action.RECORD) is None


def test_a_device_error_goes_once_a_device_changes_state_and_a_settings_refusal_does_not(model):
    model.refuse(Action.LIVE, "cannot start: the camera is not connected", Cause.DEVICE)
    model.refuse(Action.RECORD, "choose a recording path first (folder/name.zarr)")
    model.recheck()  # nothing changed: both stay
    assert model.shown(Action.LIVE) is not None and model.shown(Action.RECORD) is not None
    model.refresh()  # a device changed state (the camera reconnected): its error spoke of the state before
    assert model.shown(Action.LIVE) is None
    assert model.shown(Action.RECORD).cause is Cause.SETTINGS  # the path is still missing
    model.refuse(Action.LIVE, "cannot start: the camera is not connected", Cause.DEVICE)
    model.recheck(settings_changed=True)  # the settings changed: a device error goes too
    assert model.shown(Action.LIVE) is None


def test_starting_clears_the_refusal_and_a_running_action_keeps_what_it_shows(model):
    model.refuse(Action.LIVE, "cannot start: the camera is not connected")
    model.take(Holder.LIVE)
    assert model.shown(Action.LIVE) is None
    model.refuse(Action.RECORD, "not recording: you chose not to record with this calibration")
    model.take(Holder.RECORDING)
    assert model.shown(Action.RECORD) is None
    model.refuse(Action.RECORD, "cannot record: a recording is running", Cause.HELD)
    model.recheck(settings_changed=True)
    assert model.shown(Action.RECORD).text == "cannot record: a recording is running"
    model.clear(Action.RECORD)
    assert model.shown(Action.RECORD) is None


def test_an_unknown_action_is_refused():
    with pytest.raises(ValueError, match=r"`action` must be an Action; got 'record'"):
        CaptureModel().refusal("record")


def test_the_model_and_the_holder_it_shares_with_the_device_service_import_and_run_without_qt():
    code = ("import sys\n"
            "class Block:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name.split('.')[0] in ('PySide6', 'shiboken6', 'pyqtgraph'):\n"
            "            raise ImportError(name)\n"
            "sys.meta_path.insert(0, Block())\n"
            "from flexvox_app.gui.models.capture_model import CaptureModel, Holder\n"
            "from flexvox_app.gui.models import holder, rig_service\n"
            "assert holder.Holder is Holder and rig_service.Holder is Holder\n"  # one Holder, shared
            "m = CaptureModel()\n"
            "m.take(Holder.LIVE)\n"
            "assert not [n for n in sys.modules if n.split('.')[0] in ('PySide6', 'pyqtgraph')]\n"
            "print(m.holder.value)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "live"
