"""The calibration a recording uses (Qt-free model of the Capture workspace's "Calibration" box).

A calibration reaches Capture two ways: a file written by ``flexvox calibrate`` or the
Calibrate workspace (:func:`load_for_capture`, through :func:`calibration.files.load_calibration`,
which refuses a file made for another rig, camera or resolution), or the Calibrate workspace's
fresh result (:func:`from_outcome`, checked against the same identity). Either way the result
is an :class:`ActiveCalibration`; :meth:`ActiveCalibration.capture_calibration` turns it into
the :class:`app.capture.service.CaptureCalibration` (homography and sync phase) recordings and
the projector patterns use.

The identity Capture checks against is the *capture* rig's (:func:`capture_identity`). On the
simulated rig (``--rig mock``) calibration runs on a separate calibration target with its own
projector, so its result is refused there, in words: it describes another rig.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.gui.models.live_source import projector_size
from app.gui.models.rig_service import RigService

_logger = logging.getLogger(__name__)


class CalibrationRefused(Exception):  # noqa: N818 - a verdict in words, shown to the operator
    """A calibration cannot be used for this rig's capture; the message says why."""


def capture_identity(service: RigService):
    """The :class:`calibration.session.RigIdentity` of the capture rig (what a calibration must match)."""
    from calibration.session import RigSession

    rig = service.rig
    return RigSession.from_rig(rig, projector_size=projector_size(rig.projector)).identity


@dataclass(frozen=True)
class ActiveCalibration:
    """A calibration chosen for capture.

    Attributes
    ----------
    homography : ndarray (3, 3)
        Projector pixel (x, y) → camera pixel (x, y).
    phase_slots : int or None
        Sync phase (exposure slot t sees pattern (t + phase) mod K), None when the calibration has no sync.
    sync_K, sync_period_us : int or None
        The code length and pattern period the phase was measured at.
    rms_px : float or None
        Homography RMS reprojection error.
    created : str
        ISO date of the calibration.
    path : Path or None
        The file it came from (None: the Calibrate workspace's unsaved result).
    """

    homography: np.ndarray
    phase_slots: int | None
    sync_K: int | None
    sync_period_us: int | None
    rms_px: float | None
    created: str
    path: Path | None = None
    notes: tuple[str, ...] = field(default=())

    @property
    def origin(self) -> str:
        """Where it came from, in words."""
        return str(self.path) if self.path is not None else "the Calibrate workspace (not saved)"

    def phase_for(self, K: int, period_us: int) -> tuple[int, str]:
        """The phase to use with a code of ``K`` slots at ``period_us``, and a warning ("" when none).

        The phase is a count of slots measured at one K and period; at another timing it is only a
        guess (reduced mod K), and the warning says to measure it again.
        """
        if self.phase_slots is None:
            return 0, "this calibration has no sync measurement: phase 0 (run the synchronisation wizard)"
        if self.sync_K == K and self.sync_period_us == period_us:
            return int(self.phase_slots) % K, ""
        return int(self.phase_slots) % K, (
            f"the sync phase was measured at K = {self.sync_K}, {self.sync_period_us} µs patterns; this plan is "
            f"K = {K}, {period_us} µs: phase {int(self.phase_slots) % K} is a guess, run the synchronisation "
            "wizard at this timing")

    def capture_calibration(self, K: int, period_us: int):
        """The :class:`~app.capture.service.CaptureCalibration` for a plan of ``K`` slots at ``period_us``."""
        from app.capture.service import CaptureCalibration

        phase, _ = self.phase_for(K, period_us)
        return CaptureCalibration(homography=self.homography, phase_slots=phase,
                                  source=f"{self.origin} ({self.created})")

    def describe(self) -> str:
        """One line: file, date, RMS, phase."""
        rms = "—" if self.rms_px is None else f"{self.rms_px:.3f} px"
        phase = "no sync" if self.phase_slots is None else f"phase {self.phase_slots} (K = {self.sync_K})"
        return f"{self.origin} · {self.created} · RMS {rms} · {phase}"


def _sync_fields(sync: dict | None) -> tuple[int | None, int | None, int | None]:
    if not sync or sync.get("phase_slots") is None or sync.get("status") not in (None, "ok"):
        return None, None, None
    return int(sync["phase_slots"]), sync.get("K"), sync.get("period_us")


def load_for_capture(path, identity) -> ActiveCalibration:
    """Read a calibration file for capture on the rig of ``identity``.

    Raises
    ------
    CalibrationRefused
        For a missing or damaged file, or one made for another rig, camera or resolution
        (the message is :func:`calibration.files.load_calibration`'s).
    """
    from calibration.errors import CalibrationError
    from calibration.files import load_calibration

    path = Path(path).expanduser()
    try:
        data = load_calibration(path, identity)
    except CalibrationError as exc:
        raise CalibrationRefused(str(exc)) from exc
    phase, K, period = _sync_fields(data.get("sync"))
    rms = (data.get("quality") or {}).get("rms_px")
    _logger.info("calibration for capture: %s", path)
    return ActiveCalibration(data["H"], phase, K, period, None if rms is None else float(rms),
                             str(data.get("created", "undated")), path)


def from_outcome(outcome, identity, *, path=None, now=None) -> ActiveCalibration:
    """The Calibrate workspace's result (a :class:`~app.gui.models.calibration_model.CalibrationOutcome`) for capture.

    Raises
    ------
    CalibrationRefused
        When the run did not succeed, or was made on another rig than ``identity``'s.
    """
    import datetime as dt

    from calibration.errors import CalibrationMismatchError
    from calibration.files import check_identity

    if outcome is None or not outcome.success:
        raise CalibrationRefused("run a successful calibration first")
    where = "the Calibrate workspace's result"
    try:
        check_identity({"rig": outcome.identity.as_dict()}, identity, where)
    except CalibrationMismatchError as exc:
        if outcome.identity.name == identity.name and "simulated" in identity.name:
            raise CalibrationRefused(
                f"{exc} — on the simulated rig, calibration runs on its own calibration target (another "
                f"simulated projector, {'x'.join(map(str, outcome.identity.projector_size))}), so its result "
                "cannot drive this rig's capture") from exc
        raise CalibrationRefused(str(exc)) from exc
    sync = outcome.sync
    phase, K, period = _sync_fields(None if sync is None else sync.summary())
    hom = outcome.homography
    when = (now or dt.datetime.now(dt.UTC)).isoformat(timespec="seconds")
    return ActiveCalibration(np.asarray(hom.homography, np.float64), phase, K, period, float(hom.rms_px), when,
                             None if path is None else Path(path))
