"""Every motion-aware option, one at a time, on the CPU and on the GPU under numba-cuda's simulator: the same
video within :data:`~tests.flexvox_core.gpu.parity_cases.TOLERANCE`, or the run on the CPU with a note saying why
(:mod:`tests.flexvox_core.gpu.parity_cases`). Each option's case first shows that the option changes the CPU's
video. A field added to MotionOptions without a plan field (``stages.OPTION_PLAN``) or a parity case fails here."""

import dataclasses
import inspect

import pytest

from flexvox_core.motion.options import MotionOptions
from tests.flexvox_core.gpu.parity_cases import FIELD_VALUES, ROUTES, TOLERANCE, case_ids, run_case

ROUTED = {"flow='farneback'", "flow_consistency=True", "multiplexed"}
"""The cases the GPU hands to the CPU, saying why."""


def test_every_option_has_a_plan_field_and_a_parity_case():
    """Each field of MotionOptions reaches the engines through a member of Window (``OPTION_PLAN``) and has a case
    with a value other than its default; the engines read the options through the window alone."""
    from flexvox_core.motion import stages
    from flexvox_core.motion.gpu import engine

    fields = {f.name for f in dataclasses.fields(MotionOptions)}
    assert set(stages.OPTION_PLAN) == fields
    window = {f.name for f in dataclasses.fields(stages.Window)} | {n for n, _ in inspect.getmembers(stages.Window)}
    for name, members in stages.OPTION_PLAN.items():
        assert members and set(members) <= window, (name, members)
    assert set(FIELD_VALUES) == fields
    for name, value in FIELD_VALUES.items():
        assert MotionOptions(**{name: value}) != MotionOptions(), name
    assert set(ROUTES) == {"defaults", "dropped frame", "kept sub-frames", "multiplexed", "DIS on the card"}
    for code in (stages.CpuStages, stages.run_stages, engine.CudaStages):
        assert ".options" not in inspect.getsource(code), code


@pytest.mark.parametrize("case", case_ids())
def test_the_gpu_gives_the_cpus_video_or_says_why_not(case):
    diff, note = run_case(case)
    if note is None:
        assert diff <= TOLERANCE, f"{case}: max |CPU - GPU| = {diff:.2e} > {TOLERANCE:g}"
    else:
        assert "runs on the CPU" in note
    assert (note is not None) == (case in ROUTED), (case, note)
