"""Live capture (Qt-free, shared by ``flexvox capture`` and the Capture workspace).

:mod:`app.capture.plan` holds what a capture records with (the code, the rate, the projector's
patterns through calibration's one pattern function); :mod:`app.capture.rig_setup` sets the rig
up for a plan (patterns, sync box, camera trigger and delay) for a recording and for the live
view alike; :mod:`app.capture.service` streams frames crash-safely to a recording (threads, queue
policy, failures); :mod:`app.capture.pacing` paces the simulated rig's clock to the wall clock.
"""

from app.capture.plan import CapturePlan, TimingCheck, pattern_period_us
from app.capture.service import (
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
    "CaptureError", "CapturePlan", "CaptureResult", "CaptureService", "CaptureState", "CaptureStats",
    "LatestFrame", "QueuePolicy", "SyncSetting", "TimingCheck", "default_storage", "pattern_period_us",
]
