"""The numpy cap that keeps numba-cuda working, and the test that says when it can go (docs/dependencies.md).

numba-cuda up to :data:`flexvox_core.gpu.device.NUMBA_CUDA_CHECKED` fails with numpy 2.5 and newer, which pip
installs on Python 3.12 and 3.13. pyproject.toml's ``gpu`` and ``test`` extras cap numpy below
:data:`~flexvox_core.gpu.device.NUMPY_LIMIT`, and the device check refuses a stack without the cap in one line.
"""

import re
import tomllib
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

from flexvox_core.gpu import device

ROOT = Path(__file__).resolve().parents[1]
LIMIT = ".".join(map(str, device.NUMPY_LIMIT))


def _extras() -> dict[str, list[str]]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]


@pytest.mark.parametrize("extra", ["gpu", "test"])
def test_every_extra_with_numba_cuda_caps_numpy_where_the_device_check_says(extra):
    requirements = _extras()[extra]
    assert any(r.startswith("numba-cuda") for r in requirements)
    assert f"numpy<{LIMIT}" in requirements


def test_the_core_keeps_numpy_open():
    """Only the GPU stack needs the cap: `pip install flexvox` alone takes the newest numpy."""
    text = (ROOT / "pyproject.toml").read_text()
    core = tomllib.loads(text)["project"]["dependencies"]
    assert [r for r in core if r.startswith("numpy")] == ["numpy>=1.26"]


def test_the_installed_numpy_is_below_the_cap():
    assert device._version(np.__version__)[:2] < device.NUMPY_LIMIT
    assert device.stack_problem() is None


def test_the_numpy_cap_is_checked_against_the_installed_numba_cuda():
    """Fails once a numba-cuda newer than the last one checked is installed: then try it with numpy 2.5
    (`make test PYTHON=python3.13` with the cap lifted from pyproject.toml's gpu and test extras) and either lift
    the cap (and delete NUMPY_LIMIT's check) or move NUMBA_CUDA_CHECKED to the new version."""
    installed = metadata.version("numba-cuda")
    checked = ".".join(map(str, device.NUMBA_CUDA_CHECKED))
    assert device._version(installed) <= device.NUMBA_CUDA_CHECKED, (
        f"numba-cuda {installed} is newer than {checked}, the last checked against numpy {LIMIT}: see this test's "
        "docstring")


@pytest.mark.parametrize("numpy_version, numba_cuda, broken", [
    ("2.5.0", "0.30.4", True), ("2.5.5", "0.30.4", True), ("2.6.0rc1", "0.29.0", True),
    ("2.4.6", "0.30.4", False), ("1.26.4", "0.30.4", False), ("2.5.0", "0.31.0", False),
])
def test_stack_problem_names_both_versions_and_the_fix(numpy_version, numba_cuda, broken):
    problem = device.stack_problem(numpy_version, numba_cuda)
    if broken:
        assert problem == (f"numba-cuda {numba_cuda} does not work with numpy {numpy_version} (numpy {LIMIT} and "
                           f"newer); pip install 'numpy<{LIMIT}' (or pip install '.[gpu]' in a clone of flexvox, "
                           "which caps it)")
    else:
        assert problem is None


def test_cuda_asked_for_on_a_broken_stack_raises_the_one_line(monkeypatch):
    monkeypatch.setattr(device, "stack_problem", lambda: "numba-cuda 0.30.4 does not work with numpy 2.5.0 (…)")
    assert device.cuda_status() == (False, "numba-cuda 0.30.4 does not work with numpy 2.5.0 (…)")
    with pytest.raises(device.DeviceUnavailable, match=re.escape("device='cuda': numba-cuda 0.30.4 does not work")):
        device.resolve_device("cuda")
    assert device.resolve_device("auto") == "cpu"


@pytest.mark.parametrize("text, parts", [("2.4.6", (2, 4, 6)), ("2.5.0rc1", (2, 5, 0)), ("0.30.4.dev0", (0, 30, 4)),
                                         ("13", (13,))])
def test_version_parts(text, parts):
    assert device._version(text) == parts
