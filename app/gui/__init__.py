"""The flexvox Qt application (``flexvox app``): device panel, Calibrate, Capture and Review.

Two kinds of module live here, kept apart as napari keeps ``components`` and ``_qt``:

- **Qt-free models and services** in :mod:`flexvox_app.gui.models` (import-linter forbids Qt there, and a
  test imports every one of them with Qt blocked);
- **Qt views** that take those models in their constructors: shared widgets in
  :mod:`flexvox_app.gui.widgets`, one subpackage per workspace (:mod:`flexvox_app.gui.calibrate`,
  :mod:`flexvox_app.gui.capture`, :mod:`flexvox_app.gui.review`) and the projector output
  (:mod:`flexvox_app.gui.projector`).

What is shared with the command line lives below both (``app/capture``, ``calibration``,
``flexvox_core``): see docs/architecture.md. This package file imports nothing, so
``import flexvox_app.gui.models.continuum`` never loads Qt.
"""
