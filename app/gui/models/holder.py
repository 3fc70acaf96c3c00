"""Who holds the rig's devices: one name (:class:`Holder`) for Capture, Calibrate, the device panel and dock.

The rig is shared by the workspaces; each asks the others before it uses the devices. The vocabulary, the same
everywhere in the GUI:

- ``holder``: a :class:`Holder`, who holds the devices now
  (:attr:`flexvox_app.gui.models.capture_model.CaptureModel.holder`,
  :attr:`flexvox_app.gui.calibrate.workspace.CalibrateWorkspace.holder`,
  :attr:`flexvox_app.gui.models.rig_service.RigService.holder`);
- ``held_by``: who holds them, in the operator's words ("the calibration"), None when nobody does
  (:attr:`~flexvox_app.gui.models.rig_service.RigService.held_by`);
- ``held_here()``: why this workspace holds the rig now, in words (the reason another workspace is refused),
  None when it does not (:meth:`flexvox_app.gui.calibrate.workspace.CalibrateWorkspace.held_here`; Capture's,
  a recording, is said by the main window);
- ``held_elsewhere``: the callable a workspace is given, ``() -> str | None``: why another workspace holds the
  rig now, None when it does not (the main window wires one workspace's hold to the other's
  ``held_elsewhere``).
"""

from __future__ import annotations

import enum

__all__ = ["Holder"]


class Holder(enum.Enum):
    """Who holds the rig's devices now."""

    IDLE = "idle"
    """Nobody: the live view, a recording or a calibration may start."""
    LIVE = "live"
    """Capture's live view reads the camera."""
    RECORDING = "recording"
    """A recording owns the devices, from Record until the capture has ended."""
    CALIBRATING = "calibrating"
    """The Calibrate workspace uses the devices (a calibration, its live numbers, the synchronisation wizard)."""
