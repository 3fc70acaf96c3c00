"""The rig's devices as the device panel sees them (Qt-free service).

Wraps a :class:`rig_drivers.interfaces.Rig`: each device's role, name, state, whether it is
simulated, the last error in words, and who holds the devices (a calibration, co-location live,
the synchronisation wizard: they open and close the devices themselves, so their state flickers
while they run; :meth:`RigService.begin_use` says who holds them (:attr:`RigService.holder`,
:attr:`RigService.held_by`), and :meth:`RigService.end_use` connects again what the operator had connected
before). :meth:`RigService.connect` opens and enables a device,
:meth:`RigService.disconnect` closes it; failures are caught *as results* (kept in
``last_error`` and logged at warning level), never swallowed. Views subscribe with
:meth:`RigService.subscribe` (a plain callback, napari-style events without Qt).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from flexvox_app.gui.models.holder import Holder
from flexvox_core.deprecations import warn_renamed
from rig_drivers.errors import DeviceError
from rig_drivers.interfaces import Device, DeviceState, LedControl, Rig

_logger = logging.getLogger(__name__)

ROLES = ("projector", "camera", "sync")


@dataclass(frozen=True)
class DeviceStatus:
    """What the panel shows for one device."""

    role: str
    name: str
    state: DeviceState | None
    simulated: bool
    last_error: str

    @property
    def present(self) -> bool:
        """False for a role the rig does not have (sync wired through the projector)."""
        return self.state is not None


class RigService:
    """The devices of a rig, their states and their last errors.

    Parameters
    ----------
    rig : rig_drivers.interfaces.Rig
    """

    def __init__(self, rig: Rig):
        self.rig = rig
        self._errors: dict[str, str] = dict.fromkeys(ROLES, "")
        self._listeners: list[Callable[[str], None]] = []
        self._users: dict[str, set[str]] = {}
        """Who uses the devices now, each with the roles that were connected when it began."""

    @property
    def simulated(self) -> bool:
        """True for the simulated rig (``--rig mock``)."""
        return self.rig.simulated is not None

    @property
    def name(self) -> str:
        """The rig's name (:attr:`rig_drivers.interfaces.Rig.name`: a profile's, or the simulated rig's)."""
        return self.rig.name

    def device(self, role: str) -> Device | None:
        """The device in ``role`` (None: the rig has none)."""
        if role == "projector":
            return self.rig.projector
        if role == "camera":
            return self.rig.camera
        if role == "sync":
            return self.rig.sync
        raise ValueError(f"`role` must be one of {', '.join(ROLES)}; got {role!r}")

    def status(self, role: str) -> DeviceStatus:
        """The device's current status."""
        dev = self.device(role)
        if dev is None:
            return DeviceStatus(role, "none (the projector's TRIG_OUT_2 triggers the camera)", None,
                                self.simulated, "")
        return DeviceStatus(role, dev.name, dev.state, self.simulated, self._errors[role])

    def statuses(self) -> list[DeviceStatus]:
        """Every role's status."""
        return [self.status(r) for r in ROLES]

    def subscribe(self, callback: Callable[[str], None]) -> None:
        """Call ``callback(role)`` whenever a device's state or last error changes."""
        self._listeners.append(callback)

    def unsubscribe(self, callback: Callable[[str], None]) -> None:
        """Stop calling ``callback``."""
        if callback in self._listeners:
            self._listeners.remove(callback)

    def notify(self, role: str) -> None:
        """Tell subscribers that the device in ``role`` changed (its run state, say)."""
        for cb in list(self._listeners):
            cb(role)

    def _attempt(self, role: str, action: str, fn) -> bool:
        try:
            fn()
        except (DeviceError, OSError, ValueError) as exc:
            self._errors[role] = f"{action} failed: {exc}"
            _logger.warning("%s %s: %s", role, action, exc)
            self.notify(role)
            return False
        self._errors[role] = ""
        self.notify(role)
        return True

    def connect(self, role: str) -> bool:
        """Open and enable the device; False (with ``last_error`` set) when it fails."""
        dev = self.device(role)
        if dev is None:
            return False

        def go():
            if dev.state is DeviceState.CLOSED:
                dev.open()
            dev.enable()

        return self._attempt(role, "connect", go)

    def disconnect(self, role: str) -> bool:
        """Close the device (it always ends closed); False when closing reported an error."""
        dev = self.device(role)
        if dev is None:
            return False
        return self._attempt(role, "disconnect", dev.close)

    def ensure_connected(self, *roles: str) -> bool:
        """Connect each of ``roles`` that is not enabled yet; True when all are enabled."""
        ok = True
        for role in roles:
            dev = self.device(role)
            if dev is not None and dev.state is not DeviceState.ENABLED:
                ok = self.connect(role) and ok
        return ok

    @property
    def led_control(self) -> LedControl | None:
        """The projector's LED currents (:attr:`rig_drivers.interfaces.Projector.led_control`), None where flexvox
        does not set them."""
        return self.rig.projector.led_control

    @property
    def has_led_control(self) -> bool:
        """True when the projector takes LED currents (a LightCrafter 4500)."""
        return self.led_control is not None

    def led_currents(self) -> tuple[int, int, int] | None:
        """The projector's LED PWM values (read back when connected, else the profile's), or None."""
        leds = self.led_control
        if leds is None:
            return None
        if self.rig.projector.state is not DeviceState.CLOSED:
            try:
                return leds.led_currents()
            except DeviceError as exc:
                self.record_error("projector", f"reading the LED currents failed: {exc}")
        return leds.configured_led_currents

    def set_led_currents(self, red: int, green: int, blue: int) -> bool:
        """Send LED PWM values 0..255 to a connected projector; False (with ``last_error``) when it fails."""
        leds = self.led_control
        if leds is None:
            return False
        if self.rig.projector.state is DeviceState.CLOSED:
            self.record_error("projector", "connect the projector first to set its LED currents")
            return False
        return self._attempt("projector", "setting the LED currents", lambda: leds.set_led_currents(red, green, blue))

    @property
    def held_by(self) -> str | None:
        """Who holds the devices now, in words ("the calibration"), None when nobody does."""
        return next(iter(self._users), None)

    @property
    def holder(self) -> Holder:
        """:attr:`~flexvox_app.gui.models.holder.Holder.CALIBRATING` while a user holds the devices (those of
        :meth:`begin_use` are the Calibrate workspace's: the calibration, its live numbers, the synchronisation
        wizard), else :attr:`~flexvox_app.gui.models.holder.Holder.IDLE`. Capture's live view and recordings
        are held in :class:`~flexvox_app.gui.models.capture_model.CaptureModel`, not here."""
        return Holder.CALIBRATING if self._users else Holder.IDLE

    @property
    def in_use_by(self) -> str | None:
        """Deprecated name of :attr:`held_by` (removed in the next release)."""
        warn_renamed("RigService.in_use_by", "RigService.held_by", stacklevel=3)
        return self.held_by

    def begin_use(self, user: str) -> None:
        """``user`` opens and closes the devices from now on (they are held: the panel says so)."""
        if user in self._users:
            return
        connected = {r for r in ROLES if (d := self.device(r)) is not None and d.state is DeviceState.ENABLED}
        if self._users:  # a user before this one remembers what the operator had connected
            connected = set()
        self._users[user] = connected
        _logger.info("devices held by %s", user)
        for role in ROLES:
            self.notify(role)

    def end_use(self, user: str) -> list[str]:
        """``user`` is done with the devices: connect again those the operator had connected before the first
        holder began (its own session closed them), once no one holds them; while another still does, that one
        connects them when it is done, whichever of the two began first. Returns the roles connected again."""
        if user not in self._users:
            return []
        connected = self._users.pop(user)
        again = []
        if self._users:  # another still holds the devices: it connects them again when it is done
            next(iter(self._users.values())).update(connected)
        else:
            for role in ROLES:
                dev = self.device(role)
                if role in connected and dev is not None and dev.state is not DeviceState.ENABLED:
                    if self.connect(role):
                        again.append(role)
        _logger.info("devices free (%s done); connected again: %s", user, ", ".join(again) or "none")
        for role in ROLES:
            self.notify(role)
        return again

    def record_error(self, role: str, message: str) -> None:
        """Keep an error another part of the app met with this device (e.g. during live view)."""
        self._errors[role] = message
        self.notify(role)

    def close(self) -> None:
        """Close every device."""
        for role in ROLES:
            dev = self.device(role)
            if dev is not None and dev.state is not DeviceState.CLOSED:
                self.disconnect(role)
