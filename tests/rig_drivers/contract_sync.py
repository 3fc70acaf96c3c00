"""The SyncController contract: every implementation must pass these.

A subclass provides ``sync`` (a new, unopened SyncController) and ``advance`` (a callable
``(us) -> None`` that moves the box's clock forward).
"""

import pytest

from rig_drivers.errors import IncompatibleStateError, SettingError
from rig_drivers.interfaces import DeviceState, SyncSettings

SETTINGS = SyncSettings(period_us=4166, pulses_per_frame=16)


class SyncControllerContract:
    def test_starts_closed_and_refuses_configure(self, sync):
        assert sync.state is DeviceState.CLOSED
        with pytest.raises(IncompatibleStateError, match=r"cannot configure: .* \(call open\(\) first\)"):
            sync.configure(SETTINGS)

    def test_start_needs_enable_and_settings(self, sync):
        with sync:
            with pytest.raises(IncompatibleStateError, match=r"call enable\(\) first"):
                sync.start()
            sync.enable()
            with pytest.raises(IncompatibleStateError, match=r"cannot start: call configure\(\) first"):
                sync.start()

    def test_counts_pulses_and_time(self, sync, advance):
        with sync:
            sync.configure(SETTINGS)
            assert sync.settings == SETTINGS
            sync.enable()
            sync.start()
            assert sync.running
            advance(10 * 4166 + 7)
            assert sync.pulse_count() == 11  # the first pulse fires at start
            assert sync.elapsed_us() == 10 * 4166 + 7

    def test_stop_freezes_and_start_restarts_counters(self, sync, advance):
        with sync:
            sync.configure(SETTINGS)
            sync.enable()
            sync.start()
            advance(3 * 4166)
            sync.stop()
            assert not sync.running
            advance(100 * 4166)
            assert sync.pulse_count() == 4 and sync.elapsed_us() == 3 * 4166
            sync.start()
            advance(4166 - 1)
            assert sync.pulse_count() == 1 and sync.elapsed_us() == 4165

    def test_configure_while_running_is_refused(self, sync):
        with sync:
            sync.configure(SETTINGS)
            sync.enable()
            sync.start()
            with pytest.raises(IncompatibleStateError, match=r"cannot configure while running: call stop\(\) first"):
                sync.configure(SyncSettings(period_us=1000, pulses_per_frame=4))
            assert sync.settings == SETTINGS

    def test_configure_rejects_wrong_type(self, sync):
        with sync:
            with pytest.raises(SettingError, match="`settings` must be SyncSettings; got dict"):
                sync.configure({"period_us": 4166})

    def test_version_is_reported(self, sync):
        with sync:
            version = sync.firmware_version()
        assert isinstance(version, str) and "syncbox" in version

    def test_close_while_running_stops(self, sync):
        sync.open()
        sync.configure(SETTINGS)
        sync.enable()
        sync.start()
        sync.close()
        assert sync.state is DeviceState.CLOSED and not sync.running
