"""Helpers shared by the DLPC350 tests: a request report as hex, and a K = 16 pattern sequence."""

from rig_drivers.interfaces import PatternSequence, ProjectorTrigger


def hexrow(report: bytes) -> str:
    """The meaningful bytes of a request report (header + command + payload) as hex."""
    length = report[2] | report[3] << 8
    return report[:4 + length].hex(" ")


def k16_sequence(rng) -> PatternSequence:
    """K = 16 one-bit patterns for a 15 Hz camera (240 Hz slots): period 1/(15 Hz * 16) = 4166 µs.

    The video port runs at 60 Hz, so each VSYNC carries 4 patterns (4 x 4166 = 16664 µs <= 16667 µs).
    """
    masks = rng.random((16, 8, 12)) < 0.5
    seq = PatternSequence.for_camera_rate(masks, 15.0, trigger=ProjectorTrigger.VSYNC, patterns_per_trigger=4)
    assert (seq.exposure_us, seq.period_us) == (4166, 4166)
    return seq
