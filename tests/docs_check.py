"""Run every shell line of the README and docs/*.md, in order, as typed, in a scratch folder.

    python -m tests.docs_check [--quick] [--keep DIR] [FILE.md ...]

Each Markdown file's fenced ``sh``/``bash``/``shell`` blocks, and the ``$ `` lines of its ``console`` blocks, run
in order in a fresh scratch folder of their own (so a file's blocks may use what its earlier lines made, and
never what another file's did), with ``flexvox`` and ``python`` meaning this checkout's code. The check prints
every line with what it did (ran, its exit status and seconds; skipped, and why) and exits 1 when a line
failed.

- **Skipped lines** say why in their own comment, for the reader too: ``[needs a display]``, ``[needs a GPU]``,
  ``[needs the rig]``, ``[needs a dask cluster]``, ``[needs the package index]``, ``[needs your own video]``.
  Lines that would run this check itself (``make test``, ``make test-full``, ``make docs-check``) are skipped
  with that reason.
- **Tiny sizes**: where a flag allows it the line runs smaller than typed, and the check prints the line as run
  (:data:`SMALLER`): built-in scenes at 48×64 with 4 frames, the simulated rig's capture on its virtual clock
  and at most 32 frames, ``bench`` and ``demo`` in their quick modes.
- ``make TARGET`` runs this checkout's Makefile with ``flexvox`` and ``python`` as above (no install).
- **The Python guide as a notebook**: after the shell lines, docs/python.md's runnable ``python`` blocks (those
  without a ``# needs ...`` first line) become the cells of a notebook that runs, in a scratch folder of its own,
  in a real Jupyter kernel (nbclient and ipykernel: the ``docs`` extra), so reprs, progress bars and the order of
  outputs are what a notebook shows. A cell that raises, or an output that prints a memory address
  (``object at 0x...``), fails the check; each cell's seconds are printed (``--notebook`` runs only this part;
  ``--keep`` keeps the run notebook as ``python-guide.ipynb``).
- ``--quick`` (``make test``, a few seconds): every line of every file is *parsed*, not run: a ``flexvox`` line by
  the command line's own parser (an option renamed or removed fails), a ``make`` line by ``make -n``. The whole
  run (``make docs-check``, and ``.ci/run``) took 29 minutes, 15 of them the README's, on a busy 2-core machine
  (docs/benchmarks.md, "Wall times").
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHELLS = ("sh", "bash", "shell", "console")
BUILTIN_SCENES = ("fan", "balls", "drummer", "pan", "static", "strobe")
NEEDS = re.compile(r"\[needs ([^\]]+)\]")
RUNS_THIS_CHECK = {
    "make test": "make test runs this check (its quick part)",
    "make test-full": "make test-full runs this check",
    "make docs-check": "this is the docs check",
}
LINE_TIMEOUT_S = 900
CAPTURE_FRAMES = 32
"""The most frames a simulated capture records here (two camera frames per sub-frame slot of a 4x4 code)."""


@dataclass(frozen=True)
class Line:
    """One shell line of a Markdown file."""

    file: Path
    number: int
    text: str
    """The command as typed (continuations joined), without the ``$ `` prompt."""

    @property
    def command(self) -> str:
        """The text without its trailing comment."""
        return _strip_comment(self.text)

    @property
    def where(self) -> str:
        try:
            name = self.file.resolve().relative_to(ROOT)
        except ValueError:
            name = self.file
        return f"{name}:{self.number}"


def _strip_comment(text: str) -> str:
    """``text`` up to its first unquoted ``#`` that starts a word."""
    quote = None
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1].isspace()):
            return text[:i].rstrip()
    return text.rstrip()


def shell_lines(path: Path) -> list[Line]:
    """Every shell line of ``path``'s fenced shell blocks, in order (comment-only and blank lines left out)."""
    lines: list[Line] = []
    block = None
    pending = ""
    start = 0
    for number, raw in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
        fence = re.match(r"^\s*```\s*([\w-]*)", raw)
        if fence:
            block = (fence.group(1) or "none") if block is None else None
            continue
        if block not in SHELLS:
            continue
        text = raw.strip()
        if block == "console":
            if not (text.startswith("$ ") or pending):
                continue  # output
            text = text[2:] if text.startswith("$ ") else text
        if not pending:
            start = number
        if text.endswith("\\"):
            pending += text[:-1] + " "
            continue
        text, pending = pending + text, ""
        if _strip_comment(text):
            lines.append(Line(Path(path), start, text))
    return lines


def skip_reason(line: Line) -> str | None:
    """Why ``line`` is not run here, or None."""
    found = NEEDS.search(line.text[len(line.command):])
    if found:
        return f"needs {found.group(1)}"
    return RUNS_THIS_CHECK.get(" ".join(line.command.split()))


def _value(args: list[str], flag: str, default: str) -> str:
    """The value after ``flag`` in ``args``, or ``default``."""
    return args[args.index(flag) + 1] if flag in args[:-1] else default


def _add(args: list[str], flag: str, *values: str) -> list[str]:
    return args if flag in args else [*args, flag, *values]


def smaller(command: str) -> str:
    """``command`` as the check runs it: on tiny sizes where a flag allows it (:data:`SMALLER`)."""
    try:
        args = shlex.split(command)
    except ValueError:
        return command
    if len(args) < 2 or args[0] != "flexvox":
        return command
    sub = args[1]
    new = list(args)
    if sub == "simulate" and len(args) > 2 and args[2] in BUILTIN_SCENES:
        new = _add(_add(new, "--size", "48x64"), "--frames", "4")
    elif sub == "capture" and _value(args, "--rig", "mock") == "mock":
        new = _add(new, "--clock", "virtual")
    if sub == "capture" and _value(args, "--rig", "mock") == "mock" and "--frames" in new[:-1]:
        at = new.index("--frames") + 1
        if new[at].isdigit() and int(new[at]) > CAPTURE_FRAMES:
            new[at] = str(CAPTURE_FRAMES)
    elif sub in ("bench", "demo"):
        new = _add(new, "--quick")
    return command if new == args else shlex.join(new)


SMALLER = {
    "flexvox simulate <built-in scene>": "--size 48x64 --frames 4",
    "flexvox capture on the simulated rig": "--clock virtual (frames as fast as they are made, not in real time), "
                                            f"--frames at most {CAPTURE_FRAMES}",
    "flexvox bench, flexvox demo": "--quick",
}
"""What the check adds to a line, where the line does not say it already."""


def _shims(folder: Path) -> Path:
    """A bin folder whose ``flexvox`` and ``python`` run this checkout with this interpreter."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, body in (("flexvox", f'exec "{sys.executable}" -m flexvox_app.cli.main "$@"'),
                       ("python", f'exec "{sys.executable}" "$@"'), ("python3", f'exec "{sys.executable}" "$@"')):
        shim = folder / name
        shim.write_text(f"#!/bin/sh\n{body}\n")
        shim.chmod(0o755)
    return folder


def _environment(bin_dir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    env["QT_QPA_PLATFORM"] = "offscreen"
    env["MPLBACKEND"] = "Agg"
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    return env


def _as_run(command: str, bin_dir: Path) -> str:
    """The shell text run for ``command``: tiny sizes; ``make`` with this checkout's Makefile and no install."""
    args = shlex.split(command)
    if args and args[0] == "make":
        return shlex.join(["make", "-f", str(ROOT / "Makefile"), *args[1:], f"BIN={bin_dir}", "STAMP="])
    return smaller(command)


@dataclass
class Outcome:
    line: Line
    status: str
    """"ok", "FAILED" or "skipped"."""
    detail: str
    ran_as: str | None = None


def parse_only(command: str, bin_dir: Path) -> tuple[bool, str]:
    """``--quick``: whether ``command`` parses (the command line's parser; ``make -n``), and what was checked."""
    import contextlib
    import io

    args = shlex.split(command)
    if args[0] == "flexvox":
        from flexvox_app.cli.main import build_parser

        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                build_parser().parse_args(args[1:])
        except SystemExit as exc:
            if exc.code not in (0, None):
                return False, err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else str(exc)
        return True, "parsed by flexvox's parser (not run: --quick)"
    if args[0] == "make":
        proc = subprocess.run(["make", "-n", "-f", str(ROOT / "Makefile"), *args[1:], f"BIN={bin_dir}", "STAMP="],
                              capture_output=True, text=True, cwd=ROOT)
        return proc.returncode == 0, ("make -n knows the target (not run: --quick)" if proc.returncode == 0
                                      else proc.stderr.strip())
    return True, "not run: --quick"


def run_file(path: Path, scratch: Path, bin_dir: Path, out=sys.stdout, quick: bool = False) -> list[Outcome]:
    """Run ``path``'s shell lines in order in ``scratch`` (``quick``: parse them); print each with what it did."""
    scratch.mkdir(parents=True, exist_ok=True)
    env = _environment(bin_dir)
    outcomes = []
    for line in shell_lines(path):
        print(f"{line.where}: $ {line.text}", file=out, flush=True)
        reason = skip_reason(line)
        if reason:
            outcomes.append(Outcome(line, "skipped", reason))
            print(f"    skipped: {reason}", file=out, flush=True)
            continue
        if quick:
            ok, what = parse_only(line.command, bin_dir)
            outcomes.append(Outcome(line, "ok" if ok else "FAILED", what))
            print(f"    {'ok' if ok else 'FAILED'}: {what}", file=out, flush=True)
            continue
        run = _as_run(line.command, bin_dir)
        shown = smaller(line.command)
        if shown != line.command:
            print(f"    ran as: {shown}", file=out, flush=True)
        t0 = time.monotonic()
        try:
            proc = subprocess.run(["bash", "-c", run], cwd=scratch, env=env, capture_output=True, text=True,
                                  timeout=LINE_TIMEOUT_S, stdin=subprocess.DEVNULL)
            code, err = proc.returncode, proc.stderr
        except subprocess.TimeoutExpired:
            code, err = None, f"still running after {LINE_TIMEOUT_S} s"
        seconds = time.monotonic() - t0
        if code == 0:
            outcome = Outcome(line, "ok", f"exit 0, {seconds:.1f} s", shown if shown != line.command else None)
            print(f"    ok: {outcome.detail}", file=out, flush=True)
        else:
            last = [ln.split("\r")[-1] for ln in (err or "").splitlines() if ln.split("\r")[-1].strip()][-3:]
            status = "timed out" if code is None else f"exit {code}"
            outcome = Outcome(line, "FAILED", f"{status}, {seconds:.1f} s: " + " | ".join(last),
                              shown if shown != line.command else None)
            print(f"    FAILED: {outcome.detail}", file=out, flush=True)
        outcomes.append(outcome)
    return outcomes


def documents() -> list[Path]:
    """The README, then docs/*.md in name order."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def named_scripts() -> list[Path]:
    """The scripts of bench/ and docs/ that the README or docs/*.md name (as a path or as ``python -m bench.NAME``),
    sorted."""
    named = set()
    for doc in documents():
        text = doc.read_text(encoding="utf-8")
        named.update(m.group(1) for m in re.finditer(r"(?<![\w/.])((?:bench|docs)/[A-Za-z0-9_]+\.(?:py|sh))\b", text))
        named.update(f"bench/{m.group(1)}.py" for m in re.finditer(r"python -m bench\.([A-Za-z0-9_]+)", text))
    return sorted(ROOT / n for n in named)


GUIDE = ROOT / "docs" / "python.md"
ADDRESS = re.compile(r"\bat 0x[0-9a-fA-F]{6,}")
CELL_TIMEOUT_S = 900


def guide_notebook(page: Path = GUIDE):
    """docs/python.md's runnable ``python`` blocks as the cells of a notebook (nbformat v4), in order."""
    import nbformat

    from tests.docs.guide_blocks import python_blocks, skipped

    cells = [nbformat.v4.new_markdown_cell(f"Run from {page.relative_to(ROOT)} by tests/docs_check.py.")]
    for line, source in python_blocks(page):
        if not skipped(source):
            cells.append(nbformat.v4.new_code_cell(source.rstrip("\n"), metadata={"guide_line": line}))
    return nbformat.v4.new_notebook(cells=cells, metadata={"kernelspec": {
        "name": "python3", "display_name": "Python 3", "language": "python"}})


def _cell_text(cell) -> str:
    """Everything a code cell showed: its streams, results (plain text and HTML) and error."""
    parts = []
    for output in cell.get("outputs", []):
        parts.append(output.get("text", ""))
        data = output.get("data", {})
        parts += [data.get("text/plain", ""), data.get("text/html", "")]
        parts += output.get("traceback", [])
    return "\n".join(str(p) for p in parts)


def run_guide_notebook(scratch: Path, out=sys.stdout, keep: Path | None = None) -> list[str]:
    """Run :func:`guide_notebook` in a Jupyter kernel in ``scratch``; the problems found (none: it passed)."""
    try:
        import ipykernel  # noqa: F401 - the kernel nbclient starts
        import nbformat
        from nbclient import NotebookClient
        from nbclient.exceptions import CellExecutionError
    except ImportError as exc:
        return [f"docs/python.md as a notebook needs the docs extra ({exc.name} is missing): `make docs` installs it"]

    scratch.mkdir(parents=True, exist_ok=True)
    notebook = guide_notebook()
    client = NotebookClient(notebook, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                            resources={"metadata": {"path": str(scratch)}})
    problems, t0 = [], time.monotonic()
    print(f"\n== {GUIDE.relative_to(ROOT)} as a notebook ({len(notebook.cells) - 1} cells, a Jupyter kernel)",
          file=out, flush=True)
    with client.setup_kernel(env={**os.environ, "MPLBACKEND": "module://matplotlib_inline.backend_inline",
                                  "PYTHONPATH": str(ROOT)}):
        for index, cell in enumerate(notebook.cells):
            if cell.cell_type != "code":
                continue
            where = f"docs/python.md:{cell.metadata['guide_line']}"
            started = time.monotonic()
            try:
                client.execute_cell(cell, index)
            except CellExecutionError as exc:
                problems.append(f"{where}: the cell raised: {str(exc).strip().splitlines()[-1]}")
                print(f"  FAILED {where} ({time.monotonic() - started:.1f} s)", file=out, flush=True)
                break
            shown = _cell_text(cell)
            if ADDRESS.search(shown):
                problems.append(f"{where}: an output prints a memory address: {ADDRESS.search(shown).group(0)}")
            print(f"  ok     {where} ({time.monotonic() - started:.1f} s)", file=out, flush=True)
    print(f"  the guide's notebook: {len(problems)} problem(s), {time.monotonic() - t0:.0f} s", file=out, flush=True)
    if keep is not None:
        nbformat.write(notebook, str(keep / "python-guide.ipynb"))
    return problems


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path, help="Markdown files (default: README.md and docs/*.md)")
    ap.add_argument("--quick", action="store_true", help="parse every line, run none (what make test runs)")
    ap.add_argument("--keep", type=Path, help="the scratch folder, kept (default: a temporary one, removed)")
    ap.add_argument("--notebook", action="store_true", help="run only docs/python.md as a notebook in a kernel")
    args = ap.parse_args(argv)
    files = [f.resolve() for f in args.files] or documents()
    if args.keep is not None and args.keep.exists():
        ap.error(f"--keep {args.keep} already exists; name a new folder")
    top = args.keep.resolve() if args.keep else Path(tempfile.mkdtemp(prefix="flexvox-docs-check-"))
    t0 = time.monotonic()
    problems: list[str] = []
    try:
        bin_dir = _shims(top / ".bin")
        outcomes = []
        for f in files if not args.notebook else []:
            outcomes += run_file(f, top / f.stem, bin_dir, quick=args.quick)
        if args.notebook or not (args.quick or args.files):
            problems = run_guide_notebook(top / "python-guide", keep=top if args.keep else None)
    finally:
        if args.keep is None:
            shutil.rmtree(top, ignore_errors=True)
    counts = {s: sum(o.status == s for o in outcomes) for s in ("ok", "FAILED", "skipped")}
    done = "parsed ok (--quick: none run)" if args.quick else "ran ok"
    print(f"\n{len(outcomes)} shell lines in {len(files)} files: {counts['ok']} {done}, {counts['FAILED']} failed, "
          f"{counts['skipped']} skipped ({time.monotonic() - t0:.0f} s)")
    for o in outcomes:
        if o.status == "FAILED":
            print(f"FAILED {o.line.where}: {o.line.text}\n    {o.detail}")
    for problem in problems:
        print(f"FAILED {problem}")
    return 1 if counts["FAILED"] or problems else 0


if __name__ == "__main__":
    sys.exit(main())
