"""The flexvox Qt application (``flexvox app``): device panel, Calibrate, Capture and Review.

Two kinds of module live here, kept apart as napari keeps ``components`` and ``_qt``:

- **Qt-free models and services** (importable on a machine without Qt; a test proves it):
  :mod:`~app.gui.models.continuum`, :mod:`~app.gui.models.expected_quality`, :mod:`~app.gui.models.jobs`,
  :mod:`~app.gui.models.review_session`, :mod:`~app.gui.models.rig_service`, :mod:`~app.gui.models.capture_plan`,
  :mod:`~app.gui.models.live_stats`.
- **Qt views** that take those models in their constructors: everything else
  (``*_workspace``, ``*_panel``, ``main_window``, ``qt_jobs``, ``settings``, ...).

This package file imports nothing, so ``import app.gui.models.continuum`` never loads Qt.
"""
