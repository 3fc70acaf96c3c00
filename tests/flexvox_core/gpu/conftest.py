"""The GPU path's tests need numba-cuda (the ``test`` extra installs it); its simulator stands in for a GPU."""

import pytest

pytest.importorskip("numba_cuda", reason="numba-cuda is not installed (pip install '.[gpu]' in a clone of flexvox)")
