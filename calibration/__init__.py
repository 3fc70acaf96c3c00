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
"""
