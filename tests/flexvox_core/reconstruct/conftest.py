import numpy as np
import pytest

from flexvox_core.codes import code_from_order, sequential_order


@pytest.fixture(scope="session")
def code24():
    """The designed 2×4 code (supports every division of the tile)."""
    return code_from_order([[0, 5, 7, 2], [6, 3, 1, 4]])


@pytest.fixture(scope="session")
def code22():
    return code_from_order([[0, 3], [2, 1]])


@pytest.fixture(scope="session")
def seq22():
    return code_from_order(sequential_order((2, 2)))


def smooth_video(rng, S, H, W, dtype=np.float32):
    """A smooth random video in [0.1, 0.9] (a few low-frequency cosines)."""
    t, y, x = np.meshgrid(np.arange(S), np.arange(H), np.arange(W), indexing="ij")
    v = np.zeros((S, H, W))
    for _ in range(4):
        ft, fy, fx = rng.uniform(0, 0.15, 3)
        v += np.cos(2 * np.pi * (ft * t + fy * y + fx * x) + rng.uniform(0, 2 * np.pi))
    v = 0.5 + 0.4 * v / 4
    return v.astype(dtype)
