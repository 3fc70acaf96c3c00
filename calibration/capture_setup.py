"""What capture needs from calibration, from one place: homography, phase, trigger delay, refusals.

Both front ends (``flexvox capture --calibration/--sync-profile`` and the Capture workspace)
turn a calibration into a :class:`CaptureCalibration` here and nowhere else:

- :func:`load_for_capture` reads a calibration file (``flexvox calibrate -o``, the Calibrate
  workspace's "Save") and :func:`load_sync_for_capture` a sync profile (the synchronisation
  wizard's "Save profile"; its phase and delay replace a calibration's); each refuses, with
  :class:`CalibrationRefused` and a message that says why, a file that is missing, damaged,
  failed, of the other kind, or made for another rig, camera or resolution;
- :func:`from_run` takes a fresh calibration run (the Calibrate workspace's "Use for capture").

The phase and the delay go together
-----------------------------------
The sync measurement finds that exposure slot 0 opens ``p + f`` slots after the projector's
sequence starts (whole slots ``p``, fraction ``f``; see :mod:`flexvox_calibration.sync`). An exposure
that opens part-way into a slot mixes two patterns in every slot. So capture delays the camera's
trigger by ``(1 − f)·period`` (:attr:`SyncTiming.trigger_delay_us`): the exposure then opens on a
slot boundary, and exposure slot ``t`` sees pattern ``(t + p') mod K`` with ``p' = p + 1`` when
``f > 0`` (:attr:`SyncTiming.phase_slots`, the phase the shutter patterns are built with). The raw
``p`` belongs to a camera delay of 0 and is kept only for display: shutter patterns built with it
while the recommended delay is set are one slot off.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from flexvox_calibration import geometry
from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.files import CALIBRATION_FORMAT, check_identity, load_calibration
from flexvox_calibration.sync import SYNC_FORMAT, boundary_phase, load_sync_profile
from flexvox_core.json_file import read_json

_logger = logging.getLogger(__name__)


class CalibrationRefused(CalibrationError):  # noqa: N818 - a verdict in words, shown to the operator
    """A calibration cannot be used for this rig's capture; the message says why."""


@dataclass(frozen=True)
class SyncTiming:
    """When the exposure opens against the projector's sequence, as capture uses it.

    Attributes
    ----------
    phase_slots : int
        The phase the shutter patterns use: exposure slot ``t`` sees pattern ``(t + phase_slots)
        mod K`` once the camera's trigger is delayed by :attr:`trigger_delay_us`.
    trigger_delay_us : float
        Camera trigger delay that opens the exposure on a slot boundary (0 when it already does).
    K, period_us : int
        The code length and pattern period the timing was measured at.
    raw_phase_slots : int
        The phase at camera delay 0 (for display only).
    offset_us : float
        The sub-slot part of the exposure's opening at camera delay 0, µs.
    """

    phase_slots: int
    trigger_delay_us: float
    K: int
    period_us: int
    raw_phase_slots: int
    offset_us: float = 0.0

    def __post_init__(self):
        for name in ("K", "period_us"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise CalibrationRefused(f"`{name}` must be a whole number >= 1; got {v!r}")
        for name in ("phase_slots", "raw_phase_slots"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or not 0 <= v < self.K:
                raise CalibrationRefused(f"`{name}` must be a whole number 0..{self.K - 1}; got {v!r}")
        d = self.trigger_delay_us
        if isinstance(d, bool) or not isinstance(d, int | float) or not math.isfinite(d) or not 0 <= d < self.period_us:
            raise CalibrationRefused(f"`trigger_delay_us` must be at least 0 and below the period "
                                     f"{self.period_us} µs; got {d!r}")

    @classmethod
    def from_summary(cls, sync: dict | None) -> SyncTiming | None:
        """From a sync measurement's summary (:meth:`flexvox_calibration.sync.SyncResult.summary`); None when
        there is none, or it failed."""
        if sync is not None and not isinstance(sync, dict):
            raise CalibrationRefused(f"the sync measurement must be an object (the sync step's summary) or null; got "
                                     f"{sync!r}")
        if not sync or sync.get("status") not in (None, "ok") or sync.get("phase_slots") is None:
            return None
        # The values as written, never rounded into range: a phase of 2.5 is a damaged file, not phase 2.
        missing = [k for k in ("K", "period_us", "phase_slots", "recommended_camera_delay_us") if sync.get(k) is None]
        if missing:
            raise CalibrationRefused(f"the sync measurement is incomplete: no {', '.join(f'`{k}`' for k in missing)} "
                                     "(the phase and the camera trigger delay go together; measure it again)")
        K, period, raw = sync["K"], sync["period_us"], sync["phase_slots"]
        eff, delay = sync.get("effective_phase_slots"), sync["recommended_camera_delay_us"]
        offset = sync.get("delay_us")
        offset = 0.0 if not isinstance(offset, int | float) or isinstance(offset, bool) or not math.isfinite(offset) \
            else float(offset)  # for display only
        try:
            if eff is None:  # older files: derive it as the sync step does, from checked values
                cls(0, delay, K, period, raw, offset)
                eff = boundary_phase(raw, delay, K)
            return cls(eff, delay, K, period, raw, offset)
        except CalibrationRefused as exc:
            raise CalibrationRefused(f"the sync measurement is out of range: {exc}") from None

    def describe(self) -> str:
        """One line: the phase and the delay in use."""
        return (f"phase {self.phase_slots} with a {self.trigger_delay_us:.0f} µs camera trigger delay "
                f"(measured at K = {self.K}, {self.period_us} µs patterns)")


@dataclass(frozen=True, eq=False)
class CaptureCalibration:
    """What capture needs from calibration: where projector pixels land, the phase and the trigger delay.

    Parameters
    ----------
    homography : array (3, 3)
        Projector pixel (x, y) → camera pixel (x, y). Default identity (uncalibrated).
    sync : SyncTiming, optional
        The synchronisation; None: phase 0 and no delay (uncalibrated timing).
    source : str
        Where the values come from (shown, and stored in the recording).
    rms_px : float, optional
        The homography's RMS reprojection error.
    created : str
        When the calibration was made (ISO date), "" when unknown.
    calibrated : bool
        True when the homography was measured (False: the identity stand-in).
    sha256 : str
        The calibration file's content hash (hex), "" when the calibration is no file's.
    rig : dict, optional
        The identity of the rig it was made for (:meth:`flexvox_calibration.session.RigIdentity.as_dict`; a
        ``RigIdentity`` is taken too): :func:`load_for_capture` and :func:`from_run` keep it, and
        :meth:`check_rig` refuses it on another rig, camera or resolution as a file is refused. None: tied to
        no rig (the uncalibrated default, or one built by hand), taken on any.
    """

    homography: np.ndarray = field(default_factory=lambda: np.eye(3))
    sync: SyncTiming | None = None
    source: str = "identity (uncalibrated)"
    rms_px: float | None = None
    created: str = ""
    calibrated: bool = False
    sha256: str = ""
    rig: dict | None = None

    def __post_init__(self):
        try:
            h = geometry.check_matrix(self.homography)
        except CalibrationError as exc:
            raise CalibrationRefused(str(exc)) from None
        if abs(np.linalg.det(h)) < 1e-12:
            raise CalibrationRefused("`homography` must be invertible")
        object.__setattr__(self, "homography", h / h[2, 2])
        if self.sync is not None and not isinstance(self.sync, SyncTiming):
            raise CalibrationRefused(f"`sync` must be a SyncTiming or None; got {type(self.sync).__name__}")
        rig = self.rig.as_dict() if hasattr(self.rig, "as_dict") else self.rig
        if rig is not None and not isinstance(rig, dict):
            raise CalibrationRefused(f"`rig` must be a RigIdentity, its as_dict(), or None; got {type(rig).__name__}")
        object.__setattr__(self, "rig", None if rig is None else dict(rig))

    def check_rig(self, identity) -> None:
        """Refuse this calibration on the rig of ``identity`` when it was made for another rig, camera or
        resolution: :class:`CalibrationRefused`, in the words a calibration file made for another rig is refused
        with (:func:`flexvox_calibration.files.check_identity`). A calibration tied to no rig (:attr:`rig` None)
        passes.
        """
        if self.rig is None:
            return
        try:
            check_identity({"rig": self.rig}, identity, self.made_as)
        except CalibrationError as exc:
            raise CalibrationRefused(str(exc)) from None

    @property
    def made_as(self) -> str:
        """What messages name the calibration by: its file (or run) without a sync profile put on top; the sync
        profile when it is all there is."""
        own, _, sync = self.source.partition("; sync from ")
        return sync if sync and not self.calibrated else own

    # ------------------------------------------------------------------ what capture uses
    @property
    def phase_slots(self) -> int:
        """The phase the shutter patterns use (0 without a sync measurement)."""
        return 0 if self.sync is None else self.sync.phase_slots

    @property
    def trigger_delay_us(self) -> float:
        """The camera trigger delay that goes with :attr:`phase_slots` (0 without a sync measurement)."""
        return 0.0 if self.sync is None else self.sync.trigger_delay_us

    def for_plan(self, K: int, period_us: int) -> tuple[int, float, list[str]]:
        """``(phase, trigger delay µs, warnings)`` for a code of ``K`` slots at ``period_us``.

        The phase is a count of slots measured at one timing; at another it is only a guess
        (reduced mod K), and a warning says to measure it again. Without a sync measurement:
        phase 0, no delay, and a warning.
        """
        warnings: list[str] = []
        if not self.calibrated:
            warnings.append("no calibration: the patterns assume the identity projector-to-camera map; calibrate "
                            "the rig (flexvox calibrate -o CAL.json) and load the file")
        if self.sync is None:
            warnings.append("no sync measurement: phase 0 and no trigger delay (run the synchronisation step)")
            return 0, 0.0, warnings
        s = self.sync
        guess = self.timing_guess(K, period_us)
        if guess:
            warnings.append(guess)
        delay = s.trigger_delay_us
        if delay >= period_us:
            delay = float(delay % period_us)
        return s.phase_slots % int(K), delay, warnings

    def timing_guess(self, K: int, period_us: int) -> str:
        """Why the phase is only a guess for a code of ``K`` slots at ``period_us`` (the sync was measured at
        another timing); "" when the sync was measured at this one, or there is none."""
        s = self.sync
        if s is None or (s.K, s.period_us) == (int(K), int(period_us)):
            return ""
        return (f"the sync was measured at K = {s.K}, {s.period_us} µs patterns; this capture is K = {K}, "
                f"{period_us} µs: phase {s.phase_slots % int(K)} is a guess, run the synchronisation at this timing")

    def with_sync(self, sync: SyncTiming | None, *, source: str | None = None) -> CaptureCalibration:
        """The same homography with another synchronisation (a sync profile loaded on top)."""
        src = self.source if source is None else f"{self.source}; sync from {source}"
        return replace(self, sync=sync, source=src)

    def as_dict(self) -> dict:
        """The recording's ``calibration`` attribute."""
        s = self.sync
        return {"homography": self.homography.tolist(), "calibrated": self.calibrated,
                "phase_slots": self.phase_slots, "trigger_delay_us": self.trigger_delay_us,
                "sync": None if s is None else {"K": s.K, "period_us": s.period_us, "raw_phase_slots":
                                                s.raw_phase_slots, "offset_us": s.offset_us},
                "rms_px": self.rms_px, "created": self.created, "source": self.source,
                "sha256": self.sha256 or None}

    def __repr__(self) -> str:
        return f"<CaptureCalibration {self.describe()}>"

    def describe(self) -> str:
        """One line: origin, date, RMS, phase and delay."""
        rms = "—" if self.rms_px is None else f"{self.rms_px:.3f} px"
        sync = "no sync" if self.sync is None else self.sync.describe()
        when = f" · {self.created}" if self.created else ""
        return f"{self.source}{when} · RMS {rms} · {sync}"


def file_sha256(path) -> str:
    """The SHA-256 of a file's bytes (hex): what names a calibration file's content."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def named(path: Path, sha256: str) -> str:
    """A file as a recording names it: its path and the start of its content hash."""
    return f"{path} (sha256 {sha256[:16]})"


def _format_of(path: Path) -> str | None:
    try:
        data = read_json(path)
    except ValueError:
        return None  # the loaders below say what is wrong
    return data.get("format") if isinstance(data, dict) else None


def load_for_capture(path, identity) -> CaptureCalibration:
    """Read a calibration file for capture on the rig of ``identity``.

    Parameters
    ----------
    path : str or Path
        A calibration file: the homography and, when the sync step ran, its timing.
    identity : flexvox_calibration.session.RigIdentity
        The capture rig's; a file made for another rig, camera or resolution is refused.

    Raises
    ------
    CalibrationRefused
        For a missing, damaged or failed file, a sync profile (it has no homography: load it with
        :func:`load_sync_for_capture`), or a file made for another rig; the message says which.
    """
    path = Path(path).expanduser()
    if _format_of(path) == SYNC_FORMAT:
        raise CalibrationRefused(f"{path} is a sync profile (the synchronisation wizard's), not a calibration: it "
                                 "has no homography. Give it as a sync profile (flexvox capture --sync-profile; "
                                 "Capture: \"Load sync profile…\") and a calibration file as the calibration")
    try:
        data = load_calibration(path, identity)  # also says what is wrong with any other file
    except CalibrationError as exc:
        raise CalibrationRefused(str(exc)) from exc
    quality = data.get("quality")
    if quality is None:
        quality = {}
    if not isinstance(quality, dict):
        raise CalibrationRefused(f"{path}: `quality` must be an object (the homography step's summary) or null; got "
                                 f"{quality!r}")
    if quality.get("status") not in (None, "ok", "partial"):
        raise CalibrationRefused(f"{path}: the calibration's homography step did not succeed "
                                 f"({quality.get('status')}): calibrate again")
    try:
        sync = SyncTiming.from_summary(data.get("sync"))
    except CalibrationRefused as exc:
        raise CalibrationRefused(f"{path}: `sync`: {exc}") from None
    rms = quality.get("rms_px")
    if rms is not None and (isinstance(rms, bool) or not isinstance(rms, int | float)):
        raise CalibrationRefused(f"{path}: `quality.rms_px` must be a number (the homography's RMS reprojection "
                                 f"error in pixels) or null; got {rms!r}")
    created = str(data.get("created", ""))
    sha256 = file_sha256(path)
    _logger.info("calibration for capture: %s (sha256 %s)", path, sha256)
    source = named(path, sha256) + (" (a partial calibration)" if quality.get("status") == "partial" else "")
    return CaptureCalibration(data["H"], sync, source, None if rms is None else float(rms), created, True, sha256,
                              _rig_of(identity))


def load_sync_for_capture(path, identity, *, base: CaptureCalibration | None = None) -> CaptureCalibration:
    """``base`` (default uncalibrated) with the phase and trigger delay of a sync profile.

    Raises
    ------
    CalibrationRefused
        For a missing or damaged profile, one without a successful measurement, a calibration file
        (load it with :func:`load_for_capture`), or one made for another rig; the message says which.
    """
    path = Path(path).expanduser()
    if _format_of(path) == CALIBRATION_FORMAT:
        raise CalibrationRefused(f"{path} is a calibration file, not a sync profile: give it as the calibration "
                                 "(flexvox capture --calibration; Capture: \"Load calibration…\")")
    try:
        data = load_sync_profile(path, identity)
    except CalibrationError as exc:
        raise CalibrationRefused(str(exc)) from exc
    try:
        sync = SyncTiming.from_summary(data.get("sync"))
    except CalibrationRefused as exc:
        raise CalibrationRefused(f"{path}: `sync`: {exc}") from None
    if sync is None:
        raise CalibrationRefused(f"{path}: the sync profile holds no successful measurement")
    _logger.info("sync profile for capture: %s (%s)", path, sync.describe())
    calibration = (base or CaptureCalibration()).with_sync(
        sync, source=f"{named(path, file_sha256(path))}, made {data.get('created', 'undated')}")
    return calibration if calibration.rig is not None else replace(calibration, rig=_rig_of(identity))


def from_run(run, run_identity, identity, *, now=None) -> CaptureCalibration:
    """A fresh calibration run (:class:`flexvox_calibration.pipeline.CalibrationRun`) for capture.

    Parameters
    ----------
    run : CalibrationRun
        Must have succeeded.
    run_identity, identity : RigIdentity
        The rig it ran on, and the capture rig's: they must be the same rig.

    Raises
    ------
    CalibrationRefused
        When the run did not succeed, or ran on another rig.
    """
    if run is None or not run.success:
        raise CalibrationRefused("run a successful calibration first")
    try:
        check_identity({"rig": run_identity.as_dict()}, identity, "the calibration just run")
    except CalibrationError as exc:
        raise CalibrationRefused(str(exc)) from exc
    hom = run.keep["homography"]
    sync = run.keep.get("sync")
    when = (now or _dt.datetime.now(_dt.UTC)).isoformat(timespec="seconds")
    return CaptureCalibration(np.asarray(hom.homography, np.float64),
                              SyncTiming.from_summary(None if sync is None else sync.summary()),
                              "the calibration just run (not saved)", float(hom.rms_px), when, True,
                              rig=_rig_of(identity))


def _rig_of(identity) -> dict:
    """The identity a calibration was checked against, as :attr:`CaptureCalibration.rig` keeps it."""
    return identity.as_dict() if hasattr(identity, "as_dict") else dict(identity)


__all__ = ["CalibrationRefused", "CaptureCalibration", "SyncTiming", "file_sha256", "from_run", "load_for_capture",
           "load_sync_for_capture", "named"]
