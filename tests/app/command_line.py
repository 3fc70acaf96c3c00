"""Running the real command line from tests, as a user would, and checking a refusal (shared by the CLI tests)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "PYTHONPATH": str(ROOT)}


def flexvox(*args, env=None, timeout=120, **kw) -> subprocess.CompletedProcess:
    """Run the real command line; text stdout and stderr."""
    return subprocess.run([sys.executable, "-m", "flexvox_app.cli.main", *map(str, args)], cwd=ROOT, env=env or ENV,
                          capture_output=True, text=True, timeout=timeout, **kw)


def stderr_lines(proc) -> list[str]:
    """Lines a user sees on stderr (a progress bar's carriage-return redraws collapsed)."""
    return [line.split("\r")[-1] for line in proc.stderr.splitlines() if line.split("\r")[-1].strip()]



def assert_refused(proc, status: int, pattern: str) -> None:
    """``proc`` exited with ``status`` and one stderr line matching ``pattern``, and no traceback."""
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = stderr_lines(proc)
    assert proc.returncode == status, (proc.returncode, proc.stdout, proc.stderr)
    assert len(lines) == 1, lines
    assert re.search(pattern, lines[0]), lines[0]
