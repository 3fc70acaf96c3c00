"""pytest's settings for the whole repository, read before any test module or package module is imported.

`make test` runs the docstring examples of ``flexvox_core`` and ``rig_drivers`` beside ``tests/``
(``--doctest-modules``, ``testpaths`` in pyproject.toml); those of ``flexvox_app`` and ``flexvox_calibration``,
which install under names other than their folders', run from ``tests/test_doctests.py``. Collecting them
imports the ``flexvox_core.gpu`` modules too, so numba-cuda's simulator is chosen here, before anything imports
numba's cuda module.
"""

import os
import sys

# The GPU path's tests run under numba-cuda's simulator unless FLEXVOX_TEST_GPU=1 (bench/gpu_check.sh sets it on
# a machine with a GPU: then the same tests run on the card, and so do those marked `gpu`). Set before numba's
# cuda module is first imported, which reads it once.
if os.environ.get("FLEXVOX_TEST_GPU") != "1":
    os.environ["NUMBA_ENABLE_CUDASIM"] = "1"
    if "numba.core.config" in sys.modules:  # a pytest plugin (napari's) imported numba already: read it again
        assert "numba.cuda" not in sys.modules, "numba's cuda module was imported before the simulator was chosen"
        sys.modules["numba.core.config"].reload_config()

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
