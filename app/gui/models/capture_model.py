"""What the Capture workspace holds and decides, without Qt.

:class:`CaptureModel` holds four parts, each with its own :class:`~flexvox_app.capture.events.Signal`:

- the **plan** (:class:`~flexvox_app.capture.plan.CapturePlan`, as chosen in the code panel):
  :attr:`CaptureModel.plan_changed`;
- the **calibration** recordings, the live view and the projector window use
  (:class:`~flexvox_calibration.capture_setup.CaptureCalibration`, None: uncalibrated):
  :attr:`CaptureModel.calibration_changed`;
- **who holds the devices**, one :class:`~flexvox_app.gui.models.holder.Holder` (defined in
  :mod:`flexvox_app.gui.models.holder`, shared with Calibrate and the device panel, and importable from here):
  nobody, Capture's live view, a recording, or a calibration (the Calibrate workspace, told by
  ``held_elsewhere``): :attr:`CaptureModel.holder_changed`;
- **the refusals**, one state machine for what may start (:class:`Action`) given who holds the rig, each
  :class:`Refusal` with its words, shown until it no longer holds (:meth:`CaptureModel.recheck`):
  :attr:`CaptureModel.refusal_changed`.

The panels of :mod:`flexvox_app.gui.capture` are views over it: they read it, call it, and follow its
signals. Signals are emitted on the caller's thread (the GUI thread) and do not contain their callbacks'
errors.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass

from flexvox_app.capture.events import Signal
from flexvox_app.capture.plan import CapturePlan
from flexvox_app.gui.models.holder import Holder
from flexvox_calibration.capture_setup import CaptureCalibration

_logger = logging.getLogger(__name__)


class Action(enum.Enum):
    """What the operator may ask Capture to start."""

    LIVE = "live view"
    RECORD = "recording"
    CALIBRATION = "calibration change"


class Cause(enum.Enum):
    """Why a refusal holds, and so when it goes."""

    HELD = "held"
    """The rig is held: the refusal goes once it is free."""
    SETTINGS = "settings"
    """The plan, the calibration or a recording setting: the refusal goes once they change."""
    DEVICE = "device"
    """A device's own error (or a setting it refused): the refusal goes once a device changes state (reconnected,
    reopened, taken or released) or the settings change."""


@dataclass(frozen=True)
class Refusal:
    """Why ``action`` did not start, in the operator's words."""

    action: Action
    text: str
    cause: Cause


class RigHeld(RuntimeError):
    """A change the model refuses while the rig is held (the message says by whom and why)."""


class CaptureModel:
    """The plan, the calibration, who holds the devices, and the refusals (see the module docstring).

    Parameters
    ----------
    plan : CapturePlan, optional
        The plan to start with (default ``CapturePlan()``; the code panel sets its own at once).
    held_elsewhere : callable, optional
        ``() -> str | None``: why another workspace holds the rig now (a calibration), None when it does not.
        While it names a reason and Capture holds nothing, :attr:`holder` is :attr:`Holder.CALIBRATING`.
    """

    def __init__(self, plan: CapturePlan | None = None, *,
                 held_elsewhere: Callable[[], str | None] | None = None):
        plan = CapturePlan() if plan is None else plan
        if not isinstance(plan, CapturePlan):
            raise TypeError(f"`plan` must be a CapturePlan; got {type(plan).__name__}")
        self._plan = plan
        self._calibration: CaptureCalibration | None = None
        self.delay_set_by_hand = False
        """The operator confirmed the trigger delay is set on a camera that cannot be told it."""
        self._held_elsewhere = held_elsewhere
        self._own = Holder.IDLE
        self._holder = Holder.IDLE  # as last told (refresh asks held_elsewhere)
        self._shown: dict[Action, Refusal] = {}
        self.plan_changed = Signal("plan_changed", contain=False)
        """``(plan)``: the plan changed."""
        self.calibration_changed = Signal("calibration_changed", contain=False)
        """``(calibration)``: the calibration now used (None: uncalibrated)."""
        self.holder_changed = Signal("holder_changed", contain=False)
        """``(holder)``: who holds the devices changed."""
        self.refusal_changed = Signal("refusal_changed", contain=False)
        """``(action, refusal)``: the refusal shown for ``action`` changed (None: none is shown now)."""

    # ------------------------------------------------------------------ the plan
    @property
    def plan(self) -> CapturePlan:
        """The plan the live view, a recording and the projector window use."""
        return self._plan

    def set_plan(self, plan: CapturePlan) -> None:
        """Use ``plan``; :attr:`plan_changed` says so (also when equal: the code panel's controls moved)."""
        if not isinstance(plan, CapturePlan):
            raise TypeError(f"`plan` must be a CapturePlan; got {type(plan).__name__}")
        self._plan = plan
        self.plan_changed.emit(plan)

    # ------------------------------------------------------------------ the calibration
    @property
    def calibration(self) -> CaptureCalibration | None:
        """The calibration chosen (None: uncalibrated)."""
        return self._calibration

    @property
    def capture_calibration(self) -> CaptureCalibration:
        """What recordings, the live view and the projector window use (uncalibrated when none was chosen)."""
        return self._calibration or CaptureCalibration()

    def set_calibration(self, calibration: CaptureCalibration | None) -> None:
        """Use ``calibration`` (None: uncalibrated); :attr:`calibration_changed` says so.

        Raises
        ------
        RigHeld
            While a recording runs (the refusal's words: :meth:`refusal` of :attr:`Action.CALIBRATION`).
        TypeError
            For anything but a CaptureCalibration or None.
        """
        if calibration is not None and not isinstance(calibration, CaptureCalibration):
            raise TypeError(f"`calibration` must be a CaptureCalibration or None; got {type(calibration).__name__}")
        refusal = self.refusal(Action.CALIBRATION)
        if refusal is not None:
            raise RigHeld(refusal.text)
        self._calibration = calibration
        _logger.info("Capture uses %s", "no calibration" if calibration is None else calibration.source)
        self.calibration_changed.emit(calibration)

    # ------------------------------------------------------------------ who holds the devices
    @property
    def holder(self) -> Holder:
        """Who holds the devices now: Capture's own use first, else :attr:`Holder.CALIBRATING` while
        ``held_elsewhere`` names a reason."""
        if self._own is not Holder.IDLE:
            return self._own
        return Holder.CALIBRATING if self.held_elsewhere() else Holder.IDLE

    @property
    def live(self) -> bool:
        """True while Capture's live view holds the devices."""
        return self._own is Holder.LIVE

    @property
    def recording(self) -> bool:
        """True from Record until the capture has ended."""
        return self._own is Holder.RECORDING

    def held_elsewhere(self) -> str | None:
        """Why another workspace holds the rig now (None: it does not)."""
        return self._held_elsewhere() if self._held_elsewhere is not None else None

    def take(self, holder: Holder) -> None:
        """Capture's live view (:attr:`Holder.LIVE`) or a recording (:attr:`Holder.RECORDING`) takes the devices.

        A recording takes them from the live view (which the workspace stops first); the live view only from
        nobody.

        Raises
        ------
        RigHeld
            When :meth:`refusal` refuses it (the message is the refusal's words).
        ValueError
            For :attr:`Holder.IDLE` or :attr:`Holder.CALIBRATING` (the Calibrate workspace holds the devices
            through ``held_elsewhere``).
        """
        action = {Holder.LIVE: Action.LIVE, Holder.RECORDING: Action.RECORD}.get(holder)
        if action is None:
            raise ValueError(f"`holder` must be Holder.LIVE or Holder.RECORDING (Capture's own uses); got {holder!r}")
        if self._own is holder:
            return
        refusal = self.refusal(action, timing=False)
        if refusal is not None:
            raise RigHeld(refusal.text)
        self._own = holder
        self.clear(action)
        self._holder_may_have_changed()

    def release(self, holder: Holder) -> None:
        """``holder`` (:attr:`Holder.LIVE` or :attr:`Holder.RECORDING`) is done with the devices; nothing happens
        when it did not hold them."""
        if holder not in (Holder.LIVE, Holder.RECORDING):
            raise ValueError(f"`holder` must be Holder.LIVE or Holder.RECORDING (Capture's own uses); got {holder!r}")
        if self._own is holder:
            self._own = Holder.IDLE
            self._holder_may_have_changed()

    def refresh(self) -> None:
        """Ask ``held_elsewhere`` again (a device changed state): :attr:`holder_changed` when the holder changed,
        and refusals that said the rig was held go once it is free; a device's own error goes too (it spoke of the
        state before)."""
        self._holder_may_have_changed(devices_changed=True)

    def _holder_may_have_changed(self, *, devices_changed: bool = False) -> None:
        holder = self.holder
        if holder is not self._holder:
            _logger.info("the rig's devices: %s → %s", self._holder.value, holder.value)
            self._holder = holder
            self.holder_changed.emit(holder)
        self.recheck(devices_changed=devices_changed)

    # ------------------------------------------------------------------ the refusals
    def refusal(self, action: Action, *, timing: bool = True) -> Refusal | None:
        """Why ``action`` may not start now (None: it may), in the words shown for it.

        - :attr:`Action.LIVE`: not while a recording runs, nor while another workspace holds the rig.
        - :attr:`Action.RECORD`: not with a plan whose timing the projector refuses (``timing``), nor while a
          recording runs or another workspace holds the rig (the live view is stopped for it).
        - :attr:`Action.CALIBRATION`: not while a recording runs (it changes after it).
        """
        if action is Action.CALIBRATION:
            if self.recording:
                return Refusal(action, "a recording is running: the calibration changes after it", Cause.HELD)
            return None
        if action is Action.RECORD:
            if timing and not self._plan.timing().ok:
                return Refusal(action, "cannot record: " + "; ".join(self._plan.timing().errors), Cause.SETTINGS)
            held = "a recording is running" if self.recording else self.held_elsewhere()
            return None if held is None else Refusal(action, f"cannot record: {held}", Cause.HELD)
        if action is Action.LIVE:
            held = "a recording is running" if self.recording else self.held_elsewhere()
            return None if held is None else Refusal(action, f"cannot start: {held}", Cause.HELD)
        raise ValueError(f"`action` must be an Action; got {action!r}")

    def check(self, action: Action) -> bool:
        """True when ``action`` may start now; otherwise its :meth:`refusal` is shown (:attr:`refusal_changed`)."""
        refusal = self.refusal(action)
        if refusal is not None:
            self._show(refusal)
        return refusal is None

    def refuse(self, action: Action, text: str, cause: Cause = Cause.SETTINGS) -> Refusal:
        """Show why ``action`` did not start for a reason only its view knows (no path, a question declined, the
        devices' own error); returns the refusal."""
        refusal = Refusal(action, str(text), cause)
        self._show(refusal)
        return refusal

    def shown(self, action: Action) -> Refusal | None:
        """The refusal shown for ``action`` (None: none)."""
        return self._shown.get(action)

    def clear(self, action: Action) -> None:
        """Stop showing ``action``'s refusal (it started, or its view says something newer)."""
        if self._shown.pop(action, None) is not None:
            self.refusal_changed.emit(action, None)

    def recheck(self, *, settings_changed: bool = False, devices_changed: bool = False,
                actions: tuple[Action, ...] = tuple(Action)) -> None:
        """Take refusals off that no longer hold: one that said the rig was held once it is free; any other once
        (``settings_changed``) the plan, the calibration or the setting it was about changed; a device's own error
        (:attr:`Cause.DEVICE`) also once a device changed state (``devices_changed``). An action that now runs
        keeps its refusal until it clears it."""
        running = {Action.LIVE: self.live, Action.RECORD: self.recording}
        for action in actions:
            shown = self._shown.get(action)
            if shown is None or running.get(action, False):
                continue
            if shown.cause is Cause.HELD:
                gone = self.refusal(action, timing=False) is None
            elif shown.cause is Cause.DEVICE:
                gone = settings_changed or devices_changed
            else:
                gone = settings_changed
            if gone:
                self.clear(action)

    def _show(self, refusal: Refusal) -> None:
        self._shown[refusal.action] = refusal
        _logger.info("%s refused: %s", refusal.action.value, refusal.text)
        self.refusal_changed.emit(refusal.action, refusal)
