"""flexvox_core, rig_drivers and calibration must import on a machine without Qt."""

import subprocess
import sys
import textwrap

BLOCK_QT = textwrap.dedent(
    """
    import importlib.abc, sys

    class BlockQt(importlib.abc.MetaPathFinder):
        BLOCKED = ("PySide6", "PyQt5", "PyQt6", "shiboken6", "pyqtgraph", "qtpy")

        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in self.BLOCKED:
                raise ImportError(f"Qt is blocked in this test: {name}")
            return None

    sys.meta_path.insert(0, BlockQt())
    import flexvox_core, rig_drivers, calibration
    import flexvox_core.design, flexvox_core.forward, flexvox_core.multiplex
    loaded = [m for m in sys.modules if m.split(".")[0] in BlockQt.BLOCKED]
    assert not loaded, loaded
    print("ok")
    """
)


def test_core_packages_import_with_qt_blocked():
    out = subprocess.run([sys.executable, "-c", BLOCK_QT], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_the_blocker_really_blocks_qt():
    # The guard above must fail if a core package did import Qt.
    script = BLOCK_QT.replace("import flexvox_core, rig_drivers, calibration", "import PySide6")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert out.returncode != 0
    assert "Qt is blocked" in out.stderr
