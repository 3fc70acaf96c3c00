import os
import sys

import pytest

if os.environ.get("FLEXVOX_TEST_GPU") != "1":
    os.environ.setdefault("NUMBA_ENABLE_CUDASIM", "1")
    if "numba" in sys.modules:  # napari's pytest plugin imports numba before any conftest: read the variable again
        import numba.core.config

        numba.core.config.reload_config()

pytest.importorskip("numba_cuda")


def pytest_configure(config):
    config.addinivalue_line("markers", "gpu: needs a real GPU (runs only with FLEXVOX_TEST_GPU=1)")


def pytest_collection_modifyitems(config, items):
    if os.environ.get("FLEXVOX_TEST_GPU") == "1":
        return
    skip = pytest.mark.skip(reason="needs a real GPU: set FLEXVOX_TEST_GPU=1")
    for item in items:
        if item.get_closest_marker("gpu") is not None:
            item.add_marker(skip)
