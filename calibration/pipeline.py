"""The whole calibration in order — co-location, homography, shutter masks, sync, frame check —
as one Qt-free call shared by ``flexvox calibrate``, the demo and the GUI wizards."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rig_drivers.interfaces import Rig


@dataclass
class CalibrationRun:
    """Outcome of :func:`run_calibration`.

    Attributes
    ----------
    report : dict
        One summary per step (``colocation``, ``homography``, ``shutter``, ``sync``, ``frames``) and
        ``failed`` naming the first step that failed.
    success : bool
    keep : dict
        The full results: ``homography`` (a HomographyResult, with its residual map), ``shutter``
        (the verification, with its map of wrong pixels), ``shutter_patterns`` (the
        :class:`~flexvox_calibration.shutter.ShutterPatterns` verified, phase 0), ``parallax`` (simulated
        rig), ``sync`` (a SyncResult, with its leakage curve).
    """

    report: dict = field(default_factory=dict)
    success: bool = False
    keep: dict = field(default_factory=dict)


def calibration_tile(tile) -> tuple[int, int]:
    """``tile`` (``(m, n)`` or ``"MxN"``) as a calibration's code tile: at least 2 slots.

    Raises
    ------
    CalibrationError
        For a 1x1 tile: K = 1 slot is open all the time, so there is no shutter to verify and no phase to
        measure (a 1x1 capture needs no calibration); or a tile that is no tile (the message says why).
    """
    from flexvox_calibration.errors import CalibrationError
    from flexvox_core.tiles import validate_tile

    try:
        m, n = validate_tile(tile)
    except ValueError as exc:
        raise CalibrationError(str(exc)) from None
    if m * n < 2:
        raise CalibrationError(f"a {m}x{n} tile (K = 1) has nothing to shutter: its one slot is open all the time, "
                               "so there is no shutter to verify and no phase to measure; calibrate with the tile "
                               "you capture with (at least 2 slots, e.g. 4x4). A 1x1 capture needs no calibration")
    return m, n


def _no_progress(desc: str):
    return lambda done, total: None


def run_calibration(rig: Rig, session, *, tile=(4, 4), progress=None) -> CalibrationRun:
    """Run every calibration step on an opened ``session`` of ``rig``; stop at the first failure.

    ``progress(desc)`` returns an ``update(done, total)`` callable for each step. On the
    simulated rig the calibration target is put in view first (as an operator holds a board in
    front of a real rig's camera) and the scene comes back at the end, and the parallax test moves
    the target to a second depth; on a real rig the parallax test is skipped with a message (it
    needs the operator to move the target).
    """
    progress = progress or _no_progress
    sim = rig.simulated
    placed = sim is not None and sim.viewing != "target"
    if placed:
        sim.show_target()
    try:
        return _run_steps(rig, session, tile, progress)
    finally:
        if placed:
            sim.show_scene()


def _run_steps(rig, session, tile, progress) -> CalibrationRun:
    from flexvox_calibration.colocation import capture_view, measure_alignment, parallax_test
    from flexvox_calibration.homography import calibrate_homography
    from flexvox_calibration.shutter import make_shutter_patterns, verify_shutter
    from flexvox_calibration.sync import band_patterns, check_frames, measure_sync
    from flexvox_core.design import design_code

    code = design_code(calibration_tile(tile)).require()  # an impossible tile is refused before any device moves
    run = CalibrationRun()
    report, keep = run.report, run.keep
    with session:
        align = measure_alignment(session, progress=progress("co-location"))
        report["colocation"] = {"alignment": align.summary()}
        if rig.simulated is not None:
            near = capture_view(session, progress=progress("parallax: near target"))
            rig.simulated.move_target(2.0)
            try:
                far = capture_view(session, progress=progress("parallax: far target"))
            finally:
                rig.simulated.move_target(1.0)
            par = parallax_test([near, far], session.projector_size)
            report["colocation"]["parallax"] = par.summary()
            keep["parallax"] = par
            colocated = par.success
        else:
            report["colocation"]["parallax"] = {
                "status": "skipped", "message": "the parallax test needs the target at two depths: run it from "
                                                 "the calibration wizard, which asks you to move the target"}
            colocated = True
        if not align.success or not colocated:
            report["failed"] = "colocation"
            return run
        hom = calibrate_homography(session, progress=progress("homography"))
        report["homography"] = hom.summary()
        keep["homography"] = hom
        if not hom.success:
            report["failed"] = "homography"
            return run
        K = code.shape[2]
        shutter = make_shutter_patterns(code, hom.homography, session.camera_size, session.projector_size,
                                        layout=session.pixel_layout)
        ver = verify_shutter(session, shutter, progress=progress("shutter"))
        report["shutter"] = ver.summary() | {"addressable": shutter.addressable, "K": K}
        keep["shutter"] = ver
        keep["shutter_patterns"] = shutter
        sync = measure_sync(session, hom.homography, K=K, progress=progress("sync"))
        report["sync"] = sync.summary()
        keep["sync"] = sync
        if sync.success:
            bands, _ = band_patterns(hom.homography, session.camera_size, session.projector_size, K)
            frames = check_frames(session, bands, 30)
            report["frames"] = frames.summary()
        outcomes = (("shutter", ver.success), ("sync", sync.success),
                    ("frames", report.get("frames", {}).get("status") == "ok"))
        failed = [name for name, good in outcomes if not good]
        run.success = not failed
        if failed:
            report["failed"] = failed[0]
    return run


def truth_comparison(rig: Rig, run: CalibrationRun, camera_size) -> dict:
    """On the simulated rig: the hidden truth beside what was found (for tests, the demo, --json)."""
    from flexvox_calibration.geometry import homography_error_px

    truth = rig.truth
    out = {"phase_true": int(truth.phase_slots), "delay_true_us": int(truth.delay_us)}
    hom = run.keep.get("homography")
    if hom is not None and hom.homography is not None:
        out["homography_error_px"] = homography_error_px(hom.homography, truth.homography, camera_size)
    return out
