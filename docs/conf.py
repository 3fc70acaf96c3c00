"""Sphinx configuration: `make docs` builds the Python guide, the examples and the API reference into
docs/_build/html, failing on any warning (-W). The reference is generated from the docstrings (numpydoc)."""

import os
import sys

sys.path.insert(0, os.path.abspath(".."))
os.environ.setdefault("MPLBACKEND", "Agg")

project = "flexvox"
author = "flexvox contributors"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.autosummary", "numpydoc"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# The docs built: the guide, the examples' page and the reference. The other pages are read on GitHub; the guide
# links to them as files.
include_patterns = ["index.rst", "python.md", "examples.md", "api.rst"]
exclude_patterns = ["_build"]
myst_heading_anchors = 3
suppress_warnings = ["myst.xref_missing"]  # links to pages read on GitHub (gpu.md, napari.md, real-rig.md)
autosummary_generate = False
numpydoc_show_class_members = False
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False
autodoc_typehints = "none"
autodoc_member_order = "bysource"
html_theme = "alabaster"
nitpicky = False
