"""Every public name has a docstring and an example; the examples in docstrings run.

Public: ``flexvox_core.__all__`` (listed once in flexvox_core/__init__.pyi) and the façades' ``__all__``
(rig_drivers, flexvox_calibration). An example is an ``Examples`` section (doctest) in the name's
docstring, or a use in docs/python.md, whose blocks run as tests. Constants and submodules need neither.
"""

import doctest
import importlib
import inspect
import re
import types

import pytest

from tests.docs.guide_blocks import ROOT

FACADES = ["flexvox_core", "rig_drivers", "flexvox_calibration"]
GUIDE = (ROOT / "docs" / "python.md").read_text(encoding="utf-8")


def public():
    for package in FACADES:
        mod = importlib.import_module(package)
        for name in mod.__all__:
            obj = getattr(mod, name)
            if isinstance(obj, types.ModuleType) or not (inspect.isclass(obj) or callable(obj)):
                continue  # submodules, constants (their docs live in the module)
            yield package, name, obj


PUBLIC = list(public())


def test_every_package_lists_its_public_names():
    import flexvox_core

    assert {"design_code", "simulate_video", "reconstruct_video", "psnr", "open_recording"} <= set(
        flexvox_core.__all__)
    for package in FACADES:
        mod = importlib.import_module(package)
        assert all(hasattr(mod, n) for n in mod.__all__), package


@pytest.mark.parametrize(("package", "name", "obj"), PUBLIC, ids=[f"{p}.{n}" for p, n, _ in PUBLIC])
def test_public_name_has_a_docstring_and_an_example(package, name, obj):
    doc = inspect.getdoc(obj) or ""
    assert len(doc.strip()) > 20, f"{package}.{name} has no docstring"
    in_guide = re.search(rf"\b{re.escape(name)}\b", GUIDE) is not None
    assert ">>>" in doc or in_guide, f"{package}.{name}: no example (an Examples section, or a use in docs/python.md)"


@pytest.mark.parametrize(("package", "name", "obj"), PUBLIC, ids=[f"{p}.{n}" for p, n, _ in PUBLIC])
def test_docstring_examples_run(package, name, obj, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    finder = doctest.DocTestFinder(recurse=False)
    globs = dict(vars(inspect.getmodule(obj) or importlib.import_module(package)))
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(obj, name, globs=globs):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{package}.{name}: {result.failed} docstring example(s) failed"


def test_reconstruct_video_shows_a_tqdm_bar_when_asked(capsys):
    import numpy as np

    import flexvox_core as fv

    code = fv.code_from_order(fv.sequential_order((2, 2)))
    frames = fv.capture(fv.render_scene("balls", 16, 12, 12), code)
    plain = fv.reconstruct_video(frames, code, fv.Method("diffusion"), chunk_frames=2)
    assert capsys.readouterr().err == ""
    shown = fv.reconstruct_video(frames, code, fv.Method("diffusion"), chunk_frames=2, progress=True)
    assert "reconstruct" in capsys.readouterr().err  # tqdm writes to stderr outside Jupyter
    np.testing.assert_array_equal(shown, plain)
