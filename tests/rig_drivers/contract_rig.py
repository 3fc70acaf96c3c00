"""The Rig contract (:class:`rig_drivers.interfaces.Rig`): every rig implementation must pass these.

A subclass provides ``rig``: a new rig whose devices are not opened.
"""

import numpy as np
import pytest

from rig_drivers.errors import DeviceError, SettingError
from rig_drivers.interfaces import (
    Camera,
    DeviceState,
    PatternSequence,
    Projector,
    Rig,
    SyncController,
    TriggerSource,
)
from rig_drivers.pixel_layout import LAYOUTS

PERIOD_US = 4166


def _devices(rig):
    return [d for d in (rig.projector, rig.camera, rig.sync) if d is not None]


class RigContract:
    def test_declares_the_rig_protocol(self, rig):
        assert isinstance(rig, Rig)
        assert isinstance(rig.name, str) and rig.name
        assert isinstance(rig.projector, Projector) and isinstance(rig.camera, Camera)
        assert rig.sync is None or isinstance(rig.sync, SyncController)
        assert rig.trigger_line in [s for s in TriggerSource if s.value.startswith("Line")]
        assert rig.pixel_layout in LAYOUTS and rig.pixel_layout == rig.projector.pixel_layout
        assert isinstance(rig.video_port, bool) and rig.video_port is rig.projector.video_port

    def test_is_built_closed(self, rig):
        assert all(d.state is DeviceState.CLOSED for d in _devices(rig))

    def test_its_projector_takes_patterns_of_its_projector_size(self, rig):
        H, W = rig.projector_size
        assert H > 0 and W > 0 and tuple(rig.projector.size) == (H, W)
        patterns = np.zeros((4, H, W), bool)
        patterns[:, ::2] = True
        with rig.projector as projector:
            projector.enable()
            if rig.video_port:  # sequences from the video port, paced by VSYNC
                seq = projector.video_sequence(patterns, PERIOD_US)
            else:
                seq = PatternSequence(patterns, PERIOD_US, PERIOD_US)
                with pytest.raises(SettingError, match=r"takes no patterns on a video port: build a PatternSequence"):
                    projector.video_sequence(patterns, PERIOD_US)
            projector.load_sequence(seq)
            assert projector.sequence.shape == (H, W)
            with pytest.raises(SettingError, match=r"patterns"):
                projector.load_sequence(PatternSequence(patterns[:, : H // 2], PERIOD_US, PERIOD_US))

    def test_simulated_and_truth_go_together(self, rig):
        if rig.simulated is None:
            assert rig.truth is None
            return
        assert rig.truth is rig.simulated.truth
        assert rig.truth.homography.shape == (3, 3)
        assert rig.projector is rig.simulated.projector and rig.camera is rig.simulated.camera

    def test_close_closes_every_device(self, rig):
        for d in _devices(rig):
            d.open()
            d.enable()
        rig.close()
        assert all(d.state is DeviceState.CLOSED for d in _devices(rig))
        rig.close()  # closing a closed rig does nothing
        assert all(d.state is DeviceState.CLOSED for d in _devices(rig))

    def test_close_closes_the_others_when_one_fails(self, rig, monkeypatch):
        for d in _devices(rig):
            d.open()

        def fails():
            raise DeviceError("the camera's cable was pulled")

        monkeypatch.setattr(rig.camera, "_do_close", fails)
        with pytest.raises(DeviceError, match=r"the camera's cable was pulled"):
            rig.close()
        assert all(d.state is DeviceState.CLOSED for d in _devices(rig))
