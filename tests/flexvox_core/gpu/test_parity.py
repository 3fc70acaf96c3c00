"""Every motion-aware option, one at a time, on the CPU and on the GPU under numba-cuda's simulator: the same
video within :data:`~tests.flexvox_core.gpu.parity_cases.TOLERANCE`, or the run on the CPU with a note saying why
(:mod:`tests.flexvox_core.gpu.parity_cases`). A field added to MotionOptions without a case fails here."""

import dataclasses

import pytest

from flexvox_core.motion.options import MotionOptions
from tests.flexvox_core.gpu.parity_cases import FIELD_VALUES, ROUTES, TOLERANCE, case_ids, run_case

FAST = {"flow='farneback'", "flow_consistency=True", "defaults", "multiplexed"}
"""The cases that stay in the quick run: the two routed to the CPU, the defaults and the multiplexed route; the
rest (a whole GPU run each, 10-25 s under the simulator on one core) are marked ``slow_sim``."""


def test_every_option_has_a_parity_case():
    """Each field of MotionOptions has a case with a value other than its default (a new field without one fails)."""
    fields = {f.name: f.default for f in dataclasses.fields(MotionOptions)}
    assert set(FIELD_VALUES) == set(fields)
    for name, value in FIELD_VALUES.items():
        assert MotionOptions(**{name: value}) != MotionOptions(), name
    assert set(ROUTES) == {"defaults", "dropped frame", "kept sub-frames", "multiplexed"}
    assert "passes=2" in case_ids()  # two passes


@pytest.mark.parametrize("case", [pytest.param(c, marks=() if c in FAST else pytest.mark.slow_sim)
                                  for c in case_ids()])
def test_the_gpu_gives_the_cpus_video_or_says_why_not(case):
    diff, note = run_case(case)
    if note is None:
        assert diff <= TOLERANCE, f"{case}: max |CPU - GPU| = {diff:.2e} > {TOLERANCE:g}"
    else:
        assert "runs on the CPU" in note
    routed = {"flow='farneback'", "flow_consistency=True", "multiplexed"}
    assert (note is not None) == (case in routed), (case, note)
