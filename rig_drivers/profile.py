"""Rig profiles: which devices a command drives (``--rig mock`` or ``--rig FILE.toml``).

``mock`` (the default) is the coupled simulated rig
(:class:`~rig_drivers.simulated_rig.SimulatedRig`). A profile file names the real devices:

.. code-block:: toml

    name = "lab rig"                  # optional, shown in messages

    [projector]
    kind = "dlpc350"                  # TI DLP LightCrafter 4500 over USB HID
    serial = "A1B2C3"                 # optional: the USB serial number, when several are connected

    [camera]
    kind = "genicam"                  # a GenICam camera through harvesters (pip install -e '.[genicam]')
    cti = "/opt/vendor/lib/producer.cti"   # the vendor's GenTL producer
    serial = "22334455"               # optional: pick the camera by serial ...
    model = "acA640-750um"            # ... and/or model
    line = "Line0"                    # optional: the trigger input line (default Line0)
    activation = "RisingEdge"         # optional (default RisingEdge)

    # or: a webcam for preview and alignment only (it cannot shutter)
    # [camera]
    # kind = "uvc"
    # index = 0

    [sync]
    kind = "syncbox"                  # the flexvox sync box on a serial port
    port = "/dev/ttyACM0"             # COM3 on Windows

    # or: the projector's TRIG_OUT_2 wired to the camera's trigger line
    # [sync]
    # kind = "projector-trigger"

Kinds: projector ``dlpc350``; camera ``genicam``, ``uvc``; sync ``syncbox``,
``projector-trigger``. Paths in the profile are relative to the profile file. Unknown keys
and kinds are errors that list what is valid; missing keys are named.

:func:`open_rig` builds the devices *without opening them* (no I/O happens until a device's
``open()``): the serial port of a sync box is opened by the sync box's ``open()``.
"""

from __future__ import annotations

import logging
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from rig_drivers.errors import SettingError
from rig_drivers.interfaces import Camera, Projector, SyncController, TriggerActivation, TriggerSource
from rig_drivers.pixel_layout import LAYOUTS

if TYPE_CHECKING:  # the simulated rig is imported only when `mock` is opened
    from rig_drivers.simulated_rig import RigTruth, SimulatedRig

_logger = logging.getLogger(__name__)

MOCK = "mock"
"""The ``--rig`` value of the simulated rig (the default)."""

PROJECTOR_KINDS = {"dlpc350": ({"kind"}, {"serial", "led_current", "led_enable", "pixel_layout"})}
LED_COLOURS = ("red", "green", "blue")
CAMERA_KINDS = {
    "genicam": ({"kind", "cti"}, {"serial", "model", "line", "activation"}),
    "uvc": ({"kind"}, {"index"}),
}
SYNC_KINDS = {"syncbox": ({"kind", "port"}, set()), "projector-trigger": ({"kind"}, set())}
_SECTIONS = {"projector": PROJECTOR_KINDS, "camera": CAMERA_KINDS, "sync": SYNC_KINDS}
_TOP = {"name", *_SECTIONS}


@dataclass(frozen=True)
class DeviceSpec:
    """One device of a profile: its kind and its (validated) settings."""

    kind: str
    options: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RigSpec:
    """A parsed rig profile (``mock`` when :attr:`simulated`)."""

    name: str
    projector: DeviceSpec | None = None
    camera: DeviceSpec | None = None
    sync: DeviceSpec | None = None
    source: Path | None = None

    @property
    def simulated(self) -> bool:
        """True for ``--rig mock``."""
        return self.projector is None

    @property
    def trigger_line(self) -> TriggerSource:
        """The camera line the frame trigger arrives on."""
        if self.camera is not None and "line" in self.camera.options:
            return TriggerSource(self.camera.options["line"])
        return TriggerSource.LINE0


MOCK_SPEC = RigSpec(name="simulated rig (mock)")


def _where(source) -> str:
    return str(source) if source is not None else "rig profile"


def _section(data: dict, section: str, where: str) -> DeviceSpec:
    kinds = _SECTIONS[section]
    table = data.get(section)
    if table is None:
        raise SettingError(f"{where}: missing [{section}] table (with kind = one of {', '.join(kinds)})")
    if not isinstance(table, dict):
        raise SettingError(f"{where}: `{section}` must be a table; got {table!r}")
    kind = table.get("kind")
    if kind is None:
        raise SettingError(f"{where} [{section}]: missing key `kind` (one of {', '.join(kinds)})")
    if kind not in kinds:
        raise SettingError(f"{where} [{section}]: unknown kind {kind!r}; valid kinds: {', '.join(kinds)}")
    required, optional = kinds[kind]
    missing = sorted(required - set(table))
    if missing:
        raise SettingError(f"{where} [{section}] kind {kind!r}: missing key(s) {', '.join(missing)}")
    unknown = sorted(set(table) - required - optional)
    if unknown:
        allowed = ", ".join(sorted(required | optional))
        raise SettingError(f"{where} [{section}] kind {kind!r}: unknown key {unknown[0]!r}; allowed: {allowed}")
    options = {k: v for k, v in table.items() if k != "kind"}
    for key in ("serial", "model", "cti", "port"):
        if key in options and (not isinstance(options[key], str) or not options[key]):
            raise SettingError(f"{where} [{section}] {key} must be a non-empty string; got {options[key]!r}")
    if "index" in options and (isinstance(options["index"], bool) or not isinstance(options["index"], int)
                               or not 0 <= options["index"] <= 255):
        raise SettingError(f"{where} [{section}] index must be a whole number 0..255; got {options['index']!r}")
    lines = [s.value for s in TriggerSource if s.value.startswith("Line")]
    if "line" in options and options["line"] not in lines:
        raise SettingError(f"{where} [{section}] line must be one of {', '.join(lines)}; got {options['line']!r}")
    if "led_current" in options:
        options["led_current"] = _led_current(options["led_current"], f"{where} [{section}]")
    if "pixel_layout" in options and options["pixel_layout"] not in LAYOUTS:
        raise SettingError(f"{where} [{section}] pixel_layout must be one of {', '.join(LAYOUTS)} (\"diamond\": the "
                           f"LightCrafter 4500's staggered rows); got {options['pixel_layout']!r}")
    if "led_enable" in options:
        options["led_enable"] = _led_enable(options["led_enable"], f"{where} [{section}]")
    activations = [a.value for a in TriggerActivation]
    if "activation" in options and options["activation"] not in activations:
        raise SettingError(f"{where} [{section}] activation must be one of {', '.join(activations)}; "
                           f"got {options['activation']!r}")
    return DeviceSpec(kind, options)


def _led_current(value, where: str) -> tuple[int, int, int]:
    """``led_current``: one PWM value 0..255 for all three LEDs, or [red, green, blue]."""
    values = [value] * 3 if not isinstance(value, list) else value
    if len(values) != 3 or any(isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 255 for v in values):
        raise SettingError(f"{where} led_current must be a whole number 0..255 (the LED PWM value, 255 = the most "
                           f"current) or [red, green, blue] of them; got {value!r}")
    return tuple(values)


def _led_enable(value, where: str) -> str | tuple[str, ...]:
    """``led_enable``: "sequence" (the pattern sequence drives the LEDs) or a list of colours kept on."""
    if value == "sequence":
        return value
    if isinstance(value, list) and value and all(v in LED_COLOURS for v in value) and len(set(value)) == len(value):
        return tuple(value)
    raise SettingError(f"{where} led_enable must be \"sequence\" (the pattern sequence drives the LEDs) or a list "
                       f"of {', '.join(LED_COLOURS)} to keep on; got {value!r}")


def parse_profile(data: dict, *, source: Path | None = None) -> RigSpec:
    """Validate a parsed profile mapping (see the module docstring) into a :class:`RigSpec`."""
    where = _where(source)
    if not isinstance(data, dict):
        raise SettingError(f"{where}: a rig profile must be a TOML table")
    unknown = sorted(set(data) - _TOP)
    if unknown:
        raise SettingError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(_TOP))}")
    projector = _section(data, "projector", where)
    camera = _section(data, "camera", where)
    sync = _section(data, "sync", where)
    if camera.kind == "genicam" and source is not None and not Path(camera.options["cti"]).is_absolute():
        camera = DeviceSpec(camera.kind, dict(camera.options, cti=str(source.parent / camera.options["cti"])))
    if camera.kind == "uvc":
        _logger.warning("%s: a UVC camera cannot shutter in sync with the projector: preview and alignment only",
                        where)
    name = data.get("name", source.stem if source is not None else "rig")
    if not isinstance(name, str):
        raise SettingError(f"{where}: `name` must be a string; got {name!r}")
    return RigSpec(name=name, projector=projector, camera=camera, sync=sync, source=source)


def load_profile(path) -> RigSpec:
    """Read and validate a rig profile TOML file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SettingError(f"no rig profile {path}: a rig is \"mock\" (the simulated rig) or the path of a .toml "
                          "rig profile") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SettingError(f"cannot read the rig profile {path}: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise SettingError(f"{path} is not valid TOML: {exc}") from exc
    return parse_profile(data, source=path)


def resolve_rig(value=MOCK) -> RigSpec:
    """The rig a ``--rig`` value names: ``mock`` (or None), a profile path, or a RigSpec."""
    if isinstance(value, RigSpec):
        return value
    if value is None or value == MOCK:
        return MOCK_SPEC
    if isinstance(value, str | Path):
        return load_profile(value)
    raise SettingError(f"`rig` must be 'mock', a profile path or a RigSpec; got {type(value).__name__}")


@dataclass
class ProfileRig:
    """The devices a ``--rig`` value names (a profile's, or ``mock``'s simulated ones), built but not opened.

    A :class:`~rig_drivers.interfaces.Rig`.

    Attributes
    ----------
    projector, camera : Projector, Camera
    sync : SyncController or None
        None when the projector's TRIG_OUT_2 triggers the camera directly.
    spec : RigSpec
    simulated : SimulatedRig or None
        The simulated rig behind ``mock`` (its clock, its view and, for tests, its truth).
    """

    projector: Projector
    camera: Camera
    sync: SyncController | None
    spec: RigSpec
    simulated: SimulatedRig | None = None

    def __repr__(self) -> str:
        lines = [f"projector: {self.projector!r}", f"camera: {self.camera!r}",
                 f"sync: {self.sync!r}" if self.sync is not None else "sync: the projector triggers the camera"]
        return f"<ProfileRig {self.name!r}\n" + "\n".join(f"  {line}" for line in lines) + ">"

    @property
    def name(self) -> str:
        """The profile's name (``mock``'s carries its seed)."""
        return self.spec.name

    @property
    def trigger_line(self) -> TriggerSource:
        """The camera line the frame trigger arrives on."""
        return self.spec.trigger_line

    @property
    def projector_size(self) -> tuple[int, int] | None:
        """The projector's pattern size (rows, columns), as its driver reports it."""
        return self.projector.size

    @property
    def pixel_layout(self) -> str:
        """How the projector's pixels sit, as its driver (the profile's ``pixel_layout``) says."""
        return self.projector.pixel_layout

    @property
    def video_port(self) -> bool:
        """True when the projector takes its patterns on its video input (a DLPC350)."""
        return self.projector.video_port

    @property
    def truth(self) -> RigTruth | None:
        """What the simulated rig behind ``mock`` hides; None for real devices."""
        return None if self.simulated is None else self.simulated.truth

    def close(self) -> None:
        """Close every device (each is closed even when another fails)."""
        try:
            self.camera.close()
        finally:
            try:
                self.projector.close()
            finally:
                if self.sync is not None:
                    self.sync.close()


class DeferredSerialPort:
    """A pyserial port opened on first use, so that building a rig does no I/O.

    It offers what :class:`~rig_drivers.syncbox.SyncBox` needs (``write``, ``readline``,
    ``reset_input_buffer``, ``close``, ``timeout``); the first of them opens the port, with
    the sync box's typed errors (not found, permission, busy).
    """

    def __init__(self, port_name: str, *, timeout_s: float = 0.5, serial_factory=None):
        self.port_name = port_name
        self.timeout = timeout_s
        self._factory = serial_factory
        self._port = None

    def _ensure(self):
        if self._port is None:
            from rig_drivers.syncbox.driver import BAUD_RATE, map_serial_error

            factory = self._factory
            if factory is None:
                import serial

                factory = serial.Serial
            try:
                self._port = factory(self.port_name, BAUD_RATE, timeout=self.timeout, exclusive=True)
            except OSError as exc:  # serial.SerialException is an OSError
                raise map_serial_error(exc, self.port_name) from exc
        return self._port

    def write(self, data: bytes):
        """Write to the port (opening it first)."""
        return self._ensure().write(data)

    def readline(self) -> bytes:
        """Read a line (opening the port first)."""
        return self._ensure().readline()

    def reset_input_buffer(self) -> None:
        """Drop pending input (opening the port first)."""
        self._ensure().reset_input_buffer()

    def close(self) -> None:
        """Close the port when it was opened."""
        port, self._port = self._port, None
        if port is not None:
            port.close()


def open_rig(rig=MOCK, *, projector_display=None, **simulated_options) -> ProfileRig:
    """Build the devices of a rig without opening them.

    Parameters
    ----------
    rig : "mock", str or Path, or RigSpec
        ``mock`` (default) for the simulated rig, else a profile path or a parsed profile. The
        simulated rig is named for its seed (``simulated rig (mock, seed 0)``): rigs of other
        seeds hide other homographies and timings, and their calibrations do not carry over.
    projector_display : callable, optional
        Real rigs: the projector's display sink, ``display(frames)`` with the packed
        ``(N, H, W, 3)`` uint8 frames of every sequence loaded (see
        :mod:`rig_drivers.dlpc350.driver`; the app's is :mod:`flexvox_app.gui.projector.display`).
        Ignored by ``mock``, whose simulated projector needs no video input.
    **simulated_options
        For ``mock``: the fields of its :class:`~rig_drivers.simulated_rig_spec.SimulatedRigSpec` (``scene``,
        ``camera_size``, ``seed``, ``clock``, ...). The one most often wanted is ``clock``:

        - default (None): real time (:class:`~rig_drivers.simulated_camera.MonotonicClock`). The simulated
          camera delivers a frame every frame period, as a real one does: 100 frames at 15 Hz take 6.7 s.
        - ``clock=VirtualClock()`` (:class:`~rig_drivers.simulated_camera.VirtualClock`): simulated time that
          jumps ahead whenever a device waits, so a capture or a calibration runs as fast as the computer
          renders it. Tests, notebooks and the examples use it; the command line's ``--clock virtual``.

    Returns
    -------
    ProfileRig
        The projector, camera and sync box (None where the projector triggers the camera), not opened;
        ``simulated`` holds the :class:`~rig_drivers.simulated_rig.SimulatedRig` behind ``mock``.

    Raises
    ------
    SettingError
        For a bad profile, naming the file, table and key; for options given to a real rig.

    Examples
    --------
    >>> from rig_drivers import VirtualClock, open_rig
    >>> rig = open_rig("mock", clock=VirtualClock(), camera_size=(24, 32), subframes=32)
    >>> rig.camera.name, rig.simulated.clock
    ('simulated camera', <VirtualClock at 0 µs>)
    """
    spec = resolve_rig(rig)
    if spec.simulated:
        from rig_drivers.simulated_rig import SimulatedRig
        from rig_drivers.simulated_rig_spec import SimulatedRigSpec

        sim = SimulatedRig.build(SimulatedRigSpec(**simulated_options))
        # Its seed makes it another rig: a calibration made on seed 0 is refused on seed 1.
        named = RigSpec(name=f"{spec.name[:-1]}, seed {sim.truth.seed})")
        return ProfileRig(sim.projector, sim.camera, sim.sync, named, simulated=sim)
    if simulated_options:
        raise SettingError(f"options {', '.join(sorted(simulated_options))} apply to the simulated rig only")
    return ProfileRig(_projector(spec.projector, projector_display), _camera(spec.camera), _sync(spec.sync), spec)


def _projector(d: DeviceSpec, display=None) -> Projector:
    from rig_drivers.dlpc350 import DLPC350, PyUsbHidTransport

    return DLPC350(PyUsbHidTransport(serial_number=d.options.get("serial")), display=display,
                   led_currents=d.options.get("led_current"), led_enable=d.options.get("led_enable"),
                   pixel_layout=d.options.get("pixel_layout", "square"))


def _camera(d: DeviceSpec) -> Camera:
    if d.kind == "genicam":
        from rig_drivers.genicam import GenICamCamera

        return GenICamCamera(d.options["cti"], serial=d.options.get("serial"), model=d.options.get("model"))
    from rig_drivers.uvc import UvcCamera

    return UvcCamera(d.options.get("index", 0))


def _sync(d: DeviceSpec) -> SyncController | None:
    if d.kind == "projector-trigger":
        return None
    from rig_drivers.syncbox import SyncBox

    return SyncBox(DeferredSerialPort(d.options["port"]), name=f"sync box on {d.options['port']}")
