"""The Calibrate workspace, the live co-location view and the synchronisation wizard."""
