"""Shared fixtures: simulated calibration rigs (virtual clock: nothing sleeps)."""

import pytest

from flexvox_calibration.homography import calibrate_homography
from flexvox_calibration.session import RigSession
from tests.rig_drivers.mock_rigs import calibration_rig

SEEDS = (0, 1, 2)


@pytest.fixture(scope="session")
def calibrated():
    """For each seed: (rig, homography result) on the rig with noise, defocus and ambient declared."""
    out = {}
    for seed in SEEDS:
        rig = calibration_rig(seed)
        with RigSession.from_rig(rig) as session:
            out[seed] = (rig, calibrate_homography(session))
    return out
