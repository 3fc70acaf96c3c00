"""The docs check (tests/docs_check.py): how it reads the docs, and its quick part, which make test runs.

The whole check (every line run in a scratch folder) is ``make docs-check``, run by ``.ci/run``; here every line
of every file is parsed by the command line's own parser, and every script the docs name runs with ``--help``.
"""

from __future__ import annotations

import io
import subprocess
import sys

import pytest

from tests import docs_check
from tests.docs_check import ROOT, Line, named_scripts, shell_lines, skip_reason, smaller

DOC = """\
Text with `flexvox inline` that is not run.

```sh
flexvox design --tile 4x4 -o code.json   # a comment
# a comment alone
flexvox simulate drummer \\
    -o rec.zarr
flexvox app   # the window [needs a display]
```

```console
$ flexvox scenes
drummer ...
```

```toml
seed = 0
```
"""


def test_the_lines_of_shell_blocks_are_read_in_order_with_continuations(tmp_path):
    doc = tmp_path / "d.md"
    doc.write_text(DOC)
    lines = shell_lines(doc)
    assert [(ln.number, ln.command) for ln in lines] == [
        (4, "flexvox design --tile 4x4 -o code.json"), (6, "flexvox simulate drummer  -o rec.zarr"),
        (8, "flexvox app"), (12, "flexvox scenes")]
    assert [skip_reason(ln) for ln in lines] == [None, None, "needs a display", None]


def test_lines_that_run_this_check_are_skipped_and_sizes_shrink_where_a_flag_allows():
    assert skip_reason(Line(ROOT / "README.md", 1, "make test   # every test")) is not None
    assert smaller("flexvox simulate drummer -o rec.zarr") == "flexvox simulate drummer -o rec.zarr --size 48x64 " \
                                                             "--frames 4"
    assert smaller("flexvox simulate gt.npy -o rec.zarr") == "flexvox simulate gt.npy -o rec.zarr"  # a file's size
    assert smaller("flexvox capture --rig mock --frames 300 -o r.zarr") == \
        "flexvox capture --rig mock --frames 32 -o r.zarr --clock virtual"
    assert smaller("flexvox capture --rig lab.toml -o r.zarr") == "flexvox capture --rig lab.toml -o r.zarr"
    assert smaller("flexvox bench -o DIR") == "flexvox bench -o DIR --quick"


def test_a_failing_line_fails_the_check(tmp_path):
    doc = tmp_path / "d.md"
    doc.write_text("```sh\nflexvox design --tile 4x4 -o code.json\nflexvox design --tile 4x4 -o code.json\n```\n")
    out = io.StringIO()
    outcomes = docs_check.run_file(doc, tmp_path / "scratch", docs_check._shims(tmp_path / "bin"), out=out)
    assert [o.status for o in outcomes] == ["ok", "FAILED"]  # the second is refused: code.json already exists
    assert "code.json already exists" in outcomes[1].detail and "FAILED" in out.getvalue()


def test_every_documented_line_parses(tmp_path):
    """The quick part: an option renamed or removed, or a line that is not a command, fails here."""
    out = io.StringIO()
    bin_dir = docs_check._shims(tmp_path / "bin")
    outcomes = [o for doc in docs_check.documents() for o in docs_check.run_file(doc, tmp_path / doc.stem, bin_dir,
                                                                                 out=out, quick=True)]
    failed = [f"{o.line.where}: {o.detail}" for o in outcomes if o.status == "FAILED"]
    assert not failed, failed
    assert sum(o.status == "ok" for o in outcomes) >= 40


@pytest.mark.parametrize("script", named_scripts(), ids=lambda p: p.name)
def test_every_script_the_docs_name_runs_with_help(script):
    command = ["bash", str(script)] if script.suffix == ".sh" else [sys.executable, "-m", f"{script.parent.name}."
                                                                     f"{script.stem}"]
    if script.parent.name == "docs":
        command = [sys.executable, str(script)]
    proc = subprocess.run([*command, "--help"], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**docs_check._environment(ROOT / ".no-bin"), "NUMBA_ENABLE_CUDASIM": "1"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "usage" in proc.stdout.lower() or script.suffix == ".sh", proc.stdout[:500]
    assert proc.stdout.strip()


def test_the_quality_figure_is_not_replaced_by_a_partial_one_without_the_sci_data(monkeypatch, capsys):
    from bench import make_quality_figure

    figure = ROOT / make_quality_figure.DEFAULT_OUT
    before = figure.read_bytes()
    monkeypatch.setattr(make_quality_figure, "sci_data_dir", lambda: None)
    monkeypatch.chdir(ROOT)
    assert make_quality_figure.main(["--overwrite", "--repeats", "1"]) == 2
    err = capsys.readouterr().err
    assert "no SCI benchmark data for runner, drop" in err and "write another one with -o FILE.png" in err
    assert figure.read_bytes() == before


def test_the_guide_becomes_a_notebook_of_its_runnable_blocks_in_order():
    """``make docs-check`` runs this notebook in a Jupyter kernel (docs_check.run_guide_notebook); here only its
    making is checked (no kernel). nbformat comes with the ``docs`` extra (``make docs`` installs it)."""
    pytest.importorskip("nbformat", reason="the docs extra is not installed (make docs installs it)")
    from tests.docs.guide_blocks import python_blocks, skipped

    notebook = docs_check.guide_notebook()
    code = [c for c in notebook.cells if c.cell_type == "code"]
    runnable = [(line, src) for line, src in python_blocks(docs_check.GUIDE) if not skipped(src)]
    assert [c.metadata["guide_line"] for c in code] == [line for line, _ in runnable]
    assert [c.source for c in code] == [src.rstrip("\n") for _, src in runnable]
    assert notebook.metadata["kernelspec"]["name"] == "python3" and len(code) >= 10
    assert docs_check.ADDRESS.search("<Thing object at 0x7f3a2b1c9d00>") and not docs_check.ADDRESS.search("0x10")
