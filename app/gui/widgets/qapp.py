"""The one QApplication of the process and the pyqtgraph options the app relies on.

Both the main window (:mod:`flexvox_app.gui.application`) and the projector output that
``flexvox calibrate|capture --projector-screen`` shows (:mod:`flexvox_app.gui.projector.display`) need a
QApplication; they get it here, so neither imports the other.
"""

from __future__ import annotations

import gc
import logging
import sys
import threading

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

_logger = logging.getLogger(__name__)

DEFAULT_SIZE = (1280, 800)
"""The first window's size: every workspace's primary actions are in view at this size (and at 1024×700)."""


def configure_pyqtgraph() -> None:
    """pyqtgraph options the app relies on: row-major images (numpy's (H, W) order), antialiasing.

    pyqtgraph is imported here, not at the module's top, so the start-up window needs only Qt."""
    import pyqtgraph as pg

    pg.setConfigOptions(imageAxisOrder="row-major", antialias=True)


class GuiThreadGarbageCollector:
    """Python's cyclic garbage collection, run on the GUI thread only (pyqtgraph's GarbageCollector pattern).

    Left automatic, a collection runs in whichever thread happens to allocate: zarr's I/O thread, a job's worker.
    When it frees the Python side of a Qt widget, the widget is destroyed in that thread: its destructor holds a Qt
    lock while it waits for the GIL, and the GUI thread, holding the GIL while it deletes another widget, waits
    for that lock. The process hangs (seen in `make test`: zarr's I/O thread in ``QObject::~QObject``, the GUI
    thread in ``BindingManager::runDeletionInMainThread``). So automatic collection is switched off and this timer
    collects, on the GUI thread, by the thresholds the automatic collector would use.
    """

    def __init__(self, interval_ms: int = 500):
        if threading.current_thread() is not threading.main_thread():
            raise RuntimeError("the garbage collector's timer must start on the GUI (main) thread")
        self.threshold = gc.get_threshold()
        gc.disable()
        disarm_dask_slicing()
        self.timer = QTimer()
        self.timer.timeout.connect(self.check)
        self.timer.start(interval_ms)

    def check(self) -> None:
        """Collect the generations whose counts passed their thresholds, youngest first (on the calling thread);
        automatic collection, if something switched it back on, off again."""
        keep_automatic_collection_off()
        counts = gc.get_count()
        for generation in range(3):
            if counts[generation] <= self.threshold[generation]:
                break
            gc.collect(generation)


_COLLECTOR: GuiThreadGarbageCollector | None = None


def keep_automatic_collection_off() -> None:
    """Python's automatic garbage collection off (:class:`GuiThreadGarbageCollector` collects instead), saying so
    when something had switched it back on (as dask's array slicing does: :func:`disarm_dask_slicing`)."""
    if gc.isenabled():
        _logger.warning("automatic garbage collection was switched back on; off again (the GUI thread collects)")
        gc.disable()


def disarm_dask_slicing() -> bool:
    """Stop dask's array slicing from switching automatic garbage collection back on; True where it had.

    ``dask.array.slicing.slice_array`` is decorated with ``dask.utils.disable_gc()``, which notes whether collection
    is on when the decorator is made (at the module's import) and switches it on after every slice if it was. Where
    ``dask.array`` was imported before the GUI's collector started (a notebook that used dask, a test process), every
    later slice would switch automatic collection back on. The decorator's note is set to off. A dask whose slicing
    is made otherwise is left as it is (:func:`keep_automatic_collection_off` still switches collection off at each
    tick)."""
    slicing = sys.modules.get("dask.array.slicing")
    closure = getattr(getattr(slicing, "slice_array", None), "__closure__", None) or ()
    for cell in closure:
        state = getattr(cell.cell_contents, "_gc_enabled", None)
        if isinstance(state, bool):
            cell.cell_contents._gc_enabled = False
            return state
    return False


def collect_garbage_on_gui_thread() -> GuiThreadGarbageCollector:
    """Start :class:`GuiThreadGarbageCollector` once per process (a QApplication must exist); the running one."""
    global _COLLECTOR
    if _COLLECTOR is None:
        _COLLECTOR = GuiThreadGarbageCollector()
    keep_automatic_collection_off()
    return _COLLECTOR


def ensure_application() -> QApplication:
    """The running QApplication, or a new one named flexvox; Python's garbage is collected on its thread only
    (:class:`GuiThreadGarbageCollector`)."""
    app = QApplication.instance()
    if app is None:
        app = QApplication(sys.argv[:1])
        app.setOrganizationName("flexvox")
        app.setApplicationName("flexvox")
    collect_garbage_on_gui_thread()
    return app
