"""Live capture (Qt-free, shared by ``flexvox capture`` and the Capture workspace).

:mod:`flexvox_app.capture.plan` holds what a capture records with (the code, the rate, the projector's
patterns through calibration's one pattern function); :mod:`flexvox_app.capture.rig_setup` sets the rig
up for a plan (patterns, sync box, camera trigger and delay) for a recording and for the live
view alike. A recording is three parts: :mod:`flexvox_app.capture.engine` (the rig set up, its camera read,
the rig put back), :mod:`flexvox_app.capture.sink` (the recording: gaps as dropped rows, checksums, the
end) and :mod:`flexvox_app.capture.service`, the runner between them (threads, queue policy, failures),
which publishes its progress as :mod:`flexvox_app.capture.events`. :mod:`flexvox_app.capture.settings` holds the
timing and queue settings, :mod:`flexvox_app.capture.status` the state, counters and result;
:mod:`flexvox_app.capture.pacing` paces the simulated rig's clock to the wall clock.
"""

from flexvox_app.capture.events import CaptureEvents, Signal
from flexvox_app.capture.plan import CapturePlan, TimingCheck, pattern_period_us
from flexvox_app.capture.rig_setup import CaptureError
from flexvox_app.capture.service import CaptureService, LatestFrame
from flexvox_app.capture.settings import QueuePolicy, SyncSetting
from flexvox_app.capture.sink import default_storage
from flexvox_app.capture.status import CaptureResult, CaptureState, CaptureStats

__all__ = [
    "CaptureError", "CaptureEvents", "CapturePlan", "CaptureResult", "CaptureService", "CaptureState",
    "CaptureStats", "LatestFrame", "QueuePolicy", "Signal", "SyncSetting", "TimingCheck", "default_storage",
    "pattern_period_us",
]
