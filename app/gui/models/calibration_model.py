"""The Calibrate workspace's model (Qt-free): what a calibration runs on, the run itself, and its figures.

:func:`run_workspace_calibration` is :func:`flexvox_calibration.pipeline.run_calibration` (the call
``flexvox calibrate`` makes) with per-step progress and cancel: the pipeline asks
``progress(desc)`` for an update callable at the start of each step, and the callable this
module returns raises :class:`~flexvox_app.gui.models.jobs.Cancelled` when the token is set, so a cancel
takes effect between steps and between the patterns of a step (the session's ``with`` block
stops and closes the devices on the way out).

The pipeline's :class:`~flexvox_calibration.pipeline.CalibrationRun` keeps the full results: the
homography (with its residual map), the shutter verification (with its map of wrong pixels)
and the sync result (with its leakage curve and delay sweep).

Calibration runs on the rig's own devices. On the simulated rig (``--rig mock``) that is the one
rig Capture records with (a projector finer than the camera behind a hidden homography, a hidden
phase and sub-slot delay drawn from its seed): its calibration target is put in view for every
calibration step (as an operator holds a board in front of a real rig), the result is compared
with the hidden truth, and "Use for capture" hands it to the Capture workspace, which accepts it
because it describes the same rig.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

from flexvox_app.gui.models.jobs import CancelToken
from flexvox_app.gui.models.live_source import projector_size
from flexvox_app.gui.models.rig_service import RigService

_logger = logging.getLogger(__name__)

STEPS = ("co-location", "parallax: near target", "parallax: far target", "homography", "shutter", "sync")
"""The steps whose progress is reported, in order (the parallax views only on the simulated rig)."""


class StepTracker:
    """Which step runs and how far it is (written by the worker, read by the GUI: plain attribute swaps)."""

    def __init__(self, token: CancelToken, report=None):
        self.token = token
        self.step = ""
        self.index = -1
        self.done = 0
        self.total = 0
        self.report = report
        """``report(done, total)`` (e.g. a job's progress signal), or None."""

    def __call__(self, desc: str):
        """The pipeline's ``progress(desc)``: a cancel point, then an ``update(done, total)`` callable."""
        self.token.check()
        self.step = desc
        self.index = STEPS.index(desc) if desc in STEPS else self.index
        self.done, self.total = 0, 0
        if self.report is not None:
            self.report(0, 0)

        def update(done: int, total: int) -> None:
            self.done, self.total = int(done), int(total)
            if self.report is not None:
                self.report(self.done, self.total)
            self.token.check()

        return update


@dataclass
class CalibrationTarget:
    """The rig a calibration runs on and how to open a session on it.

    Attributes
    ----------
    rig : rig_drivers.interfaces.Rig
    simulated : bool
    """

    rig: object
    simulated: bool

    @property
    def seed(self) -> int | None:
        """The simulated rig's seed (None on a real rig)."""
        return int(self.rig.simulated.truth.seed) if self.simulated else None

    def session(self):
        """A new (unopened) :class:`flexvox_calibration.session.RigSession` on the rig.

        On the simulated rig the calibration target is put in front of the camera first (the
        Capture workspace puts the scene back when it starts the live view or a recording).
        """
        from flexvox_calibration.session import RigSession

        if self.simulated:
            if self.rig.simulated.viewing != "target":
                self.rig.simulated.show_target()
            return RigSession.from_rig(self.rig)
        return RigSession.from_rig(self.rig, projector_size=projector_size(self.rig.projector))


def target_for(service: RigService) -> CalibrationTarget:
    """The service's rig as a calibration target (the simulated rig is the same rig Capture uses)."""
    return CalibrationTarget(service.rig, service.simulated)


@dataclass
class CalibrationOutcome:
    """A finished run as the workspace shows it.

    Attributes
    ----------
    run : flexvox_calibration.pipeline.CalibrationRun
    identity : flexvox_calibration.session.RigIdentity
        What a saved file is tied to.
    camera_size : (H, W)
    truth : dict or None
        Simulated rig: :func:`flexvox_calibration.pipeline.truth_comparison`.
    shutter : flexvox_calibration.shutter.ShutterVerification or None
        The second verification pass (its ``wrong`` map); None when the run stopped before the shutter.
    seconds : float
    finished_at : str
        The local time the run ended ("14:03:27"), to tell runs apart in words.
    """

    run: object
    identity: object
    camera_size: tuple[int, int]
    truth: dict | None = None
    shutter: object | None = None
    seconds: float = 0.0
    finished_at: str = ""
    notes: list = field(default_factory=list)

    @property
    def success(self) -> bool:
        """True when every step succeeded (then the calibration can be saved)."""
        return bool(self.run.success)

    @property
    def report(self) -> dict:
        """The pipeline's per-step summaries."""
        return self.run.report

    @property
    def homography(self):
        """The :class:`~flexvox_calibration.homography.HomographyResult`, or None."""
        return self.run.keep.get("homography")

    @property
    def sync(self):
        """The :class:`~flexvox_calibration.sync.SyncResult`, or None."""
        return self.run.keep.get("sync")


def run_workspace_calibration(target: CalibrationTarget, *, tile=(4, 4), cancel: CancelToken | None = None,
                              tracker: StepTracker | None = None) -> CalibrationOutcome:
    """Run the whole calibration on ``target`` with per-step progress and cancel.

    Raises
    ------
    flexvox_app.gui.models.jobs.Cancelled
        When ``cancel`` was set (between steps or patterns); the devices are stopped and closed.
    """
    from flexvox_calibration.pipeline import run_calibration, truth_comparison

    cancel = cancel or CancelToken()
    tracker = tracker or StepTracker(cancel)
    t0 = time.perf_counter()
    session = target.session()
    identity, camera_size = session.identity, session.camera_size
    run = run_calibration(target.rig, session, tile=tuple(tile), progress=tracker)
    outcome = CalibrationOutcome(run, identity, camera_size)
    outcome.shutter = run.keep.get("shutter")
    if target.simulated:
        outcome.truth = truth_comparison(target.rig, run, camera_size)
    outcome.seconds = time.perf_counter() - t0
    outcome.finished_at = time.strftime("%H:%M:%S")
    _logger.info("calibration %s in %.1f s", "succeeded" if run.success else
                 f"stopped at {run.report.get('failed')}", outcome.seconds)
    return outcome


@dataclass
class LiveColocation:
    """One live co-location measurement and the camera image it goes with.

    Attributes
    ----------
    alignment : flexvox_calibration.colocation.AlignmentResult
        The numbers, and the homography estimate (None when the fit failed).
    image : ndarray (H, W) float64 or None
        The camera's view with the projector fully lit, right after the measurement.
    projector_size : (H, W)
    """

    alignment: object
    image: object
    projector_size: tuple[int, int]


def measure_live_colocation(target: CalibrationTarget, cancel: CancelToken | None = None) -> LiveColocation:
    """:func:`measure_live_alignment` and one camera image under a white projector (one more capture)."""
    import numpy as np

    from flexvox_calibration.colocation import measure_alignment

    cancel = cancel or CancelToken()

    def check(done, total):
        cancel.check()

    with target.session() as session:
        result = measure_alignment(session, progress=check)
        cancel.check()
        image = None
        if result.status != "no_frames":
            image = session.capture(np.ones(session.projector_size, bool))
        return LiveColocation(result, image, tuple(session.projector_size))


def measure_live_alignment(target: CalibrationTarget, cancel: CancelToken | None = None):
    """One set of co-location numbers (:func:`flexvox_calibration.colocation.measure_alignment`) on ``target``."""
    from flexvox_calibration.colocation import measure_alignment

    cancel = cancel or CancelToken()

    def check(done, total):
        cancel.check()

    with target.session() as session:
        return measure_alignment(session, progress=check)


# --------------------------------------------------------------------------- figures in words


def _num(v, fmt: str = ".3f", unit: str = "") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    return f"{v:{fmt}}{unit}"


def verdict(status: str | None) -> tuple[str, bool | None]:
    """(word, good) for a step status: ✓/✗ and whether it passed (None: not run or skipped)."""
    if status is None:
        return "not run", None
    if status == "ok":
        return "✓ ok", True
    if status == "skipped":
        return "skipped", None
    return f"✗ {status.replace('_', ' ')}", False


def summary_rows(outcome: CalibrationOutcome) -> list[tuple[str, list[tuple[str, str]], str | None, str]]:
    """Per section: (title, [(figure, value)], status, message) — what the results page lays out."""
    rep = outcome.report
    rows = []
    col = rep.get("colocation", {})
    al = col.get("alignment")
    if al is not None:
        off = al.get("offset_px")
        rows.append(("Co-location", [
            ("offset of the projector's centre", "—" if off is None else f"({off[0]:+.2f}, {off[1]:+.2f}) px"),
            ("rotation", _num(al.get("rotation_deg"), "+.3f", "°")),
            ("scale", _num(al.get("scale"), ".4f", " camera px / projector px")),
            ("mirrored", "yes" if al.get("mirrored") else "no"),
            ("lit fraction of the camera frame", _num(al.get("lit_fraction"), ".1%")),
        ], al.get("status"), al.get("message", "")))
    par = col.get("parallax")
    if par is not None:
        figures = []
        if par.get("disagreement_px"):
            figures.append(("views' homographies differ by", ", ".join(f"{v:.3f}" for v in par["disagreement_px"])
                            + " px"))
            figures.append(("residual RMS per view", ", ".join(f"{v:.3f}" for v in par["view_rms_px"]) + " px"))
            sx, sy = par["shift_px"]
            figures.append(("near − far shift", f"({sx:+.3f}, {sy:+.3f}) px; scale change {par['scale_change']:+.2e}"))
        rows.append(("Parallax (co-located?)", figures, par.get("status"),
                     par.get("message", "") + (f" {par['advice']}" if par.get("advice") and par.get("status") != "ok"
                                               else "")))
    hom = rep.get("homography")
    if hom is not None:
        rows.append(("Homography", [
            ("RMS reprojection error", _num(hom.get("rms_px"), ".3f", " px")),
            ("coverage (decoded)", _num(hom.get("coverage"), ".1%")),
            ("inliers / decoded", f"{hom.get('inliers', 0)} / {hom.get('decoded', 0)}"),
            ("contrast", _num(hom.get("contrast_snr"), ".1f", " noise σ")),
        ], hom.get("status"), hom.get("message", "")))
    sh = rep.get("shutter")
    if sh is not None:
        rows.append(("Shutter masks", [
            ("slot accuracy", _num(sh.get("accuracy"), ".3%")),
            ("wrong pixels", str(sh.get("wrong"))),
            ("crosstalk", _num(sh.get("crosstalk"), ".2%")),
            ("decodable fraction", _num(sh.get("decodable_fraction"), ".1%")),
            ("addressable pixels", _num(sh.get("addressable"), ".1%")),
            ("K", str(sh.get("K"))),
        ], sh.get("status"), sh.get("message", "")))
    sy = rep.get("sync")
    if sy is not None:
        rows.append(("Synchronisation", [
            ("phase with no camera delay (exposure slot 0 sees slot)", str(sy.get("phase_slots"))),
            ("sub-slot delay", _num(sy.get("delay_us"), ".0f", " µs")),
            ("recommended camera trigger delay", _num(sy.get("recommended_camera_delay_us"), ".0f", " µs")),
            ("phase the shutter patterns use, with that delay", str(sy.get("effective_phase_slots"))),
            ("sweep slope (expected 1)", _num(sy.get("slope"), ".3f")),
        ], sy.get("status"), sy.get("message", "")))
    fr = rep.get("frames")
    if fr is not None:
        rows.append(("Drops and drift", [
            ("frames read", str(fr.get("frames"))),
            ("dropped (frame-id gaps)", str(fr.get("gaps"))),
            ("late arrivals", str(fr.get("long_intervals"))),
            ("frame period", f"{_num(fr.get('frame_period_us'), '.1f')} µs (expected {fr.get('expected_period_us')})"),
            ("drift", _num(fr.get("drift_us_per_frame"), "+.3f", " µs per frame")),
        ], fr.get("status"), fr.get("message", "")))
    if outcome.truth is not None:
        t = outcome.truth
        found_phase = sy.get("phase_slots") if sy else None
        found_delay = sy.get("delay_us") if sy else None
        figures = [("homography error against the truth", _num(t.get("homography_error_px"), ".4f", " px")),
                   ("phase found / true", f"{found_phase} / {t['phase_true']}"),
                   ("delay found / true", f"{_num(found_delay, '.0f')} / {t['delay_true_us']} µs")]
        good = found_phase == t["phase_true"] and t.get("homography_error_px", math.inf) < 0.5
        rows.append(("Against the simulated rig's hidden truth", figures, "ok" if good else "differs",
                     "the simulated rig hides a homography, phase and delay drawn from the seed"))
    return rows
