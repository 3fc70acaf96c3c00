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
    from flexvox_core.video_api import reconstruct_video

    code = design_code((4, 4)).code
    frames = np.zeros((400, 240, 320), np.float32)  # 400 frames -> 6400 sub-frames of 240x320: 2 GiB out
    with pytest.raises(MemoryBudgetError, match=r"reconstructing 400 frames of 240x320 at K = 16 in memory .*"
                                                 r"`flexvox batch`"):
        reconstruct_video(frames, code)
    assert reconstruct_video(frames[:4, :24, :32], code).shape == (64, 24, 32)


def _sparse_npy(path, shape, descr="|u1"):
    """A .npy whose header declares ``shape``; its data is a hole in the file (no disk, nothing to read)."""
    from numpy.lib import format as npy_format

    with open(path, "wb") as fh:
        npy_format.write_array_header_1_0(fh, {"descr": descr, "fortran_order": False, "shape": shape})
        fh.truncate(fh.tell() + int(np.prod(shape)) * np.dtype(descr).itemsize)


def test_a_video_file_too_large_to_read_is_refused_from_its_header(small_machine, tmp_path, monkeypatch):
    from flexvox_core.simulate.sources import load_video

    _sparse_npy(tmp_path / "big.npy", (64, 1024, 1024))  # 64 MiB stored, 256 MiB as float32: fits
    _sparse_npy(tmp_path / "huge.npy", (256, 2048, 2048))  # 1 GiB stored, 4 GiB as float32
    assert load_video(tmp_path / "big.npy").shape == (64, 1024, 1024)
    monkeypatch.setattr(np, "load", lambda *a, **k: pytest.fail("the pixels were read"))
    with pytest.raises(MemoryBudgetError, match=r"huge.npy: reading its 256x2048x2048 uint8 samples as a float32 "
                                                 r"video needs about 6.0 GiB of memory; this machine has 1.0 GiB "
                                                 r"available: cut it to fewer or smaller frames$"):
        load_video(tmp_path / "huge.npy")


@pytest.mark.parametrize("given, mib", [(False, 56), (True, 40)], ids=["read-by-simulate", "read-by-the-caller"])
def test_a_video_file_whose_simulation_would_not_fit_is_refused(tmp_path, monkeypatch, given, mib):
    """Read by simulate: refused from the header, for all it needs (56 MiB); read by the caller (the command line):
    refused before the simulation's working copies, for what it needs beyond the video already read (40 MiB)."""
    from flexvox_core.simulate import simulator
    from flexvox_core.simulate.scene_file import SceneSpec
    from flexvox_core.simulate.sources import load_video

    np.save(tmp_path / "clip.npy", np.zeros((64, 256, 256), np.float32))  # 16 MiB: 16 frames at K = 4
    video = load_video(tmp_path / "clip.npy") if given else None
    monkeypatch.setattr(memory_budget, "available_bytes", lambda: 30 * 1024 ** 2)  # reads (20 MiB), cannot simulate
    monkeypatch.setattr(simulator, "load_video", lambda *a: pytest.fail("read before the check"))
    monkeypatch.setattr(simulator, "simulate_video", lambda *a, **k: pytest.fail("simulated before the check"))
    spec = SceneSpec(builtin=None, file=tmp_path / "clip.npy", frames=None, name="clip", tile=(2, 2))
    with pytest.raises(MemoryBudgetError, match=rf"^simulating .*clip.npy \(16 frames of 256x256 at K = 4\) needs "
                                                 rf"about {mib} MiB of memory; this machine has 30 MiB available: "
                                                 r"cut the video to fewer or smaller frames, or simulate fewer "
                                                 r"frames$"):
        simulator.simulate(spec, video=video)


def test_huge_shutter_patterns_are_refused(small_machine):
    from flexvox_calibration.shutter import make_shutter_patterns

    code = design_code((8, 8)).code
    with pytest.raises(MemoryBudgetError, match=r"^making shutter patterns for a 8192x8192 projector at K = 64 needs "
                                                 r"about 11.5 GiB of memory; .*check the projector size"):
        make_shutter_patterns(code, np.eye(3), (24, 32), (8192, 8192))


def test_the_simulated_rig_refuses_a_camera_too_large_to_render(small_machine):
    from rig_drivers.simulated_rig import SimulatedRig

    with pytest.raises(MemoryBudgetError, match=r"the drummer scene at 4096x4096 with 256 sub-frames needs about "
                                                 r"32.0 GiB .*: use a smaller camera size$"):
        SimulatedRig.create("drummer", camera_size=(4096, 4096))
