"""Shared test settings: seeded randomness, deterministic hypothesis, offscreen Qt."""

import os

# The GPU path's tests run under numba-cuda's simulator unless FLEXVOX_TEST_GPU=1 (bench/gpu_check.sh sets it on
# a machine with a GPU: then the same tests run on the card, and so do those marked `gpu`). Set before numba's
# cuda module is first imported, which reads it once.
if os.environ.get("FLEXVOX_TEST_GPU") != "1":
    os.environ["NUMBA_ENABLE_CUDASIM"] = "1"
    import sys

    if "numba.core.config" in sys.modules:  # a pytest plugin (napari's) imported numba already: read it again
        assert "numba.cuda" not in sys.modules, "numba's cuda module was imported before the simulator was chosen"
        sys.modules["numba.core.config"].reload_config()

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

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
