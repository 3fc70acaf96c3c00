"""The Capture workspace and its panels: code and timing, calibration, live view, recording, projector output."""
