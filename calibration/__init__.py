"""calibration — co-location aid, projector–camera homography, shutter masks and
synchronisation. Qt-free. Filled in by the *Calibration* issue."""
