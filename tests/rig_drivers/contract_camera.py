"""The Camera contract: every implementation must pass these (subclass and provide fixtures).

A subclass provides ``camera``: a new, unopened :class:`~rig_drivers.interfaces.Camera` that
delivers free-running frames once acquiring (with a small ``read_frame`` timeout), and
``exposure_us``: an exposure it accepts.
"""

import numpy as np
import pytest

from rig_drivers.errors import IncompatibleStateError, SettingError
from rig_drivers.interfaces import (
    CameraCapabilities,
    CameraSettings,
    DeviceState,
    Frame,
    TriggerConfig,
    TriggerSource,
)

TIMEOUT_S = 2.0


class CameraContract:
    @pytest.fixture
    def exposure_us(self):
        return 5000.0

    def test_starts_closed_and_refuses_configure(self, camera, exposure_us):
        assert camera.state is DeviceState.CLOSED and camera.settings is None
        with pytest.raises(IncompatibleStateError, match=r"cannot configure: .* \(call open\(\) first\)"):
            camera.configure(CameraSettings(exposure_us=exposure_us))

    def test_context_manager_and_shape(self, camera):
        with camera as cam:
            assert cam is camera and camera.state is DeviceState.OPEN
            H, W = camera.sensor_shape
            assert isinstance(camera.capabilities, CameraCapabilities)
        assert H >= 1 and W >= 1 and camera.state is DeviceState.CLOSED

    def test_start_needs_enable_and_configure(self, camera, exposure_us):
        with camera:
            with pytest.raises(IncompatibleStateError, match=r"call enable\(\) first"):
                camera.start_acquisition()
            camera.enable()
            with pytest.raises(IncompatibleStateError, match=r"cannot start acquisition: call configure\(\) first"):
                camera.start_acquisition()
            assert not camera.acquiring

    def test_read_before_start_is_refused(self, camera, exposure_us):
        with camera:
            camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.enable()
            with pytest.raises(IncompatibleStateError, match=r"call start_acquisition\(\) first"):
                camera.read_frame(timeout_s=0.05)

    def test_free_run_frames_have_shape_increasing_ids_and_times(self, camera, exposure_us):
        with camera:
            camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.enable()
            camera.start_acquisition()
            assert camera.acquiring
            frames = [camera.read_frame(timeout_s=TIMEOUT_S) for _ in range(3)]
            shape = camera.sensor_shape
        for f in frames:
            assert isinstance(f, Frame) and f.image.shape == shape and np.isfinite(f.image).all()
        ids = [f.frame_id for f in frames]
        times = [f.timestamp_s for f in frames]
        assert ids == sorted(set(ids)) and times == sorted(times)

    def test_configure_while_acquiring_is_refused(self, camera, exposure_us):
        with camera:
            camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.enable()
            camera.start_acquisition()
            with pytest.raises(IncompatibleStateError, match=r"cannot configure while acquiring"):
                camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.stop_acquisition()
            assert not camera.acquiring
            camera.configure(CameraSettings(exposure_us=exposure_us, gain_db=0))
            assert camera.settings.exposure_us == exposure_us

    def test_hardware_trigger_follows_capabilities(self, camera, exposure_us):
        settings = CameraSettings(exposure_us=exposure_us, trigger=TriggerConfig(source=TriggerSource.LINE0))
        with camera:
            if camera.capabilities.hardware_trigger:
                camera.configure(settings)
                assert camera.settings.trigger.source is TriggerSource.LINE0
            else:
                with pytest.raises(SettingError, match="has no hardware trigger: it cannot shutter"):
                    camera.configure(settings)
                assert camera.settings is None

    def test_software_trigger_needs_software_source(self, camera, exposure_us):
        with camera:
            camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.enable()
            with pytest.raises(IncompatibleStateError, match=r"cannot trigger: call start_acquisition\(\) first"):
                camera.trigger_software()
            camera.start_acquisition()
            with pytest.raises(IncompatibleStateError,
                               match="cannot trigger by software: the trigger source is FreeRun"):
                camera.trigger_software()

    def test_bad_timeout_and_settings_are_refused(self, camera, exposure_us):
        with camera:
            with pytest.raises(SettingError, match="`settings` must be CameraSettings; got dict"):
                camera.configure({"exposure_us": exposure_us})
            camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.enable()
            camera.start_acquisition()
            with pytest.raises(SettingError, match="`timeout_s` must be > 0"):
                camera.read_frame(timeout_s=0)

    def test_close_while_acquiring_stops(self, camera, exposure_us):
        camera.open()
        camera.configure(CameraSettings(exposure_us=exposure_us))
        camera.enable()
        camera.start_acquisition()
        camera.close()
        assert camera.state is DeviceState.CLOSED and not camera.acquiring
        camera.close()  # idempotent
        assert camera.state is DeviceState.CLOSED

    def test_restart_acquisition_delivers_again(self, camera, exposure_us):
        with camera:
            camera.configure(CameraSettings(exposure_us=exposure_us))
            camera.enable()
            camera.start_acquisition()
            first = camera.read_frame(timeout_s=TIMEOUT_S)
            camera.stop_acquisition()
            camera.start_acquisition()
            again = camera.read_frame(timeout_s=TIMEOUT_S)
            shape = camera.sensor_shape
        assert again.image.shape == first.image.shape == shape
        assert again.timestamp_s >= first.timestamp_s
