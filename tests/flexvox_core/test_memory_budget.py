"""Work that would not fit in memory is refused before anything is allocated."""

import numpy as np
import pytest

from flexvox_core import memory_budget
from flexvox_core.design import design_code
from flexvox_core.memory_budget import GIB, MemoryBudgetError, available_bytes, check_fits


@pytest.fixture
def small_machine(monkeypatch):
    """A machine with 1 GiB available."""
    monkeypatch.setattr(memory_budget, "available_bytes", lambda: 1 * GIB)


def test_available_memory_is_read():
    avail = available_bytes()
    assert avail is None or avail > 64 * 1024 ** 2


def test_check_fits_names_what_and_how_much(small_machine):
    check_fits(0.5 * GIB, "a job", "do less")
    with pytest.raises(MemoryBudgetError, match=r"^a job needs about 2.0 GiB of memory; this machine has 1.0 GiB "
                                                 r"available: do less$"):
        check_fits(2 * GIB, "a job", "do less")


def test_unknown_memory_refuses_nothing(monkeypatch):
    monkeypatch.setattr(memory_budget, "available_bytes", lambda: None)
    check_fits(1e30, "anything", "")


def test_a_huge_simulation_is_refused_before_rendering(small_machine, monkeypatch):
    from flexvox_core.simulate import simulator
    from flexvox_core.simulate.scene_file import SceneSpec

    rendered = []
    monkeypatch.setattr(simulator, "render_scene", lambda *a, **k: rendered.append(a))
    spec = SceneSpec(builtin="drummer", name="drummer", height=4000, width=4000, frames=8)
    with pytest.raises(MemoryBudgetError, match=r"simulating 4000x4000 with 8 frames of K = 16 needs about 23\.8 GiB"):
        simulator.simulate(spec)
    assert rendered == []


def test_a_huge_render_is_refused(small_machine):
    from flexvox_core.simulate.scenes import render_scene

    with pytest.raises(MemoryBudgetError, match=r"the drummer scene at 4000x4000 with 128 sub-frames needs about"):
        render_scene("drummer", 128, 4000, 4000)  # what the simulated rig renders at its camera size
    assert render_scene("drummer", 4, 16, 16).shape == (4, 16, 16)


def test_an_in_memory_reconstruction_too_large_points_to_batch(small_machine):
    from flexvox_core.methods import reconstruct

    code = design_code((4, 4)).code
    frames = np.zeros((400, 240, 320), np.float32)  # 400 frames -> 6400 sub-frames of 240x320: 2 GiB out
    with pytest.raises(MemoryBudgetError, match=r"reconstructing 400 frames of 240x320 at K = 16 in memory .*"
                                                 r"`flexvox batch`"):
        reconstruct(frames, code)
    assert reconstruct(frames[:4, :24, :32], code).shape == (64, 24, 32)
