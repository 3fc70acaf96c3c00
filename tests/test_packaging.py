"""What ``pip install flexvox`` installs: import names a user's own files cannot shadow, and every package.

The folders ``app/`` and ``calibration/`` install as ``flexvox_app`` and ``flexvox_calibration``
(``[tool.setuptools]`` in pyproject.toml); the packages are listed there by hand, so a test keeps the list whole.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETUPTOOLS = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]


def _installed_name(folder: Path) -> str:
    """The import name of a package folder under the repository root, through ``package-dir``."""
    parts = list(folder.relative_to(ROOT).parts)
    by_folder = {v: k for k, v in SETUPTOOLS.get("package-dir", {}).items()}
    parts[0] = by_folder.get(parts[0], parts[0])
    return ".".join(parts)


TOPS = ("app", "calibration", "flexvox_core", "rig_drivers")


def _shipped_files() -> list[Path]:
    """The files of the package folders that git tracks (no caches, no build leftovers)."""
    out = subprocess.run(["git", "ls-files", "--", *TOPS], cwd=ROOT, capture_output=True, text=True, check=True)
    return [ROOT / line for line in out.stdout.splitlines()]


def test_the_package_list_names_every_folder_that_holds_an_init_file_or_a_data_file():
    """A folder of data files only (``rig_drivers/examples``) is a package to setuptools too: unlisted, it warns
    on every install and its files are installed by a deprecated path."""
    found = sorted({_installed_name(f.parent) for f in _shipped_files()})
    assert sorted(SETUPTOOLS["packages"]) == found
    assert {"rig_drivers.examples", "rig_drivers.firmware.syncbox"} <= set(found)


def test_package_data_covers_every_file_that_is_not_python():
    """Each data file is matched by its own package's ``package-data`` patterns (none reaches into a subfolder)."""
    data = SETUPTOOLS["package-data"]
    unmatched = [str(f.relative_to(ROOT)) for f in _shipped_files() if f.suffix != ".py"
                 and not any(f.match(pattern) for pattern in data.get(_installed_name(f.parent), []))]
    assert unmatched == []
    assert all("/" not in pattern for patterns in data.values() for pattern in patterns)


def test_the_generic_folder_names_install_under_flexvox_names():
    assert SETUPTOOLS["package-dir"] == {"flexvox_app": "app", "flexvox_calibration": "calibration"}
    assert not {"app", "calibration"} & {p.split(".")[0] for p in SETUPTOOLS["packages"]}


def test_a_users_app_and_calibration_files_do_not_shadow_flexvox(tmp_path):
    """A notebook's folder with its own ``app.py`` and ``calibration.py``: flexvox still imports, and so do they."""
    (tmp_path / "calibration.py").write_text("WHO = 'mine'\n")
    (tmp_path / "app.py").write_text("WHO = 'mine too'\n")
    code = ("import calibration, app\n"
            "from flexvox_calibration import calibrate_rig\n"
            "from flexvox_calibration.session import RigSession\n"
            "from flexvox_app.capture import CapturePlan\n"
            "print(calibration.WHO, '|', app.WHO, '|', calibrate_rig.__module__, RigSession.__name__, "
            "CapturePlan.__module__)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == ("mine | mine too | flexvox_calibration.for_rig RigSession "
                                  "flexvox_app.capture.plan")


def test_importing_the_application_loads_no_module_under_a_folder_name():
    """Every module imports its siblings by the installed names: none of ``app.*`` or ``calibration.*`` loads."""
    code = ("import sys, flexvox_app.cli.main, flexvox_app.gui.main_window, flexvox_calibration.pipeline\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('app', 'calibration')))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "[]"
