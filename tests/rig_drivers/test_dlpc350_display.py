"""The DLPC350's display sink: the packed frames of every loaded sequence, in order, after validation."""

import numpy as np
import pytest

from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport, ProjectorDisplayError
from rig_drivers.dlpc350.bitplanes import pack_bitplanes, unpack_bitplanes
from rig_drivers.errors import DeviceError, DeviceTimeoutError, SettingError
from rig_drivers.interfaces import PatternSequence, ProjectorTrigger, RunState
from rig_drivers.profile import open_rig

from .display_rig import RecordingScreen
from .dlpc350_helpers import hexrow, k16_sequence


def _session_bytes(display, seq):
    fake = FakeDLPC350Transport(validate_busy_polls=2)
    with DLPC350(fake, poll_interval_s=0, display=display) as lcr:
        lcr.enable()
        lcr.load_sequence(seq)
        lcr.start()
        lcr.stop()
    return [hexrow(r) for r in fake.received]


def test_loading_hands_exactly_the_packed_frames_to_the_sink_in_order(rng):
    screen = RecordingScreen()
    fake = FakeDLPC350Transport()
    lcr = DLPC350(fake, poll_interval_s=0, display=screen)
    screen.projector = lcr
    seqs = [k16_sequence(rng),
            PatternSequence(rng.random((30, 8, 12)) < 0.5, 2000, 2000, trigger=ProjectorTrigger.VSYNC,
                            patterns_per_trigger=6),
            lcr.video_sequence(np.ones((4, 8, 12), bool), 4166)]
    with lcr:
        lcr.enable()
        for seq in seqs:
            lcr.load_sequence(seq)
            lcr.start()
            lcr.stop()
    assert len(screen.calls) == 3
    for frames, seq in zip(screen.calls, seqs, strict=True):
        np.testing.assert_array_equal(frames, pack_bitplanes(seq.patterns))  # byte for byte
        np.testing.assert_array_equal(unpack_bitplanes(frames, seq.K), seq.patterns)
    assert [f.shape for f in screen.calls] == [(1, 8, 12, 3), (2, 8, 12, 3), (1, 8, 12, 3)]
    assert screen.run_states == [RunState.STOPPED] * 3  # on screen before the sequence starts


def test_the_sink_leaves_the_usb_session_byte_for_byte_unchanged(rng):
    seq = k16_sequence(rng)
    assert _session_bytes(RecordingScreen(), seq) == _session_bytes(None, seq)


def test_a_sequence_that_does_not_validate_is_not_shown(rng):
    screen = RecordingScreen()
    fake = FakeDLPC350Transport(validate_busy_polls=10**6)
    with DLPC350(fake, poll_interval_s=0, validate_timeout_s=0.01, display=screen) as lcr:
        with pytest.raises(DeviceTimeoutError, match=r"still validating \(busy bit set\) after 0.01 s"):
            lcr.load_sequence(k16_sequence(rng))
    assert screen.calls == []


def test_a_failing_sink_is_a_device_error_that_names_the_cause(rng):
    def broken(frames):
        raise TimeoutError("the projector window did not show the frames within 5 s")

    with DLPC350(FakeDLPC350Transport(), poll_interval_s=0, display=broken) as lcr:
        with pytest.raises(ProjectorDisplayError,
                           match=r"could not show the 1 pattern frame\(s\) of 12x8 on the projector's video input: "
                                 r"TimeoutError: the projector window did not show the frames within 5 s") as info:
            lcr.load_sequence(k16_sequence(rng))
        assert isinstance(info.value, DeviceError) and isinstance(info.value.__cause__, TimeoutError)
        assert lcr.sequence is None  # not loaded: start() is refused rather than running unseen patterns


def test_the_sink_is_validated_and_settable():
    with pytest.raises(SettingError, match=r"`display` must be a callable taking the \(N, H, W, 3\) uint8 frames, "
                                           r"or None; got int"):
        DLPC350(FakeDLPC350Transport(), display=3)
    lcr = DLPC350(FakeDLPC350Transport())
    assert lcr.display is None
    screen = RecordingScreen()
    lcr.display = screen
    assert lcr.display is screen
    with pytest.raises(SettingError, match="`display` must be a callable"):
        lcr.display = "screen 1"


def test_video_sequence_fits_the_vsync_period():
    lcr = DLPC350(FakeDLPC350Transport())
    seq = lcr.video_sequence(np.zeros((16, 4, 4), bool), 4166, repeat=False)
    assert (seq.trigger, seq.patterns_per_trigger, seq.trigger_out_every, seq.repeat) == \
        (ProjectorTrigger.VSYNC, 4, 16, False)
    assert lcr.video_sequence(np.zeros((4, 4, 4), bool), 4166).patterns_per_trigger == 4
    assert lcr.video_sequence(np.zeros((30, 4, 4), bool), 500).patterns_per_trigger == 6  # divides 24 too
    lcr.check_sequence(seq)
    with pytest.raises(SettingError, match=r"`period_us` must fit one VSYNC period of 16667 µs at 60 Hz; "
                                           r"got 20000 µs with K = 2"):
        lcr.video_sequence(np.zeros((2, 4, 4), bool), 20000)


def test_open_rig_passes_the_sink_to_the_projector():
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "rig_drivers" / "examples" / "lab-rig.toml"
    screen = RecordingScreen()
    rig = open_rig(example, projector_display=screen)
    assert isinstance(rig.projector, DLPC350) and rig.projector.display is screen
    assert open_rig(example).projector.display is None
