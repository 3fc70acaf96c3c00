"""The capture rig's identity, which every calibration offered to Capture must match (Qt-free).

Calibration files, sync profiles and fresh calibration runs become a
:class:`flexvox_calibration.capture_setup.CaptureCalibration` through that module's one loader
(:func:`~flexvox_calibration.capture_setup.load_for_capture`,
:func:`~flexvox_calibration.capture_setup.load_sync_for_capture`,
:func:`~flexvox_calibration.capture_setup.from_run`),
the same calls ``flexvox capture`` makes. What the Capture workspace adds is only *which rig*:
the identity of the rig the :class:`~flexvox_app.gui.models.rig_service.RigService` drives.
"""

from __future__ import annotations

from flexvox_app.gui.models.live_source import projector_size
from flexvox_app.gui.models.rig_service import RigService


def capture_identity(service: RigService):
    """The :class:`flexvox_calibration.session.RigIdentity` of the capture rig (what a calibration must match)."""
    from flexvox_calibration.session import RigSession

    rig = service.rig
    return RigSession.from_rig(rig, projector_size=projector_size(rig.projector)).identity
