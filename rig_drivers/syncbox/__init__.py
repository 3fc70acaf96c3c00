"""The flexvox sync box: a microcontroller on a serial port that triggers the projector and
the camera from one clock. Protocol: ``PROTOCOL.md`` in this folder; firmware:
``rig_drivers/firmware/syncbox/syncbox.ino``."""

from rig_drivers.syncbox.driver import SyncBox
from rig_drivers.syncbox.fake import FakeSyncBoxSerial

__all__ = ["FakeSyncBoxSerial", "SyncBox"]
