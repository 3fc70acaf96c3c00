"""Exceptions of the calibration package.

Outcomes (a scene too dark to decode, a rig that is not co-located, dropped frames) are
*results* with a ``status`` and a ``message``; these exceptions are for misuse and for
calibration files that do not belong to the rig at hand.

::

    CalibrationError              misuse: bad arguments, a step run out of order
    ├── CalibrationFileError      a calibration/sync file that cannot be read or is malformed
    └── CalibrationMismatchError  a file made for another rig or resolution

    CalibrationWarning            (a UserWarning) a calibration used at another timing than it was measured at:
                                  its phase is a guess
"""

from __future__ import annotations


class CalibrationError(ValueError):
    """A calibration step was misused; the message names the argument and the rule."""


class CalibrationFileError(CalibrationError):
    """A calibration or sync-profile file cannot be read, or is not one."""


class CalibrationMismatchError(CalibrationError):
    """A calibration file was made for another rig, camera resolution or projector resolution."""


class CalibrationWarning(UserWarning):
    """A calibration is used where it holds only approximately (a capture at another timing than its sync was
    measured at: the phase is a guess); the message says what to measure again."""
