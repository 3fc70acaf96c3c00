"""calibration — co-location aid, projector–camera homography, shutter masks and
synchronisation. Qt-free, usable headless; the Qt wizards call it.

Modules
-------
session            RigSession: show patterns, accept only frames exposed after the change
structured_light   Gray code (OpenCV) and binary phase-shift patterns, and their decoding
homography         capture + RANSAC fit + judgement (HomographyResult)
geometry           apply/compare homographies; mirrored, nearly singular, folded
colocation         live alignment numbers and the parallax test
shutter            shutter masks through the homography; verification on the rig
sync               phase and sub-slot delay (single-shot band code + delay sweep), drops, drift
files              versioned JSON calibration files tied to a rig's identity and resolution
capture_setup      what capture needs from a calibration: homography, phase, trigger delay, refusals
pipeline           every step in order (run_calibration), shared by the CLI, the GUI and the demo
for_rig            calibrate_rig / load_rig_calibration: a rig in, what capture takes out (one call)

From Python (docs/python.md): ``from calibration import calibrate_rig, load_rig_calibration``; each
name below is imported when first used.
"""

import importlib

__all__ = ["CalibrationError", "CalibrationRefused", "CalibrationWarning", "CaptureCalibration", "calibrate_rig",
           "load_rig_calibration"]

_WHERE = {
    "CalibrationError": "flexvox_calibration.errors",
    "CalibrationRefused": "flexvox_calibration.capture_setup",
    "CalibrationWarning": "flexvox_calibration.errors",
    "CaptureCalibration": "flexvox_calibration.capture_setup",
    "calibrate_rig": "flexvox_calibration.for_rig",
    "load_rig_calibration": "flexvox_calibration.for_rig",
}


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
