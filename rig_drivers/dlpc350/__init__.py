"""TI DLP LightCrafter 4500 (DLPC350 controller) over USB HID.

- :mod:`~rig_drivers.dlpc350.protocol`: packets, command codes, field encodings, status words
- :mod:`~rig_drivers.dlpc350.bitplanes`: K masks <-> bit-planes of 24-bit RGB frames
- :mod:`~rig_drivers.dlpc350.transport`: the Transport protocol and the pyusb transport
- :mod:`~rig_drivers.dlpc350.driver`: :class:`DLPC350`, the Projector, and its display sink
  (``display(frames)``: who puts the packed frames on the video input; :class:`ProjectorDisplayError`)
- :mod:`~rig_drivers.dlpc350.fake`: :class:`FakeDLPC350Transport`, a controller in memory
"""

from rig_drivers.dlpc350.bitplanes import pack_bitplanes, unpack_bitplanes
from rig_drivers.dlpc350.driver import DLPC350, ProjectorDisplayError
from rig_drivers.dlpc350.fake import FakeDLPC350Transport
from rig_drivers.dlpc350.transport import PyUsbHidTransport, Transport

__all__ = ["DLPC350", "FakeDLPC350Transport", "ProjectorDisplayError", "PyUsbHidTransport", "Transport",
           "pack_bitplanes", "unpack_bitplanes"]
