"""The pyusb transport: every field problem becomes a typed error that says what to do."""

import errno

import pytest
import usb.core

from rig_drivers.dlpc350.transport import PyUsbHidTransport, list_dlpc350, map_usb_error
from rig_drivers.errors import (
    DeviceBusyError,
    DeviceError,
    DeviceNotFoundError,
    DevicePermissionError,
    DeviceTimeoutError,
)


class FakeUsbDevice:
    """Just enough of a pyusb device; ``fail`` maps a method name to the exception it raises."""

    def __init__(self, fail=None, kernel_driver=True):
        self.fail = fail or {}
        self.kernel_driver = kernel_driver
        self.calls = []
        self.written = []

    def _call(self, name):
        self.calls.append(name)
        if name in self.fail:
            raise self.fail[name]

    def is_kernel_driver_active(self, interface):
        self._call("is_kernel_driver_active")
        return self.kernel_driver

    def detach_kernel_driver(self, interface):
        self._call("detach_kernel_driver")

    def attach_kernel_driver(self, interface):
        self._call("attach_kernel_driver")

    def set_configuration(self):
        self._call("set_configuration")

    def write(self, endpoint, data, timeout):
        self._call("write")
        self.written.append((endpoint, bytes(data)))

    def read(self, endpoint, size, timeout):
        self._call("read")
        return bytes(size)


class FakeUtil:
    """Stands in for ``usb.util``: records claim/release on the device."""

    @staticmethod
    def claim_interface(dev, interface):
        dev._call("claim_interface")

    @staticmethod
    def release_interface(dev, interface):
        dev._call("release_interface")

    @staticmethod
    def dispose_resources(dev):
        dev._call("dispose_resources")


def usb_error(code, cls=usb.core.USBError):
    return cls(f"[Errno {code}] {errno.errorcode.get(code, '')}", errno=code)


def test_no_backend_says_install_libusb():
    def find(**kwargs):
        raise usb.core.NoBackendError("No backend available")

    with pytest.raises(DeviceNotFoundError, match=r"no USB backend: install libusb-1.0 \(Debian/Ubuntu"):
        PyUsbHidTransport(find=find).open()


def test_not_connected():
    with pytest.raises(DeviceNotFoundError, match=r"no DLP LightCrafter 4500 \(USB 0451:6401\) found: "
                                                 r"check that it is powered"):
        PyUsbHidTransport(find=lambda **kw: None).open()


def test_permission_denied_gives_the_udev_rule():
    dev = FakeUsbDevice(fail={"detach_kernel_driver": usb_error(errno.EACCES)})
    with pytest.raises(DevicePermissionError) as info:
        PyUsbHidTransport(find=lambda **kw: dev, usb_util=FakeUtil).open()
    assert 'SUBSYSTEM=="usb", ATTR{idVendor}=="0451", ATTR{idProduct}=="6401", MODE="0666"' in str(info.value)
    assert "Zadig" in str(info.value)


def test_busy_says_close_ti_gui_and_detach_kernel_driver():
    dev = FakeUsbDevice(fail={"set_configuration": usb_error(errno.EBUSY)})
    with pytest.raises(DeviceBusyError, match=r"close TI's LightCrafter 4500 GUI .* kernel HID driver is detached"):
        PyUsbHidTransport(find=lambda **kw: dev, usb_util=FakeUtil).open()


def test_open_detaches_kernel_driver_and_close_gives_it_back():
    dev = FakeUsbDevice()
    transport = PyUsbHidTransport(find=lambda **kw: dev, usb_util=FakeUtil)
    transport.open()
    transport.write(bytes(64))
    assert transport.read(0.01) == bytes(64)
    transport.close()
    assert dev.calls[:4] == ["is_kernel_driver_active", "detach_kernel_driver", "set_configuration",
                             "claim_interface"]
    assert dev.calls[-1] == "attach_kernel_driver" and dev.written == [(0x01, bytes(64))]


def test_timeout_maps_to_device_timeout():
    dev = FakeUsbDevice(fail={"read": usb.core.USBTimeoutError("Operation timed out", errno=errno.ETIMEDOUT)})
    transport = PyUsbHidTransport(find=lambda **kw: dev, usb_util=FakeUtil)
    transport.open()
    with pytest.raises(DeviceTimeoutError, match="did not answer while trying to read a reply"):
        transport.read(0.01)


def test_unplugged_and_other_errors():
    assert isinstance(map_usb_error(usb_error(errno.ENODEV), "x"), DeviceNotFoundError)
    other = map_usb_error(usb_error(errno.EIO), "send a command")
    assert type(other) is DeviceError and "USB error while trying to send a command" in str(other)


def test_closed_transport_refuses_io():
    with pytest.raises(DeviceError, match=r"the USB transport is closed: open\(\) it first"):
        PyUsbHidTransport(find=lambda **kw: None).write(bytes(64))


def test_list_dlpc350():
    class Dev:
        bus, address = 1, 7

    assert list_dlpc350(lambda **kw: [Dev()]) == [{"bus": 1, "address": 7, "vid_pid": "0451:6401"}]
