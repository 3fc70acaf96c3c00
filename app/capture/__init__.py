"""Live capture: the rig set up for a code, frames streamed crash-safely to a recording.

Qt-free; see :mod:`app.capture.service` for the threads, the queue policy and failures, and
:mod:`app.capture.patterns` for how a code becomes projector patterns.
"""

from app.capture.patterns import shutter_patterns
from app.capture.service import (
    CaptureCalibration,
    CaptureError,
    CaptureResult,
    CaptureService,
    CaptureState,
    CaptureStats,
    LatestFrame,
    QueuePolicy,
    SyncSetting,
    default_storage,
)

__all__ = [
    "CaptureCalibration", "CaptureError", "CaptureResult", "CaptureService", "CaptureState", "CaptureStats",
    "LatestFrame", "QueuePolicy", "SyncSetting", "default_storage", "shutter_patterns",
]
