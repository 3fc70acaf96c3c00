"""Every script in examples/ runs at tiny sizes (FLEXVOX_EXAMPLE_TINY=1) in a scratch folder."""

import runpy
import sys

import pytest

from tests.docs.guide_blocks import ROOT

EXAMPLES = ROOT / "examples"
SCRIPTS = sorted(p.name for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))


def test_there_are_at_least_five_and_the_readme_lists_each():
    readme = (EXAMPLES / "README.md").read_text(encoding="utf-8")
    assert len(SCRIPTS) >= 5
    assert [s for s in SCRIPTS if f"`{s}`" not in readme] == []


@pytest.mark.parametrize("script", SCRIPTS)
def test_example_runs(script, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("FLEXVOX_EXAMPLE_TINY", "1")
    monkeypatch.setattr(sys, "argv", [script])
    monkeypatch.syspath_prepend(str(EXAMPLES))
    sys.modules.pop("_sample", None)  # read FLEXVOX_EXAMPLE_TINY afresh
    runpy.run_path(str(EXAMPLES / script), run_name="__main__")
    out = capsys.readouterr().out
    assert out.strip(), f"{script} printed nothing"
    assert "Traceback" not in out
