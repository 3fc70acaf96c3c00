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


def _tqdm_steps(desc: str) -> Callable[[int, int], None]:
    """One ``tqdm.auto`` bar per calibration step (a notebook widget in Jupyter, text in a terminal)."""
    from tqdm.auto import tqdm

    bar = tqdm(desc=desc, unit="pattern", leave=False)

    def update(done: int, total: int) -> None:
        if bar.total != total:
            bar.reset(total=total)
        bar.n = done
        bar.refresh()
        if done >= total:
            bar.close()

    return update


def calibrate_rig(rig, *, tile=(4, 4), progress: bool | Callable = True, save=None,
                  overwrite: bool = False) -> CaptureCalibration:
    """Calibrate ``rig`` (co-location, homography, shutter, synchronisation, frame check) for capture.

    Parameters
    ----------
    rig : rig_drivers.interfaces.Rig
        What :func:`rig_drivers.open_rig` returns (the simulated rig with ``"mock"``). On the simulated
        rig the calibration target is put in view and the scene comes back at the end.
    tile : (int, int), keyword-only
        The code's tile the shutter step checks.
    progress : bool or callable, keyword-only
        True: a ``tqdm.auto`` bar per step; False: none; a callable ``progress(step_name)`` returns
        ``update(done, total)`` for each step.
    save : str or Path, optional, keyword-only
        Also write the calibration file (``flexvox calibrate -o``'s format) there.
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

    Examples
    --------
    >>> from rig_drivers import open_rig
    >>> rig = open_rig("mock", camera_size=(48, 64))  # doctest: +SKIP
    >>> cal = calibrate_rig(rig, progress=False)  # doctest: +SKIP
    >>> cal.phase_slots, round(cal.rms_px, 2)  # doctest: +SKIP
    (6, 0.18)
    """
    from flexvox_calibration.files import save_calibration
    from flexvox_calibration.pipeline import run_calibration
    from flexvox_calibration.session import RigSession

    steps = _tqdm_steps if progress is True else (None if progress is False else progress)
    if steps is not None and not callable(steps):
        raise TypeError(f"`progress` must be True, False or a callable; got {type(progress).__name__}")
    session = RigSession.from_rig(rig)
    run = run_calibration(rig, session, tile=tuple(tile), progress=steps)
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
