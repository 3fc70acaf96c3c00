"""DLPC350 packet layout, field encodings and the bit-plane packing."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from rig_drivers.dlpc350 import pack_bitplanes, unpack_bitplanes
from rig_drivers.dlpc350 import protocol as p
from rig_drivers.dlpc350.bitplanes import plane_location
from rig_drivers.errors import ProtocolError, SettingError


def test_write_packet_layout():
    pkt = p.build_packet(0x1A24, b"\x02", seq=7)
    assert len(pkt) == 64
    # flags 0x40 (write, reply wanted), seq, length = 2 command bytes + 1, CMD3 then CMD2, payload
    assert pkt[:7] == bytes([0x40, 7, 3, 0, 0x24, 0x1A, 0x02]) and not any(pkt[7:])


def test_read_packet_layout():
    assert p.build_packet(0x1A0C, read=True, seq=255)[:6] == bytes([0xC0, 255, 2, 0, 0x0C, 0x1A])


def test_payload_must_fit_one_report():
    with pytest.raises(ValueError, match="`payload` must be at most 58 bytes to fit one report; got 59"):
        p.build_packet(0x1A34, bytes(59))


def test_request_round_trip():
    req = p.parse_request(p.build_packet(0x1A29, bytes(range(8)), seq=9))
    assert (req.read, req.reply_wanted, req.seq, req.command, req.payload) == (False, True, 9, 0x1A29, bytes(range(8)))


def test_reply_error_flag_is_a_nak_naming_the_command():
    with pytest.raises(ProtocolError, match=r"refused TRIGGER_MODE \(0x1A23\) \(NAK"):
        p.parse_reply(p.build_reply(4, error=True)[0], command=0x1A23, seq=4)
    assert p.parse_reply(p.build_reply(4, b"\x05", read=True)[0], command=0x1A0C, seq=4) == b"\x05"


def test_lut_control_sends_counts_minus_one():
    # DLPU010G §2.4.3.4.5 Table 2-65 and TI's DLPC350_SetPatternConfig: every count as n - 1.
    assert p.encode_lut_control(16, True, 16, 1) == bytes([15, 1, 15, 0])
    assert p.encode_lut_control(128, False, 256, 64) == bytes([127, 0, 255, 63])
    with pytest.raises(SettingError, match="`entries` must be between 1 and 128; got 129"):
        p.encode_lut_control(129, True, 1, 1)
    with pytest.raises(SettingError, match="`images` must be between 1 and 64; got 0"):
        p.encode_lut_control(1, True, 1, 0)


@pytest.mark.parametrize(
    "exposure, period, message",
    [
        (4001, 4166, r"got exposure 4001 µs with period 4166 µs"),
        (4167, 4166, r"got exposure 4167 µs with period 4166 µs"),
        (0, 4166, r"`exposure_us` must be between 1 and 4294967295 µs; got 0"),
        (4166.0, 4166, r"`exposure_us` must be a whole number of µs; got 4166.0"),
    ],
)
def test_exposure_period_rule(exposure, period, message):
    with pytest.raises(SettingError, match=message):
        p.encode_exposure_period(exposure, period)


def test_exposure_period_encoding():
    assert p.encode_exposure_period(3936, 4166) == (3936).to_bytes(4, "little") + (4166).to_bytes(4, "little")


def test_lut_entry_word_layout():
    entry = p.LutEntry(pattern_number=23, trigger=p.LutTrigger.EXTERNAL_NEGATIVE, bit_depth=1, led=0b100,
                       invert=True, buffer_swap=True)
    word = 2 | 23 << 2 | 1 << 8 | 0b100 << 12 | 1 << 16 | 1 << 18
    assert entry.encode() == word.to_bytes(3, "little")
    assert p.LutEntry.decode(entry.encode()) == entry
    with pytest.raises(SettingError, match="`insert_black` and `trig_out_prev` cannot both be set"):
        p.LutEntry(0, insert_black=True, trig_out_prev=True)
    with pytest.raises(SettingError, match="`pattern_number` must be between 0 and 63; got 64"):
        p.LutEntry(64)


def test_trig_out_delay_code_is_an_offset_count():
    assert p.trig_out_delay_code(0) == 0xBB
    assert p.trig_out_delay_code(-20.05) == 0x00
    assert p.trig_out_delay_code(2.787) == 0xD5  # the last TRIG_OUT code (TI API DLPC350_SetTrigOutConfig)
    with pytest.raises(SettingError, match=r"a TRIG_OUT delay must be between -20.05 and \+2.787 µs \(codes "
                                           r"0x00..0xD5, TI API DLPC350_SetTrigOutConfig\); got 2.9 µs"):
        p.trig_out_delay_code(2.9)  # 0xD6: an LED strobe delay code, not a TRIG_OUT one
    assert p.encode_trig_out(2, invert=True)[1] == bytes([0x01, 0xBB])  # TI API: the invert flag in bit 0
    with pytest.raises(SettingError, match=r"`number` must be 1 \(TRIG_OUT_1\) or 2 \(TRIG_OUT_2\); got 3"):
        p.encode_trig_out(3)


def test_status_and_validation_words():
    status = p.Status(hardware=0b1000_1001, system=0, main=0b10)
    assert not status.ok and status.sequencer_running
    words = status.words()
    assert "forced swap error (pattern timing does not match the video VSYNC)" in words
    assert "sequencer error" in words and "internal memory test FAILED" in words
    result = p.ValidationResult(0b1_0100)
    assert result.ok and len(result.problems) == 2  # warnings only
    assert not p.ValidationResult(0b10).ok


def test_version_decoding():
    data = bytes.fromhex("0200 0103") + bytes(12)  # patch 2, minor 1, major 3 (LE word 0x03010002)
    assert p.decode_version(data)["application"] == "3.1.2"


def test_pack_bit_order_green_first_lsb_first():
    masks = np.zeros((24, 1, 1), bool)
    for k, expected in [(0, (0, 1, 0)), (7, (0, 1, 7)), (8, (0, 0, 0)), (15, (0, 0, 7)), (16, (0, 2, 0)),
                        (23, (0, 2, 7))]:
        assert plane_location(k) == expected
        masks[:] = False
        masks[k] = True
        frame = pack_bitplanes(masks)[0, 0, 0]
        assert frame[expected[1]] == 1 << expected[2] and frame.sum() == 1 << expected[2]
    assert plane_location(24) == (1, 1, 0)


@given(hnp.arrays(bool, st.tuples(st.integers(1, 50), st.integers(1, 5), st.integers(1, 5))))
def test_pack_unpack_round_trip(masks):
    frames = pack_bitplanes(masks)
    assert frames.shape == (-(-masks.shape[0] // 24),) + masks.shape[1:] + (3,) and frames.dtype == np.uint8
    assert np.array_equal(unpack_bitplanes(frames, masks.shape[0]), masks)


def test_pack_rejects_bad_masks():
    with pytest.raises(SettingError, match=r"`masks` must have shape \(K, H, W\) with K, H, W >= 1; got \(4, 4\)"):
        pack_bitplanes(np.zeros((4, 4)))
    with pytest.raises(SettingError, match="`masks` values must be 0/1"):
        pack_bitplanes(np.full((2, 2, 2), 2))
    with pytest.raises(SettingError, match="`K` must be between 1 and 24 for 1 frames; got 25"):
        unpack_bitplanes(np.zeros((1, 2, 2, 3), np.uint8), 25)
