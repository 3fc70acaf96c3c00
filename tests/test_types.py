"""The type checker: mypy, strict on the rig's device contracts and on flexvox_core (pyproject.toml's [tool.mypy]).

The modules not yet strict are listed there, in two relaxations; the lists may only shrink (napari's ratchet).
"""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

AT_MOST = {"ignore_errors": 33, "disallow_untyped_defs": 55}
"""How many modules each relaxation held when it was made ("not yet checked": ignore_errors; "not yet strict":
the strict flags off). Taking a module off a list: lower its number here too. Never raise one."""


def relaxations() -> dict[str, list[str]]:
    """The modules of each relaxation, by the flag that names it."""
    overrides = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]["overrides"]
    out = {}
    for flag in AT_MOST:
        (section,) = [o for o in overrides if flag in o]
        out[flag] = list(section["module"])
    return out


def test_the_relaxations_only_shrink_and_name_modules_that_exist():
    for flag, modules in relaxations().items():
        assert len(modules) <= AT_MOST[flag], f"the {flag} relaxation grew to {len(modules)} modules " \
                                              f"(at most {AT_MOST[flag]}): type the new module instead"
        assert modules == sorted(set(modules)), f"the {flag} relaxation's modules are not sorted and unique"
        for module in modules:
            path = ROOT / module.replace(".", "/")
            assert path.with_suffix(".py").is_file() or (path / "__init__.py").is_file(), \
                f"{module} (in the {flag} relaxation) is no module: take it off the list"


@pytest.mark.parametrize("module", [
    "rig_drivers.interfaces",
    "flexvox_core.motion.stages",
])
def test_the_protocols_are_strict(module):
    relaxed = {m for modules in relaxations().values() for m in modules}
    assert module not in relaxed


def test_mypy_passes():
    run = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Success: no issues found" in run.stdout
