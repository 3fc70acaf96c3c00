"""The Projector contract: every implementation must pass these (subclass and provide fixtures).

A subclass provides two fixtures:

- ``projector``: a new, unopened :class:`~rig_drivers.interfaces.Projector`;
- ``device_running``: a callable ``(projector) -> bool`` that reports, from the *device side*
  (the fake controller, the simulator's clock), whether patterns are being shown.
"""

import numpy as np
import pytest

from rig_drivers.errors import IncompatibleStateError, SettingError
from rig_drivers.interfaces import DeviceState, PatternSequence, ProjectorTrigger, RunState


def make_sequence(K=8, shape=(4, 6), period_us=4166, seed=3) -> PatternSequence:
    """A sequence every projector must accept: VSYNC-triggered, exposure = period, 4 per VSYNC."""
    rng = np.random.default_rng(seed)
    return PatternSequence(rng.random((K,) + shape) < 0.5, exposure_us=period_us, period_us=period_us,
                           trigger=ProjectorTrigger.VSYNC, patterns_per_trigger=4)


class ProjectorContract:
    def test_starts_closed_and_refuses_work(self, projector):
        assert projector.state is DeviceState.CLOSED
        with pytest.raises(IncompatibleStateError, match=r"it must be open or enabled \(call open\(\) first\)"):
            projector.load_sequence(make_sequence())

    def test_context_manager_opens_and_closes(self, projector):
        with projector as p:
            assert p is projector and projector.state is DeviceState.OPEN
            projector.enable()
            assert projector.state is DeviceState.ENABLED
        assert projector.state is DeviceState.CLOSED

    def test_open_twice_is_refused(self, projector):
        with projector:
            with pytest.raises(IncompatibleStateError, match="cannot open: .* is open, it must be closed"):
                projector.open()

    def test_start_needs_enable_and_a_sequence(self, projector, device_running):
        with projector:
            projector.load_sequence(make_sequence())
            with pytest.raises(IncompatibleStateError, match=r"call enable\(\) first"):
                projector.start()
            projector.enable()
            projector.start()
            assert projector.run_state is RunState.RUNNING and device_running(projector)

    def test_start_without_sequence_is_refused(self, projector):
        with projector:
            projector.enable()
            with pytest.raises(IncompatibleStateError, match=r"no sequence loaded \(call load_sequence\(\) first\)"):
                projector.start()

    def test_full_session_run_pause_resume_stop_restart(self, projector, device_running):
        seq = make_sequence()
        with projector:
            projector.enable()
            projector.load_sequence(seq)
            assert projector.sequence is seq and projector.run_state is RunState.STOPPED
            assert not device_running(projector)
            projector.start()
            assert device_running(projector)
            projector.pause()
            assert projector.run_state is RunState.PAUSED and not device_running(projector)
            projector.start()
            assert projector.run_state is RunState.RUNNING and device_running(projector)
            projector.stop()
            assert projector.run_state is RunState.STOPPED and not device_running(projector)
            projector.start()  # a stopped sequence can be started again
            assert device_running(projector)

    def test_load_while_running_is_refused(self, projector):
        with projector:
            projector.enable()
            projector.load_sequence(make_sequence())
            projector.start()
            with pytest.raises(IncompatibleStateError, match=r"while it is running: call stop\(\) first"):
                projector.load_sequence(make_sequence(seed=4))
            assert projector.run_state is RunState.RUNNING

    def test_pause_when_stopped_is_refused(self, projector):
        with projector:
            projector.enable()
            projector.load_sequence(make_sequence())
            with pytest.raises(IncompatibleStateError, match="cannot pause: the sequence is stopped"):
                projector.pause()

    def test_close_while_running_stops(self, projector, device_running):
        projector.open()
        projector.enable()
        projector.load_sequence(make_sequence())
        projector.start()
        projector.close()
        assert projector.state is DeviceState.CLOSED and projector.run_state is RunState.STOPPED
        assert not device_running(projector)
        projector.close()  # idempotent
        assert projector.state is DeviceState.CLOSED

    def test_load_rejects_wrong_type(self, projector):
        with projector:
            with pytest.raises(SettingError, match="`sequence` must be a PatternSequence; got ndarray"):
                projector.load_sequence(np.zeros((8, 4, 6), bool))

    def test_reload_replaces_sequence(self, projector):
        with projector:
            projector.load_sequence(make_sequence())
            second = make_sequence(K=12, seed=5)
            projector.load_sequence(second)
            assert projector.sequence is second and projector.sequence.K == 12
