"""How messages reach the DLPC350: the :class:`Transport` protocol (whole 64-byte HID reports),
a pyusb implementation that turns every field problem into a typed error with a fix in its
message, and the one place where a message becomes reports and a reply is read back
(:func:`send_message`, :func:`receive_reply`), as TI's API does it for every command: a message
longer than one report continues over several, and so does a long reply
(:mod:`rig_drivers.dlpc350.protocol`).
"""

from __future__ import annotations

import errno
import logging
from typing import Protocol, runtime_checkable

from rig_drivers.dlpc350.protocol import FLAG_ERROR, MessageAssembler, message_reports
from rig_drivers.errors import (
    DLPC350_BUSY_HINT,
    DLPC350_PERMISSION_HINT,
    DeviceBusyError,
    DeviceError,
    DeviceNotFoundError,
    DevicePermissionError,
    DeviceTimeoutError,
)

_logger = logging.getLogger(__name__)

VENDOR_ID = 0x0451
PRODUCT_ID = 0x6401
ENDPOINT_OUT = 0x01
ENDPOINT_IN = 0x81
INTERFACE = 0

NO_BACKEND_HINT = (
    "pyusb found no USB backend: install libusb-1.0 (Debian/Ubuntu: `sudo apt install "
    "libusb-1.0-0`; macOS: `brew install libusb`; Windows: install the device's libusb driver "
    "with Zadig)."
)
NOT_FOUND_HINT = (
    "no DLP LightCrafter 4500 (USB 0451:6401) found: check that it is powered (the fan runs), "
    "that the mini-USB cable is plugged in, and that `lsusb` lists 0451:6401."
)


@runtime_checkable
class Transport(Protocol):
    """Moves whole 64-byte reports. Both methods raise :mod:`rig_drivers.errors` types."""

    def open(self) -> None:
        """Connect (may raise DeviceNotFoundError, DevicePermissionError, DeviceBusyError)."""

    def close(self) -> None:
        """Disconnect; safe to call twice."""

    def write(self, report: bytes) -> None:
        """Send one 64-byte report."""

    def read(self, timeout_s: float) -> bytes:
        """Return one 64-byte report; raise DeviceTimeoutError after ``timeout_s``."""


def send_message(transport: Transport, command: int, payload: bytes = b"", *, read: bool = False,
                 seq: int = 0) -> int:
    """Write one message as its reports (TI API ``DLPC350_SendMsg``); return how many reports went out."""
    reports = message_reports(command, payload, read=read, seq=seq)
    for report in reports:
        transport.write(report)
    return len(reports)


def receive_reply(transport: Transport, timeout_s: float) -> bytes:
    """Read one reply, joining continuation reports when it is longer than one (TI API
    ``DLPC350_GetPatLut``); the result reads like a single report for
    :func:`~rig_drivers.dlpc350.protocol.parse_reply`."""
    first = transport.read(timeout_s)
    if len(first) >= 1 and first[0] & FLAG_ERROR:
        return first  # a NAK is answered in one report, whatever its length field says (TI API DLPC350_Write)
    assembler = MessageAssembler()
    message = assembler.feed(first)
    while message is None:
        message = assembler.feed(transport.read(timeout_s))
    return message


def map_usb_error(exc: Exception, action: str) -> DeviceError:
    """Translate a pyusb error into the typed error with an actionable message."""
    code = getattr(exc, "errno", None)
    backend = getattr(exc, "backend_error_code", None)
    if type(exc).__name__ == "USBTimeoutError" or code in (errno.ETIMEDOUT,) or backend == -7:
        return DeviceTimeoutError(
            f"the DLP LightCrafter 4500 did not answer while trying to {action}: it may be "
            f"busy with a long operation or wedged; power-cycle it if this repeats")
    if code in (errno.EACCES, errno.EPERM) or backend == -3:
        return DevicePermissionError(DLPC350_PERMISSION_HINT)
    if code == errno.EBUSY or backend == -6:
        return DeviceBusyError(DLPC350_BUSY_HINT)
    if code in (errno.ENODEV, errno.ENOENT) or backend in (-4, -5):
        return DeviceNotFoundError(f"the DLP LightCrafter 4500 disappeared while trying to {action} "
                                   f"(unplugged or powered off?)")
    return DeviceError(f"USB error while trying to {action}: {exc}")


class PyUsbHidTransport:
    """The LightCrafter's HID interface through pyusb (interrupt endpoints 0x01/0x81).

    Parameters
    ----------
    serial_number : str, optional
        Pick one projector when several are connected.
    find : callable, optional
        ``usb.core.find`` replacement (tests inject one; default: pyusb's).
    usb_util : module-like, optional
        Provides ``claim_interface``, ``release_interface`` and ``dispose_resources``
        (default: ``usb.util``; tests inject one).
    """

    def __init__(self, *, serial_number: str | None = None, find=None, usb_util=None):
        self._serial = serial_number
        self._find = find
        self._util = usb_util
        self._dev = None
        self._reattach = False

    def _find_device(self):
        find = self._find
        if find is None:
            import usb.core

            find = usb.core.find
        kwargs = {"idVendor": VENDOR_ID, "idProduct": PRODUCT_ID}
        if self._serial is not None:
            kwargs["serial_number"] = self._serial
        try:
            return find(**kwargs)
        except Exception as exc:  # NoBackendError is the common case; others keep their cause
            if type(exc).__name__ == "NoBackendError":
                raise DeviceNotFoundError(NO_BACKEND_HINT) from exc
            raise map_usb_error(exc, "look for the projector") from exc

    def _usb_util(self):
        if self._util is None:
            import usb.util

            self._util = usb.util
        return self._util

    def open(self) -> None:
        """Find the projector, detach the kernel HID driver, claim the interface."""
        dev = self._find_device()
        if dev is None:
            raise DeviceNotFoundError(NOT_FOUND_HINT)
        try:
            try:
                active = dev.is_kernel_driver_active(INTERFACE)
            except NotImplementedError:  # Windows / macOS backends: nothing to detach
                active = False
            if active:
                dev.detach_kernel_driver(INTERFACE)
                self._reattach = True
            dev.set_configuration()
            self._usb_util().claim_interface(dev, INTERFACE)
        except Exception as exc:
            if isinstance(exc, DeviceError):
                raise
            raise map_usb_error(exc, "open the projector") from exc
        self._dev = dev
        _logger.info("DLPC350 opened over USB")

    def close(self) -> None:
        """Release the interface and give the kernel driver back."""
        dev, self._dev = self._dev, None
        if dev is None:
            return
        try:
            util = self._usb_util()
            util.release_interface(dev, INTERFACE)
            util.dispose_resources(dev)
            if self._reattach:
                dev.attach_kernel_driver(INTERFACE)
        except Exception as exc:
            # Closing must not hide the error that made us close; log it in full.
            _logger.warning("while releasing the DLPC350: %s", map_usb_error(exc, "release the projector"))

    def write(self, report: bytes) -> None:
        """Write one report to endpoint 0x01."""
        if self._dev is None:
            raise DeviceError("the USB transport is closed: open() it first")
        try:
            self._dev.write(ENDPOINT_OUT, bytes(report), 1000)
        except Exception as exc:
            raise map_usb_error(exc, "send a command") from exc

    def read(self, timeout_s: float) -> bytes:
        """Read one report from endpoint 0x81."""
        if self._dev is None:
            raise DeviceError("the USB transport is closed: open() it first")
        try:
            return bytes(self._dev.read(ENDPOINT_IN, 64, max(1, int(timeout_s * 1000))))
        except Exception as exc:
            raise map_usb_error(exc, "read a reply") from exc


def list_dlpc350(find=None) -> list[dict]:
    """Describe every connected LightCrafter 4500 (bus, address, serial when readable).

    Raises
    ------
    DeviceNotFoundError
        When pyusb has no backend (the message says what to install).
    """
    if find is None:
        import usb.core

        find = usb.core.find
    try:
        devices = list(find(find_all=True, idVendor=VENDOR_ID, idProduct=PRODUCT_ID) or [])
    except Exception as exc:
        if type(exc).__name__ == "NoBackendError":
            raise DeviceNotFoundError(NO_BACKEND_HINT) from exc
        raise map_usb_error(exc, "list USB devices") from exc
    out = []
    for dev in devices:
        out.append({"bus": getattr(dev, "bus", None), "address": getattr(dev, "address", None),
                    "vid_pid": f"{VENDOR_ID:04x}:{PRODUCT_ID:04x}"})
    return out
