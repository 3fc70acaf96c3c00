"""Calibration in one call: calibrate a rig (or load its calibration file) and get what capture takes.

What ``flexvox calibrate -o CAL.json`` followed by ``flexvox capture --calibration CAL.json`` does, from Python::

    from rig_drivers import open_rig
    from flexvox_calibration import calibrate_rig

    rig = open_rig("mock")
    cal = calibrate_rig(rig, save="cal.json")   # a CaptureCalibration
    # ... CaptureService(rig, plan, "rec.zarr", calibration=cal, ...)

Both functions build the rig's :class:`~flexvox_calibration.session.RigSession` themselves; the steps are
:func:`flexvox_calibration.pipeline.run_calibration`'s, and the result is
:func:`flexvox_calibration.capture_setup.from_run`'s (or :func:`~flexvox_calibration.capture_setup.load_for_capture`'s).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from flexvox_calibration.capture_setup import CalibrationRefused, CaptureCalibration, from_run, load_for_capture

_logger = logging.getLogger(__name__)

__all__ = ["calibrate_rig", "load_rig_calibration"]


def step_count(rig) -> int:
    """The calibration steps :func:`calibrate_rig` reports on ``rig``: co-location, the parallax test's two
    views (on the simulated rig only; a real rig's is skipped), homography, shutter and synchronisation."""
    return 6 if rig.simulated is not None else 4


class _Steps:
    """The pipeline's per-step progress (``step(desc)`` returns ``update(done, total)``) as one overall count of
    steps, ``report(done_steps, total_steps)``."""

    def __init__(self, report: Callable[[int, int], None], total: int):
        self.report, self.total, self.started = report, total, 0

    def __call__(self, desc: str) -> Callable[[int, int], None]:
        index = self.started
        self.started += 1
        self.report(min(index, self.total), self.total)

        def update(done: int, total: int) -> None:
            if total and done >= total:
                self.report(min(index + 1, self.total), self.total)

        return update


def calibrate_rig(rig, *, tile=(4, 4), progress: bool | Callable[[int, int], None] | None = True, save=None,
                  overwrite: bool = False) -> CaptureCalibration:
    """Calibrate ``rig`` (co-location, homography, shutter, synchronisation, frame check) for capture.

    Parameters
    ----------
    rig : rig_drivers.interfaces.Rig
        What :func:`rig_drivers.open_rig` returns (the simulated rig with ``"mock"``). On the simulated
        rig the calibration target is put in view and the scene comes back at the end.
    tile : (int, int) or "MxN", keyword-only
        The code's tile the shutter and sync steps check: at least 2 slots (a 1x1 tile has nothing to shutter).
    progress : bool or callable(done_steps, total_steps), keyword-only
        The rule of every long call (:mod:`flexvox_core.progress`): True: one ``tqdm.auto`` bar over the steps,
        with its total (:func:`step_count`); False or None: nothing; a callable is called as each step starts
        and ends.
    save : str or Path, optional, keyword-only
        Also write the calibration file (``flexvox calibrate -o``'s format) there. Checked before calibrating, as
        ``flexvox calibrate -o`` is: an existing file (without ``overwrite``) or a missing folder is refused before
        any step runs.
    overwrite : bool, keyword-only
        Replace an existing ``save`` file.

    Returns
    -------
    CaptureCalibration
        The homography, the phase and the camera trigger delay that go together; give it to
        :class:`flexvox_app.capture.CaptureService` as ``calibration=``.

    Raises
    ------
    CalibrationRefused
        When a step fails; the message names the step and what it measured.
    flexvox_calibration.errors.CalibrationFileError
        Before calibrating, for a ``save`` that may not be written (it exists and ``overwrite`` is False, its
        folder is missing or refuses new files).

    Examples
    --------
    >>> from rig_drivers import open_rig
    >>> rig = open_rig("mock", camera_size=(48, 64))  # doctest: +SKIP
    >>> cal = calibrate_rig(rig, progress=False)  # doctest: +SKIP
    >>> cal.phase_slots, round(cal.rms_px, 2)  # doctest: +SKIP
    (6, 0.18)
    """
    from flexvox_calibration.errors import CalibrationFileError
    from flexvox_calibration.files import save_calibration
    from flexvox_calibration.pipeline import calibration_tile, run_calibration
    from flexvox_calibration.session import RigSession
    from flexvox_core.output_files import OutputError, check_output
    from flexvox_core.progress import progress_callback

    tile = calibration_tile(tile)
    if save is not None:
        try:  # as `flexvox calibrate -o` does
            check_output(save, overwrite=overwrite)
        except OutputError as exc:
            raise CalibrationFileError(f"{exc} (checked before calibrating, so no run is lost)") from None
    total = step_count(rig)
    with progress_callback(progress, desc="calibrate", unit="step", total=total) as report:
        session = RigSession.from_rig(rig)
        steps = None if report is None else _Steps(report, total)
        run = run_calibration(rig, session, tile=tile, progress=steps)
        if report is not None and run.success:
            report(total, total)
    if not run.success:
        failed = run.report.get("failed")
        step = run.report.get(failed, {}) if failed else {}
        why = step.get("message", "") if isinstance(step, dict) else str(step)
        raise CalibrationRefused(f"the calibration failed at its {failed} step" + (f": {why}" if why else ""))
    calibration = from_run(run, session.identity, session.identity)
    if save is not None:
        path = save_calibration(save, run.keep["homography"], session.identity, sync=run.keep.get("sync"),
                                overwrite=overwrite)
        calibration = load_for_capture(path, session.identity)
        _logger.info("calibration saved to %s", path)
    return calibration


def load_rig_calibration(rig, path) -> CaptureCalibration:
    """Read a calibration file (``flexvox calibrate -o``, the GUI's Save, :func:`calibrate_rig`'s ``save``)
    for capture on ``rig``.

    Parameters
    ----------
    rig : rig_drivers.interfaces.Rig
        The capture rig; a file made for another rig, camera or resolution is refused.
    path : str or Path

    Returns
    -------
    CaptureCalibration

    Raises
    ------
    CalibrationRefused
        For a missing, damaged or failed file, a sync profile, or a file made for another rig.

    Examples
    --------
    >>> cal = load_rig_calibration(rig, "cal.json")  # doctest: +SKIP
    >>> cal.calibrated  # doctest: +SKIP
    True
    """
    from flexvox_calibration.session import RigSession

    return load_for_capture(Path(path), RigSession.from_rig(rig).identity)
