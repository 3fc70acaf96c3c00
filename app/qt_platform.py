"""Whether Qt can open a window here, asked before Qt is loaded (Qt-free).

Qt aborts the whole process (SIGABRT) when its platform plugin cannot start, so front ends ask
:func:`display_problem` first: ``flexvox app`` and ``--projector-screen`` / ``--list-screens``.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

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
    missing = missing_xcb_libraries() if platform in ("", "xcb") and sys.platform.startswith("linux") else []
    if missing:  # Qt's own message names libxcb-cursor0 whatever is missing: name what is
        packages = " ".join(debian_package(name) for name in missing)
        return (f"Qt's X11 platform plugin (xcb) cannot load: this system lacks {', '.join(missing)} "
                f"(Debian/Ubuntu: sudo apt install {packages}; the README lists every system library Qt needs)")
    lines = [ln.strip() for ln in child.stderr.splitlines() if ln.strip()]
    key = next((ln for ln in lines if "platform plugin" in ln or "connect to display" in ln),
               lines[0] if lines else f"exit status {child.returncode}")
    return f"Qt cannot start its platform plugin here ({key}); {_HOW}"


def missing_xcb_libraries() -> list[str]:
    """The shared libraries Qt's X11 platform plugin (``libqxcb.so`` and the ``libQt6XcbQpa`` it loads) needs and
    this system lacks, by ``ldd`` (sonames such as ``libxcb-icccm.so.4``); [] when none is, or it cannot tell."""
    import importlib.util
    import re
    import shutil

    spec = importlib.util.find_spec("PySide6")
    if spec is None or not spec.submodule_search_locations or shutil.which("ldd") is None:
        return []
    qt = Path(next(iter(spec.submodule_search_locations))) / "Qt"
    files = [qt / "plugins" / "platforms" / "libqxcb.so", *sorted((qt / "lib").glob("libQt6XcbQpa.so*"))[:1]]
    missing: list[str] = []
    for f in files:
        if not f.exists():
            continue
        try:
            out = subprocess.run(["ldd", str(f)], capture_output=True, text=True, timeout=10).stdout
        except (OSError, subprocess.TimeoutExpired):
            return []
        for name in re.findall(r"^\s*(\S+) => not found", out, flags=re.MULTILINE):
            if name not in missing:
                missing.append(name)
    return missing


def debian_package(soname: str) -> str:
    """The Debian package that ships a library, by Debian's naming rule: ``libxcb-icccm.so.4`` → ``libxcb-icccm4``
    (a name ending in a digit takes a dash: ``libfoo2.so.1`` → ``libfoo2-1``)."""
    import re

    m = re.match(r"^(lib[\w+.-]+?)\.so\.(\d+)", soname)
    if m is None:
        return soname
    name, version = m.groups()
    return f"{name}{'-' if name[-1].isdigit() else ''}{version}"
