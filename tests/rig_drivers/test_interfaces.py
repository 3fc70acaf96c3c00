"""Settings validation, the lifecycle rules and the error hierarchy."""

import subprocess
import sys

import numpy as np
import pytest

from rig_drivers import errors
from rig_drivers.errors import IncompatibleStateError, SettingError
from rig_drivers.interfaces import (
    CameraSettings,
    Device,
    DeviceState,
    Frame,
    PatternSequence,
    SyncSettings,
    TriggerActivation,
    TriggerConfig,
    TriggerSource,
    check_pattern_timing,
)


def test_error_hierarchy():
    for cls in (errors.DeviceNotFoundError, errors.DevicePermissionError, errors.DeviceBusyError,
                errors.DeviceTimeoutError, errors.ProtocolError, errors.IncompatibleStateError,
                errors.SettingError):
        assert issubclass(cls, errors.DeviceError)
    assert issubclass(SettingError, ValueError)
    rule = 'SUBSYSTEM=="usb", ATTR{idVendor}=="0451", ATTR{idProduct}=="6401", MODE="0666"'
    assert rule in errors.DLPC350_PERMISSION_HINT


@pytest.mark.parametrize(
    "exposure, period, message",
    [
        (4000, 4166, r"`exposure_us` must equal `period_us` or be at most period - 230 µs = 3936 µs; "
                     r"got exposure 4000 µs with period 4166 µs"),
        (5000, 4166, r"`exposure_us` must not exceed `period_us`; got exposure 5000 µs > period 4166 µs"),
        (100, 4166, r"`exposure_us` must be between 235 and 10000000 µs; got 100"),
        (4166, 4166.5, r"`period_us` must be a whole number of µs; got 4166.5"),
        (True, 4166, r"`exposure_us` must be a whole number of µs; got True"),
    ],
)
def test_pattern_timing_rules(exposure, period, message):
    with pytest.raises(SettingError, match=message):
        check_pattern_timing(exposure, period)


def test_pattern_timing_accepts_the_two_legal_forms():
    assert check_pattern_timing(4166, 4166) == (4166, 4166)
    assert check_pattern_timing(3936, 4166) == (3936, 4166)


def test_pattern_sequence_validation_and_immutability():
    seq = PatternSequence(np.ones((16, 2, 3), np.uint8), 4166, 4166)
    assert seq.K == 16 and seq.shape == (2, 3) and seq.sequence_us == 66656
    assert seq.patterns_per_trigger == 16 and seq.trigger_out_every == 16
    with pytest.raises(ValueError, match="read-only"):
        seq.patterns[0, 0, 0] = False
    with pytest.raises(SettingError, match=r"`patterns` must have shape \(K, H, W\); got 2 dimensions \(2, 3\)"):
        PatternSequence(np.ones((2, 3), bool), 4166, 4166)
    with pytest.raises(SettingError, match="`patterns_per_trigger` must divide the 16 patterns; got 5"):
        PatternSequence(np.ones((16, 2, 3), bool), 4166, 4166, patterns_per_trigger=5)
    with pytest.raises(SettingError, match="`patterns` values must be 0/1"):
        PatternSequence(np.full((2, 2, 2), 3), 4166, 4166)
    with pytest.raises(SettingError, match="`patterns` must hold between 1 and 128 patterns; got 129"):
        PatternSequence(np.ones((129, 1, 1), bool), 4166, 4166)


def test_for_camera_rate_rounds_period_down():
    seq = PatternSequence.for_camera_rate(np.ones((16, 1, 1), bool), 15.0)
    assert (seq.period_us, seq.exposure_us) == (4166, 4166)
    with pytest.raises(SettingError, match=r"`camera_fps` must be > 0 and <= 10000 Hz; got -1"):
        PatternSequence.for_camera_rate(np.ones((16, 1, 1), bool), -1)


def test_camera_settings_and_trigger_enums():
    trig = TriggerConfig(TriggerSource.LINE0, TriggerActivation.RISING_EDGE)
    settings = CameraSettings(exposure_us=4000, trigger=trig)
    assert trig.is_hardware and settings.exposure_us == 4000.0 and trig.selector.value == "FrameStart"
    with pytest.raises(SettingError, match=r"`exposure_us` must be > 0 and <= 1e\+07 µs; got 0"):
        CameraSettings(exposure_us=0)
    with pytest.raises(SettingError, match="`source` must be a TriggerSource; got 'Line0'"):
        TriggerConfig("Line0")
    with pytest.raises(SettingError, match="`gain_db` must be between 0 and 48 dB; got 60"):
        CameraSettings(exposure_us=10, gain_db=60)


def test_frame_validation():
    frame = Frame(np.zeros((4, 5), np.uint16), frame_id=3, timestamp_s=0.25)
    assert frame.frame_id == 3
    with pytest.raises(SettingError, match=r"`image` must have shape \(H, W\); got shape \(1, 4, 5\)"):
        Frame(np.zeros((1, 4, 5)), 0, 0.0)
    with pytest.raises(SettingError, match="`frame_id` must be a whole number >= 0; got -1"):
        Frame(np.zeros((4, 5)), -1, 0.0)


def test_sync_settings_limits():
    assert SyncSettings(4166, 16).frame_period_us == 66656
    with pytest.raises(SettingError, match="`period_us` must be between 20 and 1000000 µs; got 10"):
        SyncSettings(10, 16)
    with pytest.raises(SettingError, match="`pulses_per_frame` must be between 1 and 1024; got 0"):
        SyncSettings(4166, 0)


class Recorder(Device):
    def __init__(self, fail_close=False):
        super().__init__(name="recorder")
        self.log = []
        self.fail_close = fail_close

    def _do_open(self):
        self.log.append("open")

    def _do_close(self):
        self.log.append("close")
        if self.fail_close:
            raise errors.DeviceError("close failed")

    def _do_enable(self):
        self.log.append("enable")

    def _do_disable(self):
        self.log.append("disable")


def test_lifecycle_order_and_idempotence():
    dev = Recorder()
    with dev:
        dev.enable()
        dev.enable()
        dev.disable()
        dev.disable()
        dev.enable()
    dev.close()
    assert dev.log == ["open", "enable", "disable", "enable", "disable", "close"]
    with pytest.raises(IncompatibleStateError, match=r"cannot enable: recorder is closed, "
                                                   r"it must be open \(call open\(\) first\)"):
        dev.enable()


def test_close_ends_closed_even_when_the_hook_fails():
    dev = Recorder(fail_close=True)
    dev.open()
    with pytest.raises(errors.DeviceError, match="close failed"):
        dev.close()
    assert dev.state is DeviceState.CLOSED


def test_rig_drivers_imports_without_qt():
    code = (
        "import importlib.abc, sys\n"
        "class B(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('PySide6', 'PyQt5', 'PyQt6', 'shiboken6', 'pyqtgraph', 'qtpy'):\n"
        "            raise ImportError('Qt blocked: ' + name)\n"
        "sys.meta_path.insert(0, B())\n"
        "import rig_drivers.interfaces, rig_drivers.simulated, rig_drivers.dlpc350, rig_drivers.syncbox\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
