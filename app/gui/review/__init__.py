"""The Review workspace: playback, reconstruction with any method, the continuum slider, motion and compare views."""
