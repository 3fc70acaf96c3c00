"""A LightCrafter pattern-mode session against the fake controller, checked byte for byte
against TI's DLPC350 Programmer's Guide and API (docs/real-rig.md; the golden test checks every
command and the K = 8..32 sessions against TI's API), and every error path of the driver."""

import numpy as np
import pytest

from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
from rig_drivers.dlpc350 import protocol as p
from rig_drivers.errors import (
    DeviceTimeoutError,
    IncompatibleStateError,
    ProtocolError,
    SettingError,
)
from rig_drivers.interfaces import PatternSequence, ProjectorTrigger, RunState

from .dlpc350_helpers import hexrow, k16_sequence


@pytest.fixture
def fake():
    return FakeDLPC350Transport(validate_busy_polls=2)


@pytest.fixture
def lcr(fake):
    dev = DLPC350(fake, poll_interval_s=0, reply_timeout_s=0.01)
    dev.open()
    dev.enable()
    fake.received.clear()
    yield dev
    fake.silent = False
    dev.close()


def test_show_k16_session_packets_byte_for_byte(fake, rng):
    seq = k16_sequence(rng)
    with DLPC350(fake, poll_interval_s=0) as lcr:
        lcr.enable()
        lcr.load_sequence(seq)
        lcr.start()
        assert fake.running
        lcr.stop()
        assert not fake.running

    # LUT: entry k shows bit-plane k (G0..G7, R0..R7); every 4th waits for VSYNC
    # (trigger 01) and swaps buffers (bit 18); LED white (bits 14:12 = 111), 1 bit (bits 11:8 = 1).
    lut = ("01 71 04 07 71 00 0b 71 00 0f 71 00 11 71 04 17 71 00 1b 71 00 1f 71 00 "
           "21 71 04 27 71 00 2b 71 00 2f 71 00 31 71 04 37 71 00 3b 71 00 3f 71 00")
    expected = [
        "40 00 03 00 00 02 00",                          # 0x0200 = 0: leave standby (enable)
        "40 01 03 00 24 1a 00",                          # 0x1A24 = 0: stop
        "40 02 03 00 1b 1a 01",                          # 0x1A1B = 1: pattern display mode
        "40 03 03 00 22 1a 00",                          # 0x1A22 = 0: patterns from the video port
        "40 04 06 00 31 1a 0f 01 0f 00",                 # 0x1A31: 16 entries, repeat, TRIG_OUT_2 per 16, 1 image
        "40 05 03 00 23 1a 00",                          # 0x1A23 = 0: VSYNC trigger mode
        "40 06 0a 00 29 1a 46 10 00 00 46 10 00 00",     # 0x1A29: exposure 4166 µs, period 4166 µs
        "40 07 03 00 33 1a 02",                          # 0x1A33 = 2: open the pattern mailbox
        "40 08 03 00 32 1a 00",                          # 0x1A32 = 0: offset 0
        "40 09 32 00 34 1a " + lut,                      # 0x1A34: 16 x 3-byte LUT entries
        "40 0a 03 00 33 1a 00",                          # 0x1A33 = 0: close the mailbox
        "40 0b 03 00 1a 1a 00",                          # 0x1A1A: validate
        "c0 00 02 00 1a 1a",                             # read 0x1A1A: busy (reads carry sequence 0, as TI's)
        "c0 00 02 00 1a 1a",                             # read 0x1A1A: busy
        "c0 00 02 00 1a 1a",                             # read 0x1A1A: done, no failure bit
        "40 0c 03 00 24 1a 02",                          # 0x1A24 = 2: start
        "40 0d 03 00 24 1a 00",                          # 0x1A24 = 0: stop
        "40 0e 03 00 00 02 01",                          # 0x0200 = 1: standby (close)
    ]
    assert [hexrow(r) for r in fake.received] == expected
    assert all(len(r) == 64 and not any(r[4 + (r[2] | r[3] << 8):]) for r in fake.received)
    # and the fake's state agrees
    entries = fake.pattern_entries()
    assert [e.pattern_number for e in entries] == list(range(16))
    assert (fake.exposure_us, fake.period_us, fake.lut_entries) == (4166, 4166, 16)


def test_restart_after_stop_resends_lut_and_validates(fake, lcr, rng):
    lcr.load_sequence(k16_sequence(rng))
    lcr.start()
    lcr.stop()
    fake.received.clear()
    lcr.start()
    commands = [req.command for req in fake.requests()]
    assert commands[0] == p.Command.START_STOP and p.Command.MAILBOX_DATA in commands
    assert commands[-1] == p.Command.START_STOP and fake.received[-1][6] == 2 and fake.running


def test_pause_resumes_without_reloading(fake, lcr, rng):
    lcr.load_sequence(k16_sequence(rng))
    lcr.start()
    lcr.pause()
    assert fake.run_state == 1
    fake.received.clear()
    lcr.start()
    assert [r[4:7] for r in fake.received] == [bytes([0x24, 0x1A, 0x02])]
    assert fake.running


def test_version_and_status_in_words(lcr):
    assert lcr.version()["application"] == "3.0.0"
    status = lcr.status()
    assert status.ok and not status.sequencer_running
    assert "internal initialisation successful" in status.words()
    assert "sequencer stopped" in status.words()


def test_exposure_period_rule_checked_before_sending(fake, lcr):
    with pytest.raises(SettingError, match=r"`exposure_us` must equal `period_us` or be at most "
                                           r"period - 230 µs \(DLPC350 rule\); "
                                           r"got exposure 4000 µs with period 4166 µs"):
        lcr.set_exposure_period(4000, 4166)
    assert fake.received == []
    lcr.set_exposure_period(3936, 4166)  # exactly 230 µs of dark time is allowed
    assert (fake.exposure_us, fake.period_us) == (3936, 4166)


def test_video_port_needs_exposure_equal_period(fake, lcr, rng):
    seq = PatternSequence(rng.random((8, 4, 4)) < 0.5, 3000, 4166, trigger=ProjectorTrigger.VSYNC,
                          patterns_per_trigger=4)
    with pytest.raises(SettingError, match=r"`exposure_us` must equal `period_us` "
                                           r"with video-port patterns"):
        lcr.load_sequence(seq)
    assert fake.received == []


def test_groups_must_fit_one_vsync(fake, lcr, rng):
    seq = PatternSequence(rng.random((16, 4, 4)) < 0.5, 4166, 4166, trigger=ProjectorTrigger.VSYNC)
    with pytest.raises(SettingError, match=r"must fit one VSYNC period of 16667 µs at 60 Hz; got 16 x 4166 µs "
                                           r"= 66656 µs \(at most 4 patterns per VSYNC\)"):
        lcr.load_sequence(seq)
    assert fake.received == []


def test_non_vsync_trigger_is_refused(lcr, rng):
    seq = PatternSequence(rng.random((4, 4, 4)) < 0.5, 4166, 4166, trigger=ProjectorTrigger.INTERNAL)
    with pytest.raises(SettingError, match="`trigger` must be VSYNC for the LightCrafter 4500"):
        lcr.load_sequence(seq)


def test_nak_names_the_command(fake, lcr):
    with pytest.raises(ProtocolError, match=r"refused 0x1A99 \(NAK: error flag set in the reply\)"):
        lcr.write_command(0x1A99, b"\x00")
    with pytest.raises(ProtocolError, match=r"refused LUT_CONTROL \(0x1A31\) \(NAK"):
        lcr.write_command(p.Command.LUT_CONTROL, b"\x00\x01")  # bad length


def test_config_while_running_is_nakked_by_the_device(fake, lcr, rng):
    lcr.load_sequence(k16_sequence(rng))
    lcr.start()
    with pytest.raises(ProtocolError, match=r"refused EXPOSURE_PERIOD \(0x1A29\)"):
        lcr.set_exposure_period(4166, 4166)


def test_validation_failure_bits_are_decoded(fake, lcr):
    # Bypass the driver's own checks: write a LUT with a bad pattern number and bad timing raw.
    lcr.write_command(p.Command.DISPLAY_MODE, b"\x01")
    lcr.write_command(p.Command.EXPOSURE_PERIOD, bytes.fromhex("a00f0000 46100000"))  # 4000 / 4166 µs
    lcr.write_command(p.Command.LUT_CONTROL, bytes([0, 1, 0, 0]))
    lcr.write_pattern_lut([p.LutEntry(pattern_number=40, trigger=p.LutTrigger.INTERNAL)])
    with pytest.raises(ProtocolError, match=r"rejected the pattern sequence: bad timing: exposure or frame period "
                                            r"settings are invalid; bad pattern number: .*; warning: frame period "
                                            r"minus exposure is less than 230 µs"):
        lcr.validate()
    with pytest.raises(ProtocolError, match=r"refused START_STOP \(0x1A24\)"):
        lcr.write_command(p.Command.START_STOP, b"\x02")  # the device will not start unvalidated


def test_validation_busy_forever_times_out(fake, lcr):
    fake.validate_busy_polls = 10**6
    lcr._validate_timeout_s = 0.02
    lcr._poll_interval_s = 0.005
    with pytest.raises(DeviceTimeoutError, match=r"still validating \(busy bit set\) after 0.02 s"):
        lcr.validate()


def test_silent_device_times_out_with_advice(fake, lcr):
    fake.silent = True
    with pytest.raises(DeviceTimeoutError, match=r"no reply to GET_VERSION \(0x0205\) within 0.01 s: check the USB "
                                                 r"cable, close TI's LightCrafter GUI"):
        lcr.version()


def test_malformed_and_mismatched_replies(fake, lcr):
    fake.inject_reply(b"\x40\x00")
    with pytest.raises(ProtocolError, match=r"malformed reply to GET_VERSION \(0x0205\): a report must be 64 bytes"):
        lcr.version()
    fake.inject_reply(p.build_reply(200, bytes(16), read=True)[0])
    with pytest.raises(ProtocolError, match="carries sequence number 200, expected 0: another program"):
        lcr.version()  # reads carry sequence number 0, as TI's API sends them
    fake.inject_reply(p.build_reply(0, b"\x01\x02", read=True)[0])
    with pytest.raises(ProtocolError, match=r"2 data bytes, expected 16"):
        lcr.version()


def test_trigger_outputs_encode_delays(fake, lcr):
    lcr.configure_trigger_output(2, rising_us=1.072)
    assert hexrow(fake.received[-1]) == "40 01 04 00 1e 1a 00 c5"  # 0xBB + 10 steps of 107.2 ns
    lcr.configure_trigger_output(1, invert=True, rising_us=-20.0, falling_us=0)
    assert fake.received[-1][6:9] == bytes([0x01, 0x00, 0xBB])  # invert in bit 0; -20 µs -> code 0x00
    assert fake.trig_out[1] == bytes([0x01, 0x00, 0xBB])  # the fake took what TI sends
    with pytest.raises(SettingError, match=r"a TRIG_OUT delay must be between -20.05 and \+2.787 µs"):
        lcr.configure_trigger_output(2, rising_us=3)
    with pytest.raises(ProtocolError, match=r"refused TRIG_OUT2 \(0x1A1E\) \(NAK"):
        lcr.write_command(p.Command.TRIG_OUT2, bytes([0b10, 0xBB]))  # the programmer's guide's bit 1: refused
    with pytest.raises(ProtocolError, match=r"refused TRIG_OUT2"):
        lcr.write_command(p.Command.TRIG_OUT2, bytes([0, 0xD6]))  # an LED strobe delay code
    lcr.configure_trigger_input(delay_us=107.136)
    assert fake.received[-1][6:10] == (1000).to_bytes(4, "little")


def test_trigger_config_refused_while_running(lcr, rng):
    lcr.load_sequence(k16_sequence(rng))
    lcr.start()
    with pytest.raises(IncompatibleStateError, match="cannot configure a trigger output while the sequence is running"):
        lcr.configure_trigger_output(2)
    assert lcr.run_state is RunState.RUNNING


def test_frames_for_packs_the_masks(lcr, rng):
    seq = k16_sequence(rng)
    frames = lcr.frames_for(seq)
    assert frames.shape == (1, 8, 12, 3) and frames.dtype == np.uint8
    assert np.array_equal((frames[0, :, :, 1] >> 3) & 1, seq.patterns[3])   # pattern 3 -> G3
    assert np.array_equal((frames[0, :, :, 0] >> 2) & 1, seq.patterns[10])  # pattern 10 -> R2


def test_constructor_rejects_a_non_transport():
    with pytest.raises(SettingError, match=r"`transport` must have open/close/write/read "
                                           r"methods; object has no open\(\)"):
        DLPC350(object())


def test_a_long_lut_is_one_message_over_several_reports(fake, lcr, rng):
    seq = PatternSequence(rng.random((24, 4, 4)) < 0.5, 4166, 4166, trigger=ProjectorTrigger.VSYNC,
                          patterns_per_trigger=4)
    lcr.load_sequence(seq)
    data = [r for r in fake.requests() if r.command == p.Command.MAILBOX_DATA]
    offsets = [r.payload[0] for r in fake.requests() if r.command == p.Command.MAILBOX_OFFSET]
    assert [len(r.payload) for r in data] == [72] and offsets == [0]  # TI API DLPC350_SendPatLut
    first = next(i for i, r in enumerate(fake.received) if r[4:6] == bytes([0x34, 0x1A]))
    assert fake.received[first][2:4] == (74).to_bytes(2, "little")  # the length counts the whole message
    assert fake.received[first + 1][:12] == data[0].payload[58:70]  # the continuation: no header
    assert [e.pattern_number for e in fake.pattern_entries()] == list(range(24))
    back = lcr.read_pattern_lut(24)  # a long reply, over two reports
    assert [e.pattern_number for e in back] == list(range(24))


def test_led_source_power_and_error_controls(fake, lcr, rng):
    lcr.set_led_currents(10, 200, 255)
    assert fake.led_currents == bytes([10, 200, 255]) and lcr.led_currents() == (10, 200, 255)
    with pytest.raises(SettingError, match=r"`green` must be between 0 and 255; got 256"):
        lcr.set_led_currents(0, 256, 0)
    lcr.set_led_enables(automatic=False, red=False, blue=False)
    assert lcr.led_enables() == {"automatic": False, "red": False, "green": True, "blue": False}
    lcr.set_led_enables()  # the sequence drives the LEDs
    assert fake.led_enable == 0b1111 and lcr.led_enables()["automatic"]
    lcr.set_input_source(p.InputSource.TEST_PATTERN, 24)
    assert lcr.input_source() == (p.InputSource.TEST_PATTERN, 24)
    with pytest.raises(SettingError, match=r"`port_width` must be one of 30, 24, 20, 16, 10, 8 bits; got 12"):
        lcr.set_input_source(p.InputSource.PARALLEL, 12)
    assert lcr.power_mode() == "normal" and lcr.errors() == []
    lcr.load_sequence(k16_sequence(rng))
    lcr.start()
    with pytest.raises(IncompatibleStateError, match="cannot select the input source while the sequence is running"):
        lcr.set_input_source(p.InputSource.PARALLEL)
    lcr.set_led_currents(50, 50, 50)  # the light can change while it runs
    assert fake.led_currents == bytes([50, 50, 50])
    with pytest.raises(ProtocolError, match=r"refused LED_ENABLE"):
        lcr.write_command(p.Command.LED_ENABLE, bytes([0x10]))  # a reserved bit


def test_status_errors_in_words():
    assert p.Status(0b1000_1001, 1, 0).errors() == [
        "forced swap error (pattern timing does not match the video VSYNC)", "sequencer error"]
    assert p.Status(0, 0, 0).errors() == ["internal initialisation FAILED", "internal memory test FAILED"]


def test_a_nak_with_a_long_length_field_is_a_refusal_not_a_timeout(fake, lcr):
    bad = bytearray(p.build_reply(0, error=True)[0])
    bad[2:4] = (200).to_bytes(2, "little")  # says continuation reports follow; a NAK never has any
    fake.inject_reply(bytes(bad))
    with pytest.raises(ProtocolError, match=r"refused POWER_CONTROL \(0x0200\) \(NAK"):
        lcr.set_standby(False)
    assert lcr.power_mode() == "normal"  # the next command is answered as usual
