"""The docstring examples of ``flexvox_app`` and ``flexvox_calibration``, run under their installed names.

``flexvox_core`` and ``rig_drivers`` install under their folders' names, so pytest collects their examples itself
(``--doctest-modules`` over ``testpaths``). ``app/`` and ``calibration/`` install as ``flexvox_app`` and
``flexvox_calibration``: collected by folder, each module would load a second time as ``app.…``. Here every
module whose source holds an example is imported by its installed name and its examples run (with ``ELLIPSIS``
and ``NORMALIZE_WHITESPACE``).
"""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"app": "flexvox_app", "calibration": "flexvox_calibration"}


def _modules_with_examples() -> list[str]:
    names = []
    for folder, package in PACKAGES.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            if ">>> " not in path.read_text(encoding="utf-8"):
                continue
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            names.append(".".join((package, *parts)))
    return names


MODULES = _modules_with_examples()


def test_the_packages_have_examples_to_run():
    assert len(MODULES) >= 5, MODULES  # the GUI's models and the calibration façade hold examples


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    tests = [t for t in doctest.DocTestFinder().find(module, name) if t.examples]
    assert tests, f"{name} holds '>>> ' but no docstring example was found"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples in {name} failed (printed above)"
