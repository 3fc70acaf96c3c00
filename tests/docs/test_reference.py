"""The API reference (docs/api.rst, docs/reference/*.rst) lists every public name, and the examples page shows
every example.

Here the .rst sources' summary tables are read (quick; ``make test``). ``make docs`` checks the built reference
too: docs/conf.py warns, and -W fails the build, when a name of a public package's ``__all__`` has no entry
among the documented objects.
"""

from __future__ import annotations

import ast
import importlib
import re

from tests.docs.guide_blocks import ROOT

DOCS = ROOT / "docs"
PACKAGES = ("flexvox_core", "rig_drivers", "flexvox_calibration", "flexvox_app.capture")
_DIRECTIVE = re.compile(r"^\.\. (currentmodule|autosummary|py:data)::\s*(\S*)")


def listed_names() -> set[str]:
    """Every fully qualified name a summary table (or ``py:data``) of docs/reference/*.rst lists."""
    names = set()
    for page in sorted((DOCS / "reference").glob("*.rst")):
        module, in_table = None, False
        for line in page.read_text(encoding="utf-8").splitlines():
            found = _DIRECTIVE.match(line)
            if found:
                kind, arg = found.groups()
                if kind == "currentmodule":
                    module = arg
                elif kind == "py:data":
                    names.add(f"{module}.{arg}")
                in_table = kind == "autosummary"
                continue
            if in_table and line.startswith("   ") and not line.strip().startswith(":") and line.strip():
                entry = line.strip().lstrip("~")
                names.add(entry if entry.split(".")[0] in {p.split(".")[0] for p in PACKAGES} else f"{module}.{entry}")
            elif in_table and line.strip() and not line.startswith(" "):
                in_table = False
    return names


def test_every_name_of_every_public_package_has_its_entry_in_the_reference():
    listed = listed_names()
    missing = sorted(f"{package}.{name}" for package in PACKAGES
                     for name in importlib.import_module(package).__all__ if f"{package}.{name}" not in listed)
    assert missing == []
    # the names the issue found missing, each by its public name or the module that defines it
    for name in ("flexvox_core.SCENES", "flexvox_core.EFFECTS", "flexvox_core.render_scene", "rig_drivers.Rig",
                 "rig_drivers.DeviceError", "rig_drivers.VirtualClock", "rig_drivers.SimulatedRigSpec",
                 "flexvox_calibration.CalibrationError", "flexvox_calibration.CalibrationRefused",
                 "flexvox_app.capture.CaptureResult", "flexvox_app.capture.CaptureStats",
                 "flexvox_app.capture.CaptureEvents", "flexvox_core.video_io.VideoStore",
                 "flexvox_core.motion.result.MotionAwareResult", "flexvox_core.capture_reader.CaptureReader"):
        assert name in listed, name


def test_the_reference_lists_only_names_that_exist():
    for name in listed_names():
        module, _, attr = name.rpartition(".")
        assert hasattr(importlib.import_module(module), attr), name


def test_the_build_checks_the_same_packages():
    conf = (DOCS / "conf.py").read_text(encoding="utf-8")
    assert ast.literal_eval(re.search(r"^PUBLIC = (\(.*\))$", conf, flags=re.M).group(1)) == PACKAGES
    api = (DOCS / "api.rst").read_text(encoding="utf-8")
    assert all(f"reference/{package}\n" in api for package in PACKAGES)


def test_the_examples_page_shows_every_example():
    page = (DOCS / "examples.md").read_text(encoding="utf-8")
    scripts = sorted(p.name for p in (ROOT / "examples").glob("*.py") if not p.name.startswith("_"))
    shown = re.findall(r"^```\{flexvox-example\} (\S+)$", page, flags=re.M)
    assert sorted(shown) == scripts
