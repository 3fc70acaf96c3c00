"""Co-location live: the camera image with the projector grid drawn through the current homography."""

import numpy as np
import pytest

from flexvox_app.gui.calibrate.colocation_view import ColocationView, apply_homography, projector_grid
from flexvox_app.gui.calibrate.workspace import CalibrateWorkspace
from flexvox_app.gui.models.rig_service import RigService
from tests.rig_drivers.mock_rigs import calibration_rig

# projector (x, y) -> camera: rotate 90°, scale 0.5, shift (40, 4)
H_KNOWN = np.array([[0.0, -0.5, 40.0], [0.5, 0.0, 4.0], [0.0, 0.0, 1.0]])


def test_the_grid_is_the_projectors_through_the_homography():
    g = projector_grid((40, 60), H_KNOWN, divisions=4)
    assert g["grid"].shape == (6, 2, 2) and g["border"].shape == (4, 2, 2) and g["centre"].shape == (2, 2, 2)
    corners = np.array([[-0.5, -0.5], [59.5, -0.5], [59.5, 39.5], [-0.5, 39.5]])
    np.testing.assert_allclose(g["border"][:, 0], apply_homography(H_KNOWN, corners))
    np.testing.assert_allclose(g["border"][0], [[40.25, 3.75], [40.25, 33.75]])  # the top edge, turned 90°
    np.testing.assert_allclose(g["grid"][0], apply_homography(H_KNOWN, [[14.5, -0.5], [14.5, 39.5]]))
    np.testing.assert_allclose(g["centre"].reshape(-1, 2).mean(axis=0), apply_homography(H_KNOWN, [[29.5, 19.5]])[0])
    with pytest.raises(ValueError, match=r"`divisions` must be >= 1; got 0"):
        projector_grid((40, 60), H_KNOWN, divisions=0)


def test_the_overlay_follows_a_known_homography(qtbot):
    view = ColocationView(divisions=4)
    qtbot.addWidget(view)
    image = np.random.default_rng(0).random((48, 64)).astype(np.float32)
    view.show_alignment(image, H_KNOWN, (40, 60))
    assert view.image.image.shape == (48, 64)
    x, y = view.curves["border"].getData()
    expected = projector_grid((40, 60), H_KNOWN, divisions=4)["border"].reshape(-1, 2)
    np.testing.assert_allclose(np.c_[x, y], expected)
    moved = H_KNOWN @ np.array([[1.0, 0, 3], [0, 1, -2], [0, 0, 1]])  # the operator nudges the projector
    view.show_alignment(None, moved, (40, 60))
    x, y = view.curves["grid"].getData()
    np.testing.assert_allclose(np.c_[x, y], projector_grid((40, 60), moved, divisions=4)["grid"].reshape(-1, 2))
    view.show_alignment(image, None, (40, 60))
    assert len(view.curves["grid"].getData()[0]) == 0 and view.segments is None


def test_live_co_location_shows_the_camera_with_the_estimated_grid(qtbot, settings, runner):
    ws = CalibrateWorkspace(RigService(calibration_rig(0)), settings, runner)
    qtbot.addWidget(ws)
    ws.live_panel.check.setChecked(True)
    assert ws.results_view.currentWidget() is ws.results_view.colocation_view
    qtbot.waitUntil(lambda: ws.live_panel.colocation is not None, timeout=20_000)
    ws.live_panel.set_live(False)
    qtbot.waitUntil(lambda: ws.live_panel.job is None or not ws.live_panel.job.running, timeout=10_000)
    live = ws.live_panel.colocation
    assert live.alignment.success and live.image.shape == (120, 160) and live.projector_size == (240, 320)
    view = ws.results_view.colocation_view
    assert view.image.image.shape == (120, 160)
    x, y = view.curves["border"].getData()
    expected = projector_grid(live.projector_size, live.alignment.homography)["border"].reshape(-1, 2)
    np.testing.assert_allclose(np.c_[x, y], expected)
    # the simulated target's projector is twice the camera's size and covers it: its border lies around the frame
    assert x.min() < 5 and x.max() > 155 and y.min() < 5 and y.max() > 115
    assert "expected grid" in view.title.text()
    ws.shutdown()
