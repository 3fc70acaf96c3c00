"""Whether Qt can open a window here, asked before Qt is loaded (Qt-free).

Qt aborts the whole process (SIGABRT) when its platform plugin cannot start, so front ends ask
:func:`display_problem` first: ``flexvox app`` and ``--projector-screen`` / ``--list-screens``.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

_HEADLESS = ("offscreen", "minimal")
_PROBE = "import sys; from PySide6.QtGui import QGuiApplication; QGuiApplication(sys.argv[:1])"
_HOW = ("run it in a desktop session, under a virtual screen (`xvfb-run flexvox app`), or with "
        "QT_QPA_PLATFORM=offscreen (nothing is shown)")


GUI_PACKAGES = ("PySide6", "pyqtgraph")
"""What the ``gui`` extra installs and the Qt application imports."""
GUI_INSTALL = "pip install '.[gui]' in a clone of flexvox"


def missing_gui_extra() -> str | None:
    """Why the Qt application cannot start in this environment (its extra is not installed), or None.

    The core, the command line and batch install without Qt (``pip install .`` in a clone); the window
    needs the ``gui`` extra. Asked without importing Qt: only whether its packages can be found.
    """
    missing = []
    for name in GUI_PACKAGES:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a finder that refuses it, or a half-removed package
            found = False
        if not found:
            missing.append(name)
    if not missing:
        return None
    return (f"the Qt application needs the GUI extra ({', '.join(missing)} not installed here): "
            f"{GUI_INSTALL}")


def display_problem(env=None, *, probe: bool = True) -> str | None:
    """Why Qt could not open a window here, or None when it can (checked before Qt is loaded).

    Qt aborts the whole process (SIGABRT) when its platform plugin cannot start, so this asks
    first: a Linux desktop needs DISPLAY (X11) or WAYLAND_DISPLAY; then, unless ``probe`` is
    False, a short child process starts Qt's platform plugin, which catches a missing plugin or a
    missing system library (libxcb-cursor0, say) and an unreachable display. ``offscreen`` and
    ``minimal`` need no display and are not probed.
    """
    env = os.environ if env is None else env
    platform = env.get("QT_QPA_PLATFORM", "").split(":")[0].strip().lower()
    if platform in _HEADLESS:
        return None
    if sys.platform.startswith("linux"):
        x11, wayland = env.get("DISPLAY"), env.get("WAYLAND_DISPLAY")
        if platform in ("", "xcb") and not x11 and not (platform == "" and wayland):
            return f"no display to open the window on (DISPLAY is not set); {_HOW}"
        if platform.startswith("wayland") and not wayland:
            return f"QT_QPA_PLATFORM={platform} but WAYLAND_DISPLAY is not set; {_HOW}"
    if not probe:
        return None
    try:
        child = subprocess.run([sys.executable, "-c", _PROBE], env=dict(env), capture_output=True, text=True,
                               timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None  # cannot tell: let Qt try
    if child.returncode == 0:
        return None
    lines = [ln.strip() for ln in child.stderr.splitlines() if ln.strip()]
    key = next((ln for ln in lines if "platform plugin" in ln or "connect to display" in ln),
               lines[0] if lines else f"exit status {child.returncode}")
    return f"Qt cannot start its platform plugin here ({key}); {_HOW}"
