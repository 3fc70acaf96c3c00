"""Render each workspace to PNG offscreen: ``python -m app.gui.screenshots OUTDIR``.

Runs the whole calibration on the simulated rig and hands it to Capture (``calibrate.png``: the results,
``calibrate_residuals.png``: the homography's residual heat map, ``calibrate_sync.png``: the
leakage curve and delay sweep), shows co-location live (``calibrate_colocation.png``: the camera
with the projector grid through the homography estimate), makes a small simulated recording in
a temporary folder, opens it in Review, runs a motion-aware and a diffusion reconstruction
(``review.png``, ``review_motion.png``, ``review_compare.png``), starts the Capture live view
with its motion-aware preview (``capture.png``), records from it (``capture_recording.png``),
and opens the projector output window (``capture_projector.png``: the workspace saying where it
shows; ``projector_window.png``: the window's top-left corner, where the packed pattern sits at
its native size, magnified ×4 without smoothing for the docs). Settings go to a temporary INI
file, never the user's.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

_logger = logging.getLogger(__name__)

SIZE = (1500, 920)


def make_recording(path: Path, *, scene: str = "drummer", tile=(4, 4), frames: int = 8, size=(120, 160)) -> Path:
    """A simulated recording (with ground truth) at ``path``."""
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    code = design_code(tile).code
    video = render_scene(scene, frames * code.shape[2], *size, seed=0)
    return write_simulation(path, simulate_video(video, code, rate_hz=15.0))


def wait_until(app, condition, timeout_s: float = 60.0) -> None:
    """Process events until ``condition()`` holds; TimeoutError after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError(f"condition not met within {timeout_s} s")
        app.processEvents()
        time.sleep(0.01)


def render(out_dir) -> list[Path]:
    """Write the screenshots into ``out_dir``; returns their paths."""
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import Qt

    from app.gui.application import build_window, ensure_application
    from app.gui.widgets.settings import settings_at
    from rig_drivers.profile import open_rig

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    app = ensure_application()
    written = []
    with tempfile.TemporaryDirectory() as tmp:
        rec = make_recording(Path(tmp) / "drummer.zarr")
        settings = settings_at(Path(tmp) / "settings.ini")
        window = build_window(open_rig("mock", scene="drummer"), settings=settings)
        window.resize(*SIZE)
        window.show()
        review = window.review

        def save(name):
            app.processEvents()
            p = out / name
            if not window.grab().save(str(p)):
                raise OSError(f"cannot write {p}")
            written.append(p)

        window.show_workspace("Calibrate")
        calibrate = window.calibrate
        calibrate.run_calibration()
        wait_until(app, lambda: not calibrate.running, timeout_s=120)
        if calibrate.outcome is None or not calibrate.outcome.success:
            raise RuntimeError(f"the calibration failed: {calibrate.step_label.text()}")
        calibrate.save_panel.path.setText(str(Path(tmp) / "rig-calibration.json"))
        calibrate.save_panel.save_button.click()
        calibrate.save_panel.use_button.click()  # Capture records through this calibration (the operator's path)
        window.show_workspace("Calibrate")
        for index, name in ((0, "calibrate.png"), (1, "calibrate_residuals.png"), (3, "calibrate_sync.png")):
            calibrate.results_view.setCurrentIndex(index)
            save(name)
        calibrate.live_panel.set_live(True)
        wait_until(app, lambda: calibrate.live_panel.colocation is not None, timeout_s=60)
        for _ in range(5):  # let the layout take the numbers' height
            app.processEvents()
            time.sleep(0.02)
        save("calibrate_colocation.png")
        calibrate.live_panel.set_live(False)
        wait_until(app, lambda: calibrate.live_panel.job is None or not calibrate.live_panel.job.running)
        calibrate.results_view.setCurrentIndex(0)

        window.show_workspace("Review")
        review.open_recording(rec)
        wait_until(app, lambda: review.session is not None)
        review.form.set_method_name("diffusion")
        review.form.set_position(0.18)
        review.reconstruct()
        wait_until(app, lambda: len(review.results) == 1)
        review.form.set_method_name("motion-aware")
        review.reconstruct()
        wait_until(app, lambda: len(review.results) == 2, timeout_s=120)
        review.frame_slider.setValue(4 * 16 + 5)
        wait_until(app, lambda: review.preview_job is None or not review.preview_job.running)
        review.tabs.setCurrentIndex(0)
        save("review.png")
        review.tabs.setCurrentIndex(1)
        save("review_motion.png")
        review.tabs.setCurrentIndex(2)
        save("review_compare.png")

        window.show_workspace("Capture")
        capture = window.capture
        capture.start_live()
        live = capture.live_panel
        wait_until(app, lambda: live.stats.received >= 8 and live.preview.runs >= 3, timeout_s=30)
        time.sleep(0.1)
        wait_until(app, lambda: capture.live_panel._latest is None)
        save("capture.png")
        capture.record_panel.path_edit.setText(str(Path(tmp) / "capture-demo.zarr"))
        capture.record_panel.frames_box.setValue(60)
        capture.record()
        wait_until(app, lambda: not capture.recording, timeout_s=60)
        capture.controls_scroll.ensureWidgetVisible(capture.record_panel.box)
        save("capture_recording.png")
        capture.projector.open()
        wait_until(app, lambda: capture.projector.window is not None, timeout_s=30)
        capture.controls_scroll.ensureWidgetVisible(capture.projector)
        save("capture_projector.png")
        projector = capture.projector.window
        h, w = projector.frame_size
        p = out / "projector_window.png"  # the pattern corner of the full-screen window, magnified ×4 (no smoothing)
        corner = projector.grab().toImage().copy(0, 0, w + 16, h + 16)
        if not corner.scaled(4 * corner.width(), 4 * corner.height(), Qt.AspectRatioMode.IgnoreAspectRatio,
                             Qt.TransformationMode.FastTransformation).save(str(p)):
            raise OSError(f"cannot write {p}")
        written.append(p)
        capture.projector.close_window()
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
