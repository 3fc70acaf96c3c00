"""``--device`` on reconstruct, export and batch, and the GPUs ``flexvox devices`` lists.

The tests run numba-cuda's simulator in place of a GPU (conftest.py): ``--device cuda`` runs the GPU path
there on tiny recordings; ``auto`` never takes the simulator.
"""

import json

import pytest
import zarr

from flexvox_app.cli.main import main
from flexvox_app.cli.method_options import SIMULATOR

pytestmark = pytest.mark.recording(frames=2, size=(8, 12), tile=(2, 2), name="r.zarr")


def _provenance(path):
    return dict(zarr.open_group(str(path), mode="r").attrs["flexvox"])


def test_reconstruct_on_the_gpu_says_so_and_records_it(recording, tmp_path, capsys):
    out = tmp_path / "o.zarr"
    assert main(["reconstruct", str(recording), "--method", "diffusion", "--device", "cuda", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"device: cuda ({SIMULATOR})" in text.splitlines()  # the simulator, never taken for a GPU
    assert _provenance(out)["device"] == "cuda" and _provenance(out)["gpu"] == "numba-cuda's simulator"


def test_auto_takes_the_cpu_without_a_gpu(recording, tmp_path, capsys):
    out = tmp_path / "o.zarr"
    assert main(["reconstruct", str(recording), "--method", "diffusion", "-o", str(out)]) == 0
    assert "device: cpu" in capsys.readouterr().out.splitlines()
    assert _provenance(out)["device"] == "cpu"


@pytest.mark.parametrize("argv, reason", [
    (["--method", "rebin"], "rebin has no GPU path"),
    (["--method", "diffusion", "--solver", "explicit", "--time", "0.2"], "diffusion's explicit solver runs on the CPU"),
])
def test_a_method_without_a_gpu_path_runs_on_the_cpu_and_says_why(recording, tmp_path, capsys, argv, reason):
    out = tmp_path / "o.npy"
    assert main(["reconstruct", str(recording), *argv, "--device", "cuda", "-o", str(out)]) == 0
    assert f"device: cpu ({reason})" in capsys.readouterr().out.splitlines()


def test_cuda_asked_for_and_absent_exits_2_naming_what_is_missing(recording, tmp_path, capsys, monkeypatch):
    from flexvox_core.gpu import device

    monkeypatch.setattr(device, "cuda_status", lambda: (False, "no NVIDIA driver found (libcuda)"))
    for command in (["reconstruct", str(recording), "-o", str(tmp_path / "o.npy")],
                    ["export", str(recording), "--what", "reconstruction", "-o", str(tmp_path / "o.tif")],
                    ["batch", str(recording), "-o", str(tmp_path / "o.zarr")]):
        assert main([*command, "--device", "cuda"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.endswith("error: --device cuda: no NVIDIA driver found (libcuda)") and len(err.splitlines()) == 1
    assert not any(p.name.startswith("o.") for p in tmp_path.iterdir())


def test_export_and_batch_record_the_device(recording, tmp_path, capsys):
    tif = tmp_path / "o.tif"
    assert main(["export", str(recording), "--what", "reconstruction", "--method", "diffusion", "--device", "cuda",
                 "-o", str(tif)]) == 0
    assert f"device: cuda ({SIMULATOR})" in capsys.readouterr().out.splitlines()
    out = tmp_path / "b.zarr"
    assert main(["batch", str(recording), "--method", "diffusion", "--device", "cuda", "--chunk", "1",
                 "-o", str(out)]) == 0
    assert f"device: cuda ({SIMULATOR})" in capsys.readouterr().out.splitlines()
    assert _provenance(out)["device"] == "cuda"


def test_devices_lists_the_gpus_section(capsys):
    """Under the simulator no GPU is listed, and the reason says the simulator stands in."""
    assert main(["devices", "--json"]) == 0
    gpus = json.loads(capsys.readouterr().out)["gpus"]
    assert gpus["available"] is False and "simulator" in gpus["reason"]
    assert main(["devices"]) == 0
    assert "GPUs for reconstruction (--device cuda):" in capsys.readouterr().out


def test_devices_describes_a_gpu_by_name_memory_and_driver(monkeypatch):
    from flexvox_app.cli import devices
    from flexvox_core.gpu import device
    from flexvox_core.gpu.device import GpuInfo

    monkeypatch.setattr(device, "simulator", lambda: False)
    monkeypatch.setattr(device, "cuda_status", lambda: (True, "CUDA"))
    gpu = GpuInfo(0, "NVIDIA H100 80GB HBM3", (9, 0), 80 * 2**30, 79 * 2**30, "13.0")
    assert devices._gpus(lambda: [gpu]) == {
        "available": True, "reason": None,
        "devices": [{"name": "NVIDIA H100 80GB HBM3", "memory": "80.0 GiB", "compute_capability": "9.0",
                     "driver": "13.0"}]}
    monkeypatch.setattr(device, "cuda_status", lambda: (False, "no NVIDIA driver found (libcuda)"))
    assert devices._gpus() == {"available": False, "devices": [], "reason": "no NVIDIA driver found (libcuda)"}


BROKEN = "numba-cuda 0.30.4 does not work with numpy 2.5.0 (numpy 2.5 and newer)"


@pytest.fixture
def broken_stack(monkeypatch):
    """numpy 2.5 beside numba-cuda 0.30.4, as pip gives on Python 3.12 without the cap."""
    from flexvox_core.gpu import device

    real = device.stack_problem
    monkeypatch.setattr(device, "stack_problem", lambda: real("2.5.0", "0.30.4"))


def test_a_broken_gpu_stack_is_refused_in_one_line(recording, tmp_path, capsys, broken_stack):
    assert main(["reconstruct", str(recording), "--method", "diffusion", "--device", "cuda",
                 "-o", str(tmp_path / "o.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"error: --device cuda: {BROKEN}; pip install 'numpy<2.5'" in err
    assert main(["devices", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["gpus"]["reason"].startswith(BROKEN)


@pytest.fixture
def a_driver(monkeypatch):
    """A machine with an NVIDIA driver, the simulator off (auto's case)."""
    from flexvox_core.gpu import device

    monkeypatch.setattr(device, "simulator", lambda: False)
    monkeypatch.setattr(device, "driver_library", lambda: "libcuda.so.1")


def test_auto_on_a_broken_gpu_stack_takes_the_cpu_and_says_why(recording, tmp_path, capsys, caplog, broken_stack,
                                                               a_driver):
    with caplog.at_level("WARNING", logger="flexvox_core.gpu.device"):
        assert main(["reconstruct", str(recording), "--method", "diffusion", "-o", str(tmp_path / "o.npy")]) == 0
    assert "device: cpu" in capsys.readouterr().out.splitlines()
    assert [r.getMessage() for r in caplog.records if r.levelname == "WARNING"] == [
        f"device auto: the CPU, because {BROKEN}; pip install 'numpy<2.5' (or pip install '.[gpu]' in a clone of "
        "flexvox, which caps it)"]


def test_without_a_driver_a_broken_gpu_stack_is_not_mentioned(recording, tmp_path, capsys, caplog, broken_stack,
                                                               monkeypatch):
    """No driver: auto would take the CPU anyway, so nothing warns; --device cuda names the driver first."""
    from flexvox_core.gpu import device

    monkeypatch.setattr(device, "simulator", lambda: False)
    monkeypatch.setattr(device, "driver_library", lambda: None)
    with caplog.at_level("WARNING", logger="flexvox_core.gpu.device"):
        assert main(["reconstruct", str(recording), "--method", "diffusion", "-o", str(tmp_path / "o.npy")]) == 0
    assert not [r for r in caplog.records if r.levelname == "WARNING"]
    assert device.cuda_status() == (False, "no NVIDIA driver found (libcuda)")


def test_run_on_auto_with_a_broken_gpu_stack_notes_why_on_the_result(broken_stack, a_driver):
    """From Python the result itself says why the CPU ran (`MethodOutput.device_note`)."""
    import numpy as np

    import flexvox_core as fv

    code = fv.code_from_order([[0, 1], [2, 3]])
    frames = np.random.default_rng(0).random((2, 8, 8), dtype=np.float32)
    out = fv.run(frames, code, fv.Method("diffusion"), device="auto")
    assert out.device == "cpu" and out.device_note.startswith(BROKEN)
