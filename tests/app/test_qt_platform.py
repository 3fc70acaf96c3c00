"""Asking whether Qt can open a window before Qt is loaded (Qt aborts the process otherwise)."""

import re
import sys

import pytest

from flexvox_app.qt_platform import display_problem

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the DISPLAY rules are Linux's")


@linux
@pytest.mark.parametrize("env, expected", [
    ({}, r"no display to open the window on \(DISPLAY is not set\)"),
    ({"QT_QPA_PLATFORM": "xcb", "WAYLAND_DISPLAY": "wayland-0"}, r"DISPLAY is not set"),
    ({"QT_QPA_PLATFORM": "wayland"}, r"QT_QPA_PLATFORM=wayland but WAYLAND_DISPLAY is not set"),
])
def test_a_missing_display_is_named(env, expected):
    import re

    problem = display_problem(env, probe=False)
    assert problem is not None and re.search(expected, problem)
    assert "QT_QPA_PLATFORM=offscreen" in problem and "xvfb-run" in problem


def test_headless_platforms_and_a_display_pass_without_a_probe():
    assert display_problem({"QT_QPA_PLATFORM": "offscreen"}) is None  # never probed
    assert display_problem({"QT_QPA_PLATFORM": "minimal:foo=1"}) is None
    assert display_problem({"DISPLAY": ":0"}, probe=False) is None
    assert display_problem({"WAYLAND_DISPLAY": "wayland-0"}, probe=False) is None


@linux
def test_the_probe_reports_what_qt_says(monkeypatch):
    import os

    from tests.app.no_display import unserved_display

    env = {**os.environ, "DISPLAY": unserved_display(), "QT_QPA_PLATFORM": "xcb"}  # no X server there
    problem = display_problem(env)
    # Which words depend on this system: the xcb plugin's own libraries missing, or no X server at that display.
    assert problem is not None and re.match(r"Qt cannot start its platform plugin here \(|Qt's X11 platform plugin "
                                            r"\(xcb\) cannot load: this system lacks \S", problem), problem


def test_the_display_without_a_server_skips_a_served_one(monkeypatch):
    from tests.app import no_display

    served = {59999, 59998}
    monkeypatch.setattr(no_display, "_served", lambda number: number in served)
    assert no_display.unserved_display() == ":59997"
