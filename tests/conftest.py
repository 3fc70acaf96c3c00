"""Shared test settings: seeded randomness, deterministic hypothesis, offscreen Qt."""

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

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
