"""Live capture (Qt-free, shared by ``flexvox capture`` and the Capture workspace).

:mod:`app.capture.plan` holds what a capture records with (the code, the rate, the projector's
patterns through calibration's one pattern function); :mod:`app.capture.rig_setup` sets the rig
up for a plan (patterns, sync box, camera trigger and delay) for a recording and for the live
view alike. A recording is three parts: :mod:`app.capture.engine` (the rig set up, its camera read,
the rig put back), :mod:`app.capture.sink` (the recording: gaps as dropped rows, checksums, the
end) and :mod:`app.capture.service`, the runner between them (threads, queue policy, failures),
which publishes its progress as :mod:`app.capture.events`. :mod:`app.capture.settings` holds the
timing and queue settings, :mod:`app.capture.status` the state, counters and result;
:mod:`app.capture.pacing` paces the simulated rig's clock to the wall clock.
"""

from app.capture.events import CaptureEvents, Signal
from app.capture.plan import CapturePlan, TimingCheck, pattern_period_us
from app.capture.rig_setup import CaptureError
from app.capture.service import CaptureService, LatestFrame
from app.capture.settings import QueuePolicy, SyncSetting
from app.capture.sink import default_storage
from app.capture.status import CaptureResult, CaptureState, CaptureStats

__all__ = [
    "CaptureError", "CaptureEvents", "CapturePlan", "CaptureResult", "CaptureService", "CaptureState",
    "CaptureStats", "LatestFrame", "QueuePolicy", "Signal", "SyncSetting", "TimingCheck", "default_storage",
    "pattern_period_us",
]
