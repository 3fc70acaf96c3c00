"""Calibration on a DLPC350: its patterns reach the projector's video input through the display sink.

The rig is the fake DLPC350 transport and a camera that sees only what the sink received
(:mod:`tests.rig_drivers.display_rig`), so a homography found here was found through the sink.
"""

import numpy as np

from flexvox_calibration.geometry import homography_error_px
from flexvox_calibration.homography import calibrate_homography
from flexvox_calibration.session import RigSession
from flexvox_calibration.sync import band_patterns
from rig_drivers.dlpc350.bitplanes import unpack_bitplanes
from rig_drivers.interfaces import ProjectorTrigger, RunState
from tests.rig_drivers.display_rig import display_rig


def _recording_loads(projector):
    """Keep every sequence the session loads (the patterns it asked the projector for)."""
    loaded = []
    real = projector.load_sequence

    def load(seq):
        loaded.append(seq)
        real(seq)

    projector.load_sequence = load
    return loaded


def test_the_sink_receives_every_calibration_pattern_and_the_homography_is_found_through_it():
    rig = display_rig()
    screen = rig.projector.display
    loaded = _recording_loads(rig.projector)
    with RigSession.from_rig(rig, projector_size=(48, 64)) as session:
        result = calibrate_homography(session)
        bands, _ = band_patterns(result.homography, session.camera_size, session.projector_size, 16)
        session.capture_single_shot(bands)
    assert result.success, result.message
    assert homography_error_px(result.homography, np.eye(3), (48, 64)) < 0.1  # one camera pixel per projector pixel
    assert result.coverage > 0.99
    # one display call per pattern change, in order, each exactly the loaded sequence's patterns
    assert len(screen.calls) == len(loaded) >= 40
    for frames, seq in zip(screen.calls, loaded, strict=True):
        np.testing.assert_array_equal(unpack_bitplanes(frames, seq.K), seq.patterns)
        assert seq.trigger is ProjectorTrigger.VSYNC  # what the LightCrafter's video port runs
    assert screen.run_states == [RunState.STOPPED] * len(loaded)  # shown before each start
    # the single-shot band code: 16 slots, 4 per VSYNC, played once
    last = loaded[-1]
    assert (last.K, last.patterns_per_trigger, last.repeat) == (16, 4, False)
    np.testing.assert_array_equal(unpack_bitplanes(screen.calls[-1], 16), bands)
