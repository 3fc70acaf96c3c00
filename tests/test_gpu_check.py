"""bench/gpu_check.sh against the GPU machine's image, without building its venv (`make gpu-dry-run` does that).

The image (bench/image_packages.txt) has no zarr, dask, distributed, pyusb, pyserial or opencv-contrib; the check
carries numpy and flexvox's own wheel and nothing else. These tests keep the script, its carry list, the image's
list and docs/gpu.md in agreement, and run the check's Python entry points with the absent packages blocked
(bench/gpu_dry/sitecustomize.py's finder) under numba-cuda's simulator.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = (ROOT / "bench" / "gpu_check.sh").read_text()
# What the image lacks, as import names (pyusb: usb, pyserial: serial); opencv-contrib's cv2.optflow is checked apart.
ABSENT = {"zarr", "numcodecs", "dask", "distributed", "usb", "serial", "PySide6", "pyqtgraph", "napari",
          "harvesters", "genicam", "ome_zarr_models"}


def carried() -> list[str]:
    """The script's CARRIED wheels, as ``name==version``."""
    return re.search(r"^CARRIED=\(([^)]*)\)", SCRIPT, re.M).group(1).split()


def image_packages() -> set[str]:
    lines = (ROOT / "bench" / "image_packages.txt").read_text().splitlines()
    return {line.split("#")[0].strip() for line in lines if line.split("#")[0].strip()}


def blocked_env() -> dict[str, str]:
    return {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "GPU_CHECK_ABSENT": ",".join(sorted(ABSENT)),
            "PYTHONPATH": os.pathsep.join([str(ROOT / "bench" / "gpu_dry"), str(ROOT)])}


def test_the_script_blocks_what_the_image_lacks():
    listed = set(re.search(r"^ABSENT=(\S+)", SCRIPT, re.M).group(1).split(","))
    assert listed == ABSENT


def test_carried_wheels_are_pinned_and_not_the_images_except_numpy():
    wheels = carried()
    assert wheels == ["numpy==2.4.6"], wheels  # numpy over the image's 2.5, which breaks its numba-cuda
    names = {w.split("==")[0] for w in wheels}
    assert names - image_packages() == set()  # numpy is the image's too: carried for its version alone
    assert not names & ABSENT


def test_the_image_list_names_none_of_what_it_lacks():
    assert not {p.replace("-", "_").lower() for p in image_packages()} & {a.lower() for a in ABSENT}
    assert "opencv-python-headless" in image_packages()
    assert not any("contrib" in p for p in image_packages())


def test_docs_name_every_carried_wheel():
    text = (ROOT / "docs" / "gpu.md").read_text()
    section = text[text.index("## The dry run"):]
    section = section[: section.find("\n## ", 4) if "\n## " in section[4:] else None]
    for wheel in carried():
        assert wheel.replace("==", "-") in section or wheel.replace("==", " ") in section, wheel
    assert "flexvox-0.1.0-py3-none-any.whl" in section


def test_the_blocker_refuses_an_absent_package():
    done = subprocess.run([sys.executable, "-c", "import zarr.storage"], env=blocked_env(), capture_output=True,
                          text=True)
    assert done.returncode == 1
    assert "No module named 'zarr' (absent from the GPU machine's image)" in done.stderr


ENTRY = """
import importlib, sys
import numpy as np
for name in ("bench.bench_gpu", "bench.gpu_rows", "bench.bench_live_preview", "bench.bench_cpu_scaling",
             "flexvox_app.accuracy_bench", "flexvox_app.capture.live_preview", "flexvox_core.methods",
             "flexvox_core.motion.streaming", "flexvox_core.motion.gpu.engine", "flexvox_core.gpu.diffusion",
             "flexvox_core.simulate.sources", "tests.flexvox_core.gpu.conftest"):
    importlib.import_module(name)
from flexvox_core.design import design_code
from flexvox_core.gpu.diffusion import diffuse_on_gpu
code = design_code((2, 2)).code
frames = np.random.default_rng(0).random((1, 4, 4), dtype=np.float32)
video = diffuse_on_gpu(frames, code, tensor=(1.0, 1.0, 1.0), time=1.0)
import cv2
print("ran", video.shape, "optflow" if hasattr(cv2, "optflow") else "no optflow")
"""


def test_the_checks_entry_points_import_nothing_the_image_lacks():
    done = subprocess.run([sys.executable, "-c", ENTRY], env=blocked_env(), capture_output=True, text=True,
                          cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith("ran (4, 4, 4)")


@pytest.mark.slow_sim
def test_the_check_runs_small_with_the_image_lacking_its_packages(tmp_path):
    """gpu_check.sh's tests, engine, rows and preview stages at tiny sizes under the simulator, with this venv's
    packages but what the image lacks blocked (the script blocks them itself with GPU_CHECK_SMALL=1)."""
    env = {**os.environ, "PYTHON": sys.executable, "OUT": str(tmp_path), "GPU_CHECK_SMALL": "1",
           "GPU_CHECK_ONLY": "tests,engine,rows,preview", "FLEXVOX_DATA": str(tmp_path / "none")}
    done = subprocess.run(["bash", str(ROOT / "bench" / "gpu_check.sh")], env=env, capture_output=True, text=True,
                          cwd=ROOT)
    stages = (tmp_path / "stages.txt").read_text().split("\n")
    assert [s.split()[:2] for s in stages if s] == [["tests", "0"], ["engine", "0"], ["rows", "0"],
                                                         ["preview", "0"]], done.stdout
    assert done.returncode == 0
