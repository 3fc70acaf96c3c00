"""Render each workspace to PNG offscreen: ``python -m flexvox_app.gui.screenshots OUTDIR`` (``make screenshots``).

Plays the operator's session (:class:`flexvox_app.gui.operator_session.OperatorSession`, the one the session test
plays) on the simulated rig at 1280×800 and photographs the window at its steps: ``calibrate.png`` (the
results), ``calibrate_residuals.png`` (the homography's residual heat map), ``calibrate_sync.png`` (the
leakage curve and delay sweep), ``calibrate_colocation.png`` (co-location live: the camera with the
projector grid through the homography estimate), ``capture.png`` (live view with its motion-aware
preview), ``capture_recording.png`` (the recording ended, "Open in Review" next), ``capture_projector.png``
(the workspace saying where the projector output window shows) and ``projector_window.png`` (the window's
top-left corner, where the packed pattern sits at its native size, magnified ×4 without smoothing);
in Review, after diffusion and motion-aware reconstructions, ``review.png`` (the slider's diffusion
preview beside the motion-aware result), ``review_motion.png`` (the flow and the TR map of the
motion-aware result) and ``review_compare.png``; then at 1024×700 with the Devices dock folded,
``calibrate_1024x700.png``, ``capture_1024x700.png`` and ``review_1024x700.png``; last the whole window at
1024×700 with its status bar, after Calibrate saved over the calibration file Capture uses
(``window_1024x700.png``: Capture says so and offers the new one). Settings go to a temporary INI
file, never the user's.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
from pathlib import Path

_logger = logging.getLogger(__name__)

SIZE = (1280, 800)
SMALL = (1024, 700)
"""The small screen the application must work on (every primary action and the scrubber in view)."""
RECORDED_FRAMES = 12


def make_recording(path: Path, *, scene: str = "drummer", tile=(4, 4), frames: int = 8, size=(120, 160)) -> Path:
    """A simulated recording (with ground truth) at ``path``."""
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    code = design_code(tile).code
    video = render_scene(scene, frames * code.shape[2], *size, seed=0)
    return write_simulation(path, simulate_video(video, code, rate_hz=15.0))


def render(out_dir) -> list[Path]:
    """Write the screenshots into ``out_dir``; returns their paths."""
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import Qt

    from flexvox_app.gui.application import build_window, ensure_application
    from flexvox_app.gui.operator_session import OperatorSession
    from flexvox_app.gui.widgets.questions import answering
    from flexvox_app.gui.widgets.settings import settings_at
    from rig_drivers.profile import open_rig

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ensure_application()
    written = []
    with tempfile.TemporaryDirectory() as tmp:
        settings = settings_at(Path(tmp) / "settings.ini")
        rig = open_rig("mock", scene="drummer", seed=0)  # real time: the live view's rates are what an operator sees
        window = build_window(rig, settings=settings)
        window.resize(*SIZE)
        window.show()

        def shot(name):
            p = out / name
            if not window.grab().save(str(p)):
                raise OSError(f"cannot write {p}")
            written.append(p)

        s = OperatorSession(window, tmp, shot=shot)
        try:
            s.connect_devices()
            s.calibrate()
            s.colocation_live()
            s.sync_wizard()
            s.save_calibration()
            s.use_for_capture()
            s.choose_code((4, 4))
            s.live_view(frames=8, previews=3)
            s.record(RECORDED_FRAMES)
            projector = s.projector_window()
            h, w = projector.frame_size
            p = out / "projector_window.png"  # the pattern corner of the full-screen window, ×4 (no smoothing)
            corner = projector.grab().toImage().copy(0, 0, w + 16, h + 16)
            if not corner.scaled(4 * corner.width(), 4 * corner.height(), Qt.AspectRatioMode.IgnoreAspectRatio,
                                 Qt.TransformationMode.FastTransformation).save(str(p)):
                raise OSError(f"cannot write {p}")
            written.append(p)
            s.close_projector_window()
            s.open_in_review()
            s.reconstruct("diffusion", position=0.18)
            s.reconstruct("motion-aware")
            s.go_to(4 * 16 + 5)
            s.slide(0.8)  # the slider's fixed tensor beside motion-aware
            s.frames_tab()
            shot("review.png")
            s.motion_overlay("color")
            shot("review_motion.png")
            s.compare()
            shot("review_compare.png")
            # The small screen: 1024×700 with the Devices dock folded to its strip, each workspace as left.
            s.frames_tab()
            window.device_dock.set_folded(True)
            window.resize(*SMALL)
            for name in ("Calibrate", "Capture", "Review"):
                window.show_workspace(name)
                s.settle()
                shot(f"{name.lower()}_1024x700.png")
            # The calibration in use saved over again from Calibrate: Capture says so and offers it, and the status
            # bar (in view at 1024×700) says so too; the whole window.
            window.show_workspace("Calibrate")
            with answering(True):  # "Replace the existing calibration?"
                window.calibrate.save_panel.save(window.calibrate.save_panel.saved_path)
            window.show_workspace("Capture")
            s.settle()
            shot("window_1024x700.png")
            s.quit()
        finally:
            if window.isVisible():  # a step failed: stop the devices and the jobs all the same
                window.close()
    return written


def main(argv=None) -> int:
    """Command-line entry."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    for p in render(args.out_dir):
        _logger.info("wrote %s", p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
