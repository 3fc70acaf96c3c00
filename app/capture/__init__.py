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

import importlib

# Each name from its module when first used, so that importing one Qt-free part (the live preview on the GPU machine,
# whose image has no zarr) does not import the recording's writer through the service.
_HOME = {
    "CaptureEvents": "events", "Signal": "events",
    "CapturePlan": "plan", "TimingCheck": "plan", "pattern_period_us": "plan",
    "CaptureError": "rig_setup",
    "CaptureService": "service", "LatestFrame": "service",
    "QueuePolicy": "settings", "SyncSetting": "settings",
    "default_storage": "sink",
    "CaptureResult": "status", "CaptureState": "status", "CaptureStats": "status",
}


def __getattr__(name: str):
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    globals()[name] = value
    return value


__all__ = [
    "CaptureError", "CaptureEvents", "CapturePlan", "CaptureResult", "CaptureService", "CaptureState",
    "CaptureStats", "LatestFrame", "QueuePolicy", "Signal", "SyncSetting", "TimingCheck", "default_storage",
    "pattern_period_us",
]
