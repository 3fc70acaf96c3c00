"""Shared test settings: seeded randomness, deterministic hypothesis (the GPU simulator and offscreen Qt: the root
conftest.py)."""

import os
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

# Deterministic examples: the same run on every machine and in CI; no example database.
settings.register_profile(
    "flexvox",
    derandomize=True,
    database=None,
    deadline=None,
    max_examples=60,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "flexvox"))


def pytest_configure(config):
    config.addinivalue_line("markers", "recording(**shape): the shape of the `recording` fixture's simulated "
                                       "recording (the keywords of tests/recordings.py's simulate_recording)")


@pytest.fixture
def recording(request, tmp_path):
    """The path of the tests' one simulated recording with ground truth: by default balls, 2x4 tile (K = 8), 6 frames
    of 32x48 at 15 Hz; a ``@pytest.mark.recording(frames=..., size=..., tile=..., ...)`` mark on the test or its
    module gives another shape (:func:`tests.recordings.simulate_recording`). Made afresh for each test: a test may
    damage it."""
    from tests.recordings import simulate_recording

    mark = request.node.get_closest_marker("recording")
    return simulate_recording(tmp_path, *(mark.args if mark else ()), **(mark.kwargs if mark else {}))


@pytest.fixture
def rng():
    """A seeded generator; tests never use global numpy randomness."""
    return np.random.default_rng(20261121)


def pytest_collection_modifyitems(config, items):
    """Tests marked ``gpu`` need a real NVIDIA GPU: skipped unless FLEXVOX_TEST_GPU=1 (bench/gpu_check.sh)."""
    if os.environ.get("FLEXVOX_TEST_GPU") == "1":
        return
    skip = pytest.mark.skip(reason="needs an NVIDIA GPU: run bench/gpu_check.sh on a machine with one "
                                   "(FLEXVOX_TEST_GPU=1)")
    for item in items:
        if item.get_closest_marker("gpu") is not None:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def qapp(qapp_args, qapp_cls):
    """pytest-qt's QApplication, made through the application's own ``ensure_application``: Python's garbage is then
    collected on the GUI thread only (a collection in a worker thread destroyed Qt widgets there and hung the
    process; flexvox_app.gui.widgets.qapp.GuiThreadGarbageCollector)."""
    from PySide6.QtWidgets import QApplication

    app = QApplication.instance()
    if app is None:
        app = qapp_cls(qapp_args)
    from flexvox_app.gui.widgets.qapp import ensure_application

    return ensure_application()


@pytest.fixture(autouse=True)
def _collect_on_the_main_thread():
    """Where the GUI-thread collector has switched automatic collection off, each test ends with its check, on the
    main thread (tests that run no event loop would otherwise never collect)."""
    yield
    collector = sys.modules.get("flexvox_app.gui.widgets.qapp")
    if collector is not None and collector._COLLECTOR is not None:
        collector._COLLECTOR.check()
