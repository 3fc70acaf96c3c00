"""One exception hierarchy for every device in the rig.

Every message says what went wrong *and what to do about it*: an operator at the rig reads
these, not a developer. Drivers translate their transport's own errors (``usb.core.USBError``,
``serial.SerialException``, ...) into these classes with ``raise ... from exc`` so the cause
is kept for the log.

::

    DeviceError
    ├── DeviceNotFoundError       nothing answers at that address / no USB backend
    ├── DevicePermissionError     the OS refuses access (udev rule, dialout group)
    ├── DeviceBusyError           another program or a kernel driver holds the device
    ├── DeviceTimeoutError        no (complete) answer within the timeout
    ├── ProtocolError             NAK, malformed reply, bad checksum, validation failure
    ├── IncompatibleStateError    the call is not allowed in the device's current state
    └── SettingError              a settings value breaks a rule (also a ValueError)
"""

from __future__ import annotations


class DeviceError(Exception):
    """Base class of every error a rig device raises."""


class DeviceNotFoundError(DeviceError):
    """The device is not connected, not powered, or cannot be reached at all."""


class DevicePermissionError(DeviceError):
    """The operating system refuses access to the device (fix with a udev rule or group)."""


class DeviceBusyError(DeviceError):
    """Another program, or a kernel driver, holds the device."""


class DeviceTimeoutError(DeviceError):
    """The device did not answer (completely) within the timeout."""


class ProtocolError(DeviceError):
    """The device answered, but with an error (NAK), a malformed reply or a bad checksum."""


class IncompatibleStateError(DeviceError):
    """The call is not allowed in the device's current state (e.g. configure while running)."""


class SettingError(DeviceError, ValueError):
    """A settings value breaks a rule; the message names the setting and the rule."""


# Texts shared by more than one driver -------------------------------------------------

DLPC350_UDEV_RULE = 'SUBSYSTEM=="usb", ATTR{idVendor}=="0451", ATTR{idProduct}=="6401", MODE="0666"'
"""The udev rule that lets a normal user open the LightCrafter 4500 on Linux."""

DLPC350_PERMISSION_HINT = (
    "permission denied opening the DLP LightCrafter 4500 (USB 0451:6401). On Linux add the "
    f"udev rule\n    {DLPC350_UDEV_RULE}\nto /etc/udev/rules.d/99-lightcrafter.rules, then run "
    "`sudo udevadm control --reload-rules && sudo udevadm trigger` and re-plug the USB cable. "
    "On Windows install the libusb driver for the device with Zadig (WinUSB or libusb-win32)."
)

DLPC350_BUSY_HINT = (
    "the DLP LightCrafter 4500 (USB 0451:6401) is busy: close TI's LightCrafter 4500 GUI "
    "(it keeps the device open), and on Linux make sure the kernel HID driver is detached "
    "(flexvox detaches it when it is allowed to; run as a user with the udev rule, or unbind "
    "usbhid for this device)."
)

SERIAL_PERMISSION_HINT = (
    "permission denied opening {port}: on Linux add yourself to the `dialout` group "
    "(`sudo usermod -aG dialout $USER`, then log out and in again)."
)

SERIAL_BUSY_HINT = (
    "{port} is busy: another program holds it (the Arduino IDE's serial monitor, a second "
    "flexvox, screen or minicom). Close it and try again."
)
