"""The light install: the core, the command line and batch import and run on a machine without Qt.

``pip install flexvox`` installs no Qt (PySide6 and pyqtgraph are the ``gui`` extra), so every module a
batch worker or a headless reconstruction loads must import with Qt absent. Each test runs a child
interpreter whose import system refuses PySide6, shiboken6, pyqtgraph (and PyQt, qtpy) — as if they were
not installed — and checks that none of them was loaded. ome-zarr-models and its pydantic are the ``test``
extra's (they check the NGFF metadata in the tests): they are refused in the same way.
"""

import subprocess
import sys
import textwrap

import pytest

BLOCK_QT = textwrap.dedent(
    """
    import importlib.abc, sys

    class BlockQt(importlib.abc.MetaPathFinder):
        BLOCKED = ("PySide6", "PyQt5", "PyQt6", "shiboken6", "pyqtgraph", "qtpy")
        TEST_EXTRA = ("pydantic", "pydantic_core", "pydantic_zarr", "ome_zarr_models")

        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in self.BLOCKED:
                raise ImportError(f"Qt is blocked in this test: {name}")
            if name.split(".")[0] in self.TEST_EXTRA:
                raise ImportError(f"the test extra is blocked in this test: {name}")
            return None

    sys.meta_path.insert(0, BlockQt())

    def no_qt_loaded():
        loaded = [m for m in sys.modules if m.split(".")[0] in BlockQt.BLOCKED + BlockQt.TEST_EXTRA]
        assert not loaded, loaded
    """
)

CORE = BLOCK_QT + textwrap.dedent(
    """
    import flexvox_core, rig_drivers, calibration
    import flexvox_core.design, flexvox_core.forward, flexvox_core.multiplex
    no_qt_loaded()
    print("ok")
    """
)

CLI = BLOCK_QT + textwrap.dedent(
    """
    import importlib, pkgutil
    import flexvox_app.cli, flexvox_app.cli.main, flexvox_core.batch, flexvox_core.video_io, flexvox_core.methods
    # every subcommand's module, and the parser that registers them all
    for info in pkgutil.iter_modules(flexvox_app.cli.__path__):
        importlib.import_module(f"flexvox_app.cli.{info.name}")
    flexvox_app.cli.main.build_parser()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot
    no_qt_loaded()
    print("ok")
    """
)

RUN = BLOCK_QT + textwrap.dedent(
    """
    import sys
    from flexvox_app.cli.main import main
    out = sys.argv[1]
    assert main(["simulate", "drummer", "--frames", "8", "--size", "32x32", "-o", f"{out}/rec.zarr"]) == 0
    assert main(["reconstruct", f"{out}/rec.zarr", "-o", f"{out}/video.zarr"]) == 0
    assert main(["batch", f"{out}/rec.zarr", "-o", f"{out}/batch.zarr", "--chunk", "1"]) == 0
    assert main(["export", f"{out}/rec.zarr", "--what", "frames", "-o", f"{out}/frames.tif"]) == 0
    no_qt_loaded()
    print("ok")
    """
)

APP = BLOCK_QT + textwrap.dedent(
    """
    import sys
    from flexvox_app.cli.main import main
    sys.exit(main(sys.argv[1:]))
    """
)


def _run(script: str, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True)


def test_core_packages_import_with_qt_blocked():
    out = _run(CORE)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_the_cli_every_subcommand_and_batch_import_with_qt_blocked():
    out = _run(CLI)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_simulate_reconstruct_batch_and_export_run_with_qt_blocked(tmp_path):
    out = _run(RUN, str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("ok")
    assert (tmp_path / "video.zarr" / "zarr.json").is_file() and (tmp_path / "batch.zarr" / "zarr.json").is_file()


def test_flexvox_app_without_the_gui_extra_exits_2_naming_it():
    out = _run(APP, "app")
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert "flexvox app: error: the Qt application needs the GUI extra" in lines[0]
    assert "pip install '.[gui]' in a clone of flexvox" in lines[0]  # not on the package index


def test_list_screens_without_the_gui_extra_exits_2_naming_it():
    out = _run(APP, "calibrate", "--list-screens")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        "flexvox calibrate: error: the Qt application needs the GUI extra (PySide6, pyqtgraph not installed "
        "here): pip install '.[gui]' in a clone of flexvox"]


HEAVY = ("scipy", "numba", "dask", "matplotlib", "tifffile", "numpy", "zarr", "numcodecs", "tqdm", "cv2",
         "flexvox_core.methods", "flexvox_core.recording", "flexvox_core.simulate", "importlib.metadata")

LEAN = textwrap.dedent(
    f"""
    import sys
    import flexvox_app.cli.main
    parser = flexvox_app.cli.main.build_parser()
    parser.parse_args(sys.argv[1:])
    print(",".join(m for m in {HEAVY!r} if m in sys.modules) or "none")
    """
)


@pytest.mark.parametrize("argv", [[], ["app", "--rig", "mock"]])
def test_the_command_line_parses_without_numpy_zarr_or_the_methods(argv):
    # Every `flexvox` run imports the parser and every subcommand's module, and `flexvox app` shows its start-up
    # window only after parsing: what they pull in at import time is paid by each command (scipy.optimize, which only
    # `flexvox design` needs, was 0.26 s of it; numpy, zarr, the methods' registry and the version look-up most of
    # the 0.7 s before the window). A module imports these where it runs; a parser that needs them (the methods'
    # options) defers them to when its command is used (`OneLineParser.defer`).
    out = _run(LEAN, *argv)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "none"


def test_a_deferred_parser_is_complete_when_its_command_is_used():
    script = LEAN.replace("parser.parse_args(sys.argv[1:])", "args = parser.parse_args(sys.argv[1:]); "
                          "assert args.method == 'motion-aware' and args.chunk == 16, args")
    out = _run(script, "reconstruct", "r.zarr", "-o", "v.npy", "--method", "motion-aware")
    assert out.returncode == 0, out.stderr
    assert "flexvox_core.methods" in out.stdout  # its options come from the methods' registry


def test_the_package_names_resolve_when_asked_for():
    script = textwrap.dedent(
        """
        import sys
        import flexvox_core
        assert "flexvox_core.design" not in sys.modules and "scipy" not in sys.modules
        from flexvox_core import design_code, MAX_TILE_SIDE, verify
        import flexvox_core.design
        assert design_code is flexvox_core.design.design_code and MAX_TILE_SIDE == 8
        assert {"design_code", "s_matrix", "capture", "forward"} <= set(dir(flexvox_core))
        assert {"design_code", "MAX_TILE_SIDE", "verify", "__version__", "forward"} <= set(flexvox_core.__all__)
        # the submodules `import flexvox_core` used to load are still its attributes
        assert flexvox_core.forward.capture is flexvox_core.capture and hasattr(flexvox_core, "divisions")
        try:
            flexvox_core.no_such_name
        except AttributeError as exc:
            assert "no_such_name" in str(exc)
        else:
            raise SystemExit("an unknown name resolved")
        print("ok")
        """
    )
    out = _run(script)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_the_names_are_listed_once_in_the_stub_that_type_checkers_read():
    # flexvox_core's names live in __init__.pyi alone: lazy_loader makes them the package's attributes and
    # __all__, and type checkers read the same file. Every name there resolves to what its module holds.
    import ast
    import importlib
    from pathlib import Path

    import flexvox_core

    stub = ast.parse(Path(flexvox_core.__file__).with_suffix(".pyi").read_text())
    names = {a.name: node.module for node in stub.body if isinstance(node, ast.ImportFrom) and node.module
             for a in node.names}
    assert set(names) | {"codes", "design", "divisions", "forward", "multiplex", "tiles"} == set(flexvox_core.__all__)
    for name, module in names.items():
        assert getattr(flexvox_core, name) is getattr(importlib.import_module(f"flexvox_core.{module}"), name)


def test_the_blocker_really_blocks_qt():
    # The guards above must fail if a module did import Qt.
    script = CORE.replace("import flexvox_core, rig_drivers, calibration", "import PySide6")
    out = _run(script)
    assert out.returncode != 0
    assert "Qt is blocked" in out.stderr
