"""Fixtures of the Qt application tests: a small simulated recording, settings in a temp file, a job runner."""

from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent

# A harmless message of Qt's offscreen platform plugin when windows are shown.
_OFFSCREEN_NOISE = "propagateSizeHints"


def pytest_collection_modifyitems(config, items):
    """Every GUI test fails on a Qt warning (pytest-qt's qt_log_level_fail), bar the offscreen plugin's note."""
    for item in items:
        if HERE in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.qt_log_level_fail("WARNING"))
            item.add_marker(pytest.mark.qt_log_ignore(_OFFSCREEN_NOISE))


TILE = (2, 4)
FRAMES = 6
SIZE = (32, 48)


@pytest.fixture(scope="session")
def recording(tmp_path_factory):
    """The tests' one simulated recording (tests/conftest.py's ``recording``, balls, 2×4 code (K = 8), 6 frames of
    32×48), made once for the GUI's tests: they only read it."""
    from tests.recordings import simulate_recording

    return simulate_recording(tmp_path_factory.mktemp("rec"), frames=FRAMES, size=SIZE, tile=TILE, name="balls.zarr")


@pytest.fixture(scope="session")
def naive_psnr(recording):
    """PSNR of the raw frames repeated K times: every reconstruction must beat it."""
    from flexvox_core.metrics import psnr
    from flexvox_core.recording import open_recording

    rec = open_recording(recording)
    return float(psnr(rec.ground_truth[:], np.repeat(rec.normalised_frames(), rec.K, axis=0)))


@pytest.fixture
def settings(tmp_path):
    """Settings in a temporary INI file."""
    from flexvox_app.gui.widgets.settings import settings_at

    return settings_at(tmp_path / "settings.ini")


@pytest.fixture
def runner(qapp):
    """A job runner on its own thread pool, shut down after the test."""
    from flexvox_app.gui.application import configure_pyqtgraph
    from flexvox_app.gui.widgets.qt_jobs import JobRunner

    configure_pyqtgraph()
    r = JobRunner()
    yield r
    assert r.shutdown(10_000), "a background job did not stop"


@pytest.fixture
def review(qtbot, settings, runner):
    """A Review workspace with the shipped bench figures."""
    from flexvox_app.gui.models.expected_quality import load_table
    from flexvox_app.gui.models.machine_speed import SpeedModel, _version, settings_key
    from flexvox_app.gui.review.workspace import ReviewWorkspace

    # Motion-aware's calibration run takes seconds: tests that do not time this machine take a made-up model.
    settings.set(settings_key("motion-aware", 8), SpeedModel("motion-aware", 8, c=1e-6, p=1.0, points=(),
                                                             version=_version()).to_json())
    ws = ReviewWorkspace(settings, runner, load_table())
    qtbot.addWidget(ws)
    ws.resize(1200, 800)
    return ws


@pytest.fixture
def opened(qtbot, review, recording):
    """The Review workspace with the recording open (preview off, so tests control the jobs)."""
    review.preview_check.setChecked(False)
    review.open_recording(recording)
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    return review


def small_rig(**kw):
    """The simulated rig, small, on real time."""
    from rig_drivers.profile import open_rig

    kw.setdefault("scene", "balls")
    kw.setdefault("camera_size", (48, 64))
    kw.setdefault("subframes", 64)
    return open_rig("mock", **kw)


H_SHIFT = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -0.25], [0.0, 0.0, 1.0]])
"""A homography a hand-made calibration file holds (half a pixel right, a quarter up)."""


def write_calibration(path, identity, *, h=H_SHIFT, phase=3, K=16, period_us=1041, rms=0.123, overwrite=False):
    """A calibration file for the rig of ``identity`` (as flexvox calibrate writes it), made 2026-03-14."""
    import datetime as dt

    from flexvox_calibration.files import CALIBRATION_FORMAT, CALIBRATION_VERSION, write_versioned

    body = {"homography": {"projector_to_camera": h.tolist(), "camera_to_projector": np.linalg.inv(h).tolist()},
            "quality": {"status": "ok", "rms_px": rms},
            "sync": {"status": "ok", "phase_slots": phase, "K": K, "period_us": period_us,
                     "recommended_camera_delay_us": 0.0}}
    return write_versioned(path, CALIBRATION_FORMAT, CALIBRATION_VERSION, identity, body, overwrite=overwrite,
                           now=dt.datetime(2026, 3, 14, 9, 30, tzinfo=dt.UTC))
