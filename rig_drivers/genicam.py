"""GenICam machine-vision cameras through ``harvesters`` (the optional extra ``flexvox[genicam]``).

A GenTL producer (``.cti`` file, from the camera vendor) gives access to the camera; the
`harvesters <https://github.com/genicam/harvesters>`_ package drives it. Both are
imported only when a camera is opened, so flexvox runs without them.

What :meth:`GenICamCamera.configure` writes (standard SFNC feature names; the
trigger wiring is in docs/real-rig.md):

=====================  ==================================================================
``TriggerSelector``    ``FrameStart``
``TriggerMode``        ``On`` for a line or software trigger, ``Off`` for free running
``TriggerSource``      ``Line0``..``Line3`` or ``Software``
``TriggerActivation``  ``RisingEdge`` / ``FallingEdge`` / ... (lines only)
``TriggerDelay``       µs, whenever the camera has it (0 undoes an earlier delay); a delay
                       asked of a camera without it is an error (capabilities say
                       ``trigger_delay``; capture then asks the operator to set it)
``ExposureAuto``       ``Off`` (when present), then ``ExposureTime`` in µs
``GainAuto``           ``Off`` (when present), then ``Gain`` in dB
``AcquisitionFrameRate``  free running only, when present: ``1e6 / exposure_us`` clamped to
                       the camera's range (so free-run frames come as fast as the exposure allows)
=====================  ==================================================================

A feature the camera lacks is skipped with a warning in the log and listed in
:attr:`GenICamCamera.unapplied` (the simulated producer ``viky.cti`` has neither trigger
nor exposure features), except that a trigger the camera cannot do is refused with
:class:`~rig_drivers.errors.SettingError`.

Per buffer: the frame id is the producer's ``BUFFER_INFO_FRAMEID``; the timestamp is the
buffer's device timestamp in ns when the producer gives one, else the host's monotonic
clock at delivery (:attr:`GenICamCamera.capabilities` then says ``device_timestamps=False``).
Incomplete buffers (harvesters discards them and emits ``INCOMPLETE_BUFFER``) and gaps in the
frame ids are counted in :attr:`GenICamCamera.dropped_frames`.
"""

from __future__ import annotations

import dataclasses
import importlib
import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rig_drivers.errors import (
    DeviceBusyError,
    DeviceError,
    DeviceNotFoundError,
    DevicePermissionError,
    DeviceTimeoutError,
    IncompatibleStateError,
    SettingError,
)
from rig_drivers.interfaces import (
    Camera,
    CameraCapabilities,
    CameraSettings,
    DeviceState,
    Frame,
    TriggerSource,
)

_logger = logging.getLogger(__name__)

INSTALL_HINT = ("install it from the flexvox checkout with `.venv/bin/pip install -e \".[genicam]\"` "
                "(the packages harvesters and genicam; `make test` installs them)")

MAX_FETCH_ATTEMPTS = 1000
"""Most fetch calls in one read_frame (each waits at most the time left)."""


def load_harvesters():
    """Import ``harvesters.core`` (it provides ``Harvester`` and ``Callback``).

    Raises
    ------
    DeviceNotFoundError
        When harvesters is not installed, saying how to install it.
    """
    try:
        return importlib.import_module("harvesters.core")
    except ImportError as exc:
        raise DeviceNotFoundError(f"GenICam cameras need the harvesters package, which is not installed: "
                                  f"{INSTALL_HINT}") from exc


def simulated_producer() -> Path | None:
    """The path of ``viky.cti``, the simulated GenTL producer the ``genicam`` wheel ships,
    or None when the wheel is not installed."""
    try:
        genicam = importlib.import_module("genicam")
    except ImportError:
        return None
    path = Path(genicam.__file__).parent / "viky.cti"
    return path if path.is_file() else None


def _map_open_error(exc: Exception, what: str) -> DeviceError:
    name = type(exc).__name__
    if name == "AccessDeniedException":
        return DeviceBusyError(f"{what}: access denied: another program (the vendor's viewer, a second "
                               f"flexvox) holds the camera, or you lack permission (on Linux check the "
                               f"vendor's udev rules); close it and try again ({exc})")
    if name in ("ResourceInUseException", "BusyException"):
        return DeviceBusyError(f"{what}: the camera is in use by another program; close it and try again ({exc})")
    if isinstance(exc, PermissionError):
        return DevicePermissionError(f"{what}: permission denied ({exc})")
    return DeviceNotFoundError(f"{what}: {exc}")


class _IncompleteCounter:
    """Counts harvesters' INCOMPLETE_BUFFER events (built on harvesters' Callback)."""

    @staticmethod
    def make(base: type, camera: GenICamCamera):
        class Counter(base):
            def emit(self, context=None) -> None:
                camera._on_incomplete()

        return Counter()


class GenICamCamera(Camera):
    """A GenICam camera through a GenTL producer and harvesters.

    Parameters
    ----------
    cti : str or Path
        The GenTL producer file.
    serial, model : str, optional
        Pick the camera by serial number and/or model (default: the first one found).
    harvesters_module : module-like, optional
        Provides ``Harvester`` and ``Callback`` (default: ``harvesters.core``, imported at
        :meth:`open`). Tests inject fakes.
    clock_s : callable, optional
        Host clock in seconds for timeouts and fallback timestamps (default ``time.monotonic``).
    """

    def __init__(self, cti, *, serial: str | None = None, model: str | None = None,
                 harvesters_module=None, clock_s: Callable[[], float] | None = None, name: str | None = None):
        super().__init__(name=name or f"GenICam camera{' ' + serial if serial else ''}")
        self.cti = Path(cti)
        self.serial = None if serial is None else str(serial)
        self.model = None if model is None else str(model)
        self._module = harvesters_module
        self._clock_s = clock_s or time.monotonic
        self._harvester = None
        self._ia = None
        self._nodes = None
        self._shape = (0, 0)
        self._caps = CameraCapabilities(hardware_trigger=False, frame_ids=True, device_timestamps=False)
        self._last_id: int | None = None
        self._host_ids = 0
        self._pending_incomplete = 0
        self.dropped_frames = 0
        """Frames lost since open: incomplete buffers plus gaps in the frame ids."""
        self.incomplete_buffers = 0
        """Incomplete buffers discarded since open."""
        self.unapplied: list[str] = []
        """Features the last configure() could not write (the camera lacks them)."""
        self.device_info: dict = {}

    # ------------------------------------------------------------------ properties
    @property
    def capabilities(self) -> CameraCapabilities:
        """Known after :meth:`open` (before: no trigger); ``device_timestamps`` after the first frame."""
        return self._caps

    @property
    def sensor_shape(self) -> tuple[int, int]:
        """``(Height, Width)`` read at open."""
        if self.state is DeviceState.CLOSED:
            raise IncompatibleStateError(f"cannot read the sensor shape: {self.name} is closed (call open() first)")
        return self._shape

    # ------------------------------------------------------------------ lifecycle
    def _do_open(self) -> None:
        module = self._module or load_harvesters()
        if not self.cti.is_file():
            raise DeviceNotFoundError(f"no GenTL producer at {self.cti}: install the camera vendor's SDK "
                                      f"(or `pip install genicam` for the simulated viky.cti) and give its .cti path")
        harvester = module.Harvester()
        try:
            harvester.add_file(str(self.cti))
            harvester.update()
            infos = list(harvester.device_info_list)
            index = self._pick(infos)
            try:
                ia = harvester.create(index)
            except Exception as exc:  # translated into a typed error with a fix
                raise _map_open_error(exc, f"cannot open {self._describe(infos[index])}") from exc
        except BaseException:
            harvester.reset()
            raise
        self._harvester, self._ia = harvester, ia
        self._nodes = ia.remote_device.node_map
        self.device_info = self._info_dict(infos[index])
        counter_base = getattr(module, "Callback", None)
        if counter_base is not None:
            ia.add_callback(ia.Events.INCOMPLETE_BUFFER, _IncompleteCounter.make(counter_base, self))
        self._prefer_mono()
        self._shape = (int(self._nodes.Height.value), int(self._nodes.Width.value))
        lines = self._symbolics("TriggerSource")
        self._caps = CameraCapabilities(
            hardware_trigger=any(s.startswith("Line") for s in lines), frame_ids=True, device_timestamps=False,
            trigger_delay=self._node("TriggerDelay") is not None)
        self.dropped_frames = self.incomplete_buffers = self._pending_incomplete = 0
        self._last_id = None
        _logger.info("opened %s (%dx%d, trigger lines: %s)", self._describe(infos[index]), self._shape[1],
                     self._shape[0], ", ".join(s for s in lines if s.startswith("Line")) or "none")

    def _do_close(self) -> None:
        ia, harvester = self._ia, self._harvester
        self._ia = self._harvester = self._nodes = None
        try:
            if ia is not None:
                ia.destroy()
        finally:
            if harvester is not None:
                harvester.reset()

    @staticmethod
    def _info_dict(info) -> dict:
        props = getattr(info, "property_dict", {}) or {}
        return {k: props.get(k) for k in ("vendor", "model", "serial_number", "id_") if props.get(k) is not None}

    def _describe(self, info) -> str:
        d = self._info_dict(info)
        return " ".join(str(d[k]) for k in ("vendor", "model") if k in d) + f" (serial {d.get('serial_number', '?')})"

    def _pick(self, infos) -> int:
        if not infos:
            raise DeviceNotFoundError(f"the GenTL producer {self.cti} finds no camera: is it plugged in and "
                                      f"powered (and, for GigE, on this machine's subnet)?")
        for i, info in enumerate(infos):
            d = self._info_dict(info)
            if (self.serial is None or str(d.get("serial_number")) == self.serial) and \
                    (self.model is None or str(d.get("model")) == self.model):
                if self.serial is None and self.model is None and len(infos) > 1:
                    _logger.info("%d cameras found; using the first (give a serial to choose)", len(infos))
                return i
        found = "; ".join(self._describe(info) for info in infos)
        wanted = ", ".join(f"{k} {v}" for k, v in (("serial", self.serial), ("model", self.model)) if v)
        raise DeviceNotFoundError(f"no camera with {wanted} through {self.cti}; found: {found}")

    # ------------------------------------------------------------------ nodes
    def _node(self, name: str):
        nodes = self._nodes
        if hasattr(nodes, "has_node") and not nodes.has_node(name):
            return None
        return getattr(nodes, name, None)

    def _symbolics(self, name: str) -> tuple[str, ...]:
        node = self._node(name)
        return tuple(getattr(node, "symbolics", ())) if node is not None else ()

    def _write(self, name: str, value, *, required: bool = False) -> bool:
        node = self._node(name)
        if node is None:
            if required:
                raise SettingError(f"{self.name} has no {name} feature: it cannot do this setting")
            self.unapplied.append(name)
            _logger.warning("%s has no %s feature; left at the camera's setting", self.name, name)
            return False
        symbolics = getattr(node, "symbolics", None)
        if symbolics is not None and isinstance(value, str) and value not in symbolics:
            raise SettingError(f"{self.name}: {name} cannot be {value!r}; it can be {', '.join(symbolics)}")
        lo, hi = getattr(node, "min", None), getattr(node, "max", None)
        if not isinstance(value, str | bool) and lo is not None and hi is not None and not lo <= value <= hi:
            raise SettingError(f"{self.name}: {name} must be between {lo:g} and {hi:g}; got {value:g}")
        try:
            node.value = value
        except Exception as exc:  # genicam's AccessException, LogicalErrorException, ...
            raise SettingError(f"{self.name} refused {name} = {value!r}: {exc}") from exc
        return True

    def _prefer_mono(self) -> None:
        formats = self._symbolics("PixelFormat")
        node = self._node("PixelFormat")
        if node is None or str(node.value).startswith("Mono"):
            return
        mono = [f for f in formats if f.startswith("Mono")]
        if mono:
            self._write("PixelFormat", "Mono16" if "Mono16" in mono else mono[0])

    # ------------------------------------------------------------------ hooks
    def _do_configure(self, settings: CameraSettings) -> None:
        self.unapplied = []
        trig = settings.trigger
        if trig.source is not TriggerSource.FREE_RUN:
            if trig.source.value not in self._symbolics("TriggerSource"):
                raise SettingError(f"{self.name} has no trigger source {trig.source.value}; it has "
                                   f"{', '.join(self._symbolics('TriggerSource')) or 'no trigger features'}")
            if trig.source is TriggerSource.SOFTWARE and self._node("TriggerSoftware") is None:
                raise SettingError(f"{self.name} has no TriggerSoftware command")
        if self._node("TriggerSelector") is not None:
            self._write("TriggerSelector", trig.selector.value)
        if trig.source is TriggerSource.FREE_RUN:
            if self._node("TriggerMode") is not None:
                self._write("TriggerMode", "Off")
        else:
            self._write("TriggerMode", "On", required=True)
            self._write("TriggerSource", trig.source.value, required=True)
            if trig.is_hardware:
                self._write("TriggerActivation", trig.activation.value, required=True)
            if trig.delay_us or self._node("TriggerDelay") is not None:  # 0 too: undo an earlier delay
                self._write("TriggerDelay", float(trig.delay_us), required=bool(trig.delay_us))
        if self._node("ExposureAuto") is not None:
            self._write("ExposureAuto", "Off")
        self._write("ExposureTime", float(settings.exposure_us))
        if self._node("GainAuto") is not None:
            self._write("GainAuto", "Off")
        if settings.gain_db or self._node("Gain") is not None:
            self._write("Gain", float(settings.gain_db))
        rate = self._node("AcquisitionFrameRate")
        if trig.source is TriggerSource.FREE_RUN and rate is not None:
            if self._node("AcquisitionFrameRateEnable") is not None:
                self._write("AcquisitionFrameRateEnable", True)
            self._write("AcquisitionFrameRate", float(np.clip(1e6 / settings.exposure_us, rate.min, rate.max)))

    def _do_start_acquisition(self) -> None:
        self._last_id = None
        self._ia.start()

    def _do_stop_acquisition(self) -> None:
        self._ia.stop()

    def _do_trigger_software(self) -> None:
        self._node("TriggerSoftware").execute()

    def _on_incomplete(self) -> None:
        self.incomplete_buffers += 1
        self.dropped_frames += 1
        self._pending_incomplete += 1
        _logger.warning("%s: incomplete buffer discarded (%d so far)", self.name, self.incomplete_buffers)

    def _do_read_frame(self, timeout_s: float) -> Frame:
        deadline = self._clock_s() + timeout_s
        for _ in range(MAX_FETCH_ATTEMPTS):
            remaining = deadline - self._clock_s()
            if remaining <= 0:
                break
            buffer = self._ia.try_fetch(timeout=remaining)
            if buffer is None:  # timed out, or an incomplete buffer was discarded (counted)
                continue
            with buffer:
                return self._frame(buffer)
        raise DeviceTimeoutError(
            f"{self.name}: no complete frame within {timeout_s:g} s (trigger source "
            f"{self._settings.trigger.source.value}): check the trigger wiring and that the "
            f"projector or sync box is running; for GigE cameras check the link and packet size")

    def _frame(self, buffer) -> Frame:
        component = buffer.payload.components[0]
        h, w = int(component.height), int(component.width)
        data = np.asarray(component.data)
        channels = max(1, data.size // max(1, h * w))
        image = data.reshape(h, w, channels)
        image = image[:, :, 0].copy() if channels == 1 else image[:, :, :3].mean(axis=2, dtype=np.float32)
        try:
            frame_id = int(buffer.module.frame_id)
        except Exception:  # noqa: BLE001 - the producer has no frame id: count on the host
            self._caps = dataclasses.replace(self._caps, frame_ids=False)
            self._host_ids += 1
            frame_id = self._host_ids
        try:
            timestamp_s = int(buffer.timestamp_ns) / 1e9
            device_ts = True
        except Exception:  # noqa: BLE001 - no device timestamp: host clock (capabilities say so)
            timestamp_s = float(self._clock_s())
            device_ts = False
        if device_ts != self._caps.device_timestamps:
            _logger.info("%s: timestamps from the %s clock", self.name, "device" if device_ts else "host")
            self._caps = dataclasses.replace(self._caps, device_timestamps=device_ts)
        if self._last_id is not None and frame_id > self._last_id + 1:
            gap = frame_id - self._last_id - 1
            # Incomplete buffers already counted make part of the gap.
            self.dropped_frames += max(0, gap - self._pending_incomplete)
            _logger.warning("%s: %d frame(s) lost before frame %d", self.name, gap, frame_id)
        self._pending_incomplete = 0
        self._last_id = frame_id
        return Frame(image, frame_id=frame_id, timestamp_s=timestamp_s)
