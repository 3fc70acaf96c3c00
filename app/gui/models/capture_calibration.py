"""The capture rig's identity, which every calibration offered to Capture must match (Qt-free).

Calibration files, sync profiles and fresh calibration runs become a
:class:`calibration.capture_setup.CaptureCalibration` through that module's one loader
(:func:`~calibration.capture_setup.load_for_capture`, :func:`~calibration.capture_setup.load_sync_for_capture`,
:func:`~calibration.capture_setup.from_run`),
the same calls ``flexvox capture`` makes. What the Capture workspace adds is only *which rig*:
the identity of the rig the :class:`~app.gui.models.rig_service.RigService` drives.
"""

from __future__ import annotations

from app.gui.models.live_source import projector_size
from app.gui.models.rig_service import RigService


def capture_identity(service: RigService):
    """The :class:`calibration.session.RigIdentity` of the capture rig (what a calibration must match)."""
    from calibration.session import RigSession

    rig = service.rig
    return RigSession.from_rig(rig, projector_size=projector_size(rig.projector)).identity
