"""Time from ``flexvox app`` to a usable main window, idle and under load.

Each run starts a fresh interpreter that runs ``flexvox app`` (the simulated rig, a throw-away settings file)
as the command line does, through ``flexvox_app.cli.main``. The child logs each start-up step (the
``start-up: …`` lines of :mod:`flexvox_app.gui.application`) and notes when the main window is shown and its event loop
runs (usable); it then closes. Printed per run: the seconds from starting the process to each step and to the
usable main window (the interpreter's own start included).

Under load, ``--busy N`` processes spinning on the CPU (pure Python loops) start before the run and are
stopped after it (each by its process id, and each stops itself after ``--busy-limit`` seconds whatever
happens), as on a shared 2-core lab machine.

Figures only, never pass/fail. Usage::

    QT_QPA_PLATFORM=offscreen python bench/bench_startup.py [--runs 3] [--busy 4] [--busy-limit 120] [--root CHECKOUT]

(``offscreen`` runs without a display; under an X server leave QT_QPA_PLATFORM unset to include the window
system's mapping of the windows).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import logging, os, sys, time
T0 = float(sys.argv[1])
marks = []

class Marks(logging.Handler):
    def emit(self, record):
        msg = record.getMessage()
        if msg.startswith("start-up: ") and "main window shown" not in msg:
            marks.append((time.time() - T0, msg[len("start-up: "):]))

log = logging.getLogger("flexvox_app.gui.application")
log.addHandler(Marks())
log.setLevel(logging.INFO)

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QMainWindow

show = QMainWindow.show

def shown_then_closed(window):  # the main window shown: usable once its event loop runs
    show(window)
    def usable():
        marks.append((time.time() - T0, "usable main window"))
        window.close()  # nothing to lose at start: it closes without asking
    QTimer.singleShot(0, usable)

QMainWindow.show = shown_then_closed
from flexvox_app.gui.widgets import settings as s
s.default_settings = lambda: s.settings_at(os.path.join(sys.argv[2], "flexvox.ini"))
from flexvox_app.cli.main import main
status = main(["app"])
for seconds, step in marks:
    print(f"{seconds:7.2f} s  {step}")
print("STATUS", status)
"""


def one_run(tmp: Path, root: Path) -> list[tuple[float, str]]:
    """Run ``flexvox app`` of the checkout ``root`` once; returns the (seconds, step) marks."""
    env = dict(os.environ, PYTHONPATH=str(root))
    t0 = time.time()
    out = subprocess.run([sys.executable, "-c", CHILD, repr(t0), str(tmp)], cwd=root, env=env,
                         capture_output=True, text=True, timeout=300)
    if out.returncode != 0 or "STATUS 0" not in out.stdout:
        raise RuntimeError(f"flexvox app did not start and close cleanly:\n{out.stdout}\n{out.stderr[-3000:]}")
    marks = []
    for line in out.stdout.splitlines():
        if " s  " in line:
            seconds, step = line.split(" s  ", 1)
            marks.append((float(seconds), step))
    return marks


def busy_loops(n: int, limit_s: float) -> list[subprocess.Popen]:
    """``n`` processes spinning on the CPU, each stopping itself after ``limit_s`` seconds."""
    code = f"import time\nend = time.time() + {limit_s}\nwhile time.time() < end:\n    pass\n"
    return [subprocess.Popen([sys.executable, "-c", code]) for _ in range(n)]


def series(label: str, runs: int, tmp: Path, root: Path) -> None:
    totals = []
    for i in range(runs):
        marks = one_run(tmp, root)
        total = next(s for s, step in marks if step == "usable main window")
        totals.append(total)
        print(f"{label} run {i + 1}: usable main window after {total:.2f} s")
        for seconds, step in marks:
            print(f"    {seconds:6.2f} s  {step}")
    print(f"{label}: median {statistics.median(totals):.2f} s, min {min(totals):.2f} s, max {max(totals):.2f} s "
          f"over {runs} runs\n")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=3, help="runs per condition (default 3)")
    p.add_argument("--busy", type=int, default=4, help="busy-loop processes for the loaded runs (default 4; 0: "
                   "idle only)")
    p.add_argument("--busy-limit", type=float, default=120.0, help="seconds after which each busy loop stops "
                   "itself (default 120)")
    p.add_argument("--root", type=Path, default=ROOT, help="the checkout to start (default this one; another "
                   "gives the figures to compare with)")
    args = p.parse_args(argv)
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} before the runs")
    with tempfile.TemporaryDirectory() as tmp:
        series("idle", args.runs, Path(tmp), args.root)
        if args.busy:
            loops = busy_loops(args.busy, args.busy_limit)
            try:
                time.sleep(1.0)
                series(f"under load ({args.busy} busy loops)", args.runs, Path(tmp), args.root)
            finally:
                for proc in loops:
                    proc.terminate()
                for proc in loops:
                    proc.wait(timeout=10)


if __name__ == "__main__":
    main()
