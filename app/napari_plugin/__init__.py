"""flexvox in napari: a reader for recordings and reconstructions, and two dock widgets (``flexvox[napari]``).

- :mod:`flexvox_app.napari_plugin.layers` — Qt-free and napari-free: what napari's reader gets (npe2
  layer-data tuples with names, time scales and metadata) and the reconstruction as a generator of
  progress steps that can be cancelled between chunks;
- :mod:`flexvox_app.napari_plugin.widgets` — the dock widgets (qtpy, napari's ``thread_worker``):
  *Reconstruct* (any registered method with its options) and *Motion-aware flow* (the flow as a
  colour wheel and the [TR, SR] map);
- ``napari.yaml`` — the npe2 manifest napari finds through the ``napari.manifest`` entry point.

How to install and use it: docs/napari.md.
"""
