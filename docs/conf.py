"""Sphinx configuration: `make docs` builds the Python guide, the examples and the API reference into
docs/_build/html, failing on any warning (-W).

The reference (docs/api.rst and docs/reference/) lists every public name of every public package in summary
tables (autosummary), one page per name generated from its docstring (numpydoc) into docs/reference/generated/
at each build. Four things are made here:

* Links to numpy, zarr, dask and distributed: intersphinx reads small inventories written at each build from
  :data:`EXTERNAL` (the build has no internet, so it cannot download theirs); a link leads to the project's
  own page.
* A docstring's reference to a name by the module that defines it (``flexvox_core.design.DesignResult``) links
  to the name's page under its public package (``flexvox_core.DesignResult``).
* ``.. flexvox-scenes::``, ``.. flexvox-effects::``: tables of the built-in scenes and of the simulated effects
  with their parameters, from the registries themselves.
* ``.. flexvox-example:: NAME.py``: an example's code and what it prints, run at tiny size during the build.

At the end, every name in a public package's ``__all__`` must have its entry in the reference, or the build
warns (and -W fails it).
"""

from __future__ import annotations

import importlib
import os
import shutil
import subprocess
import sys
import tempfile
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive, directives
from docutils.statemachine import StringList
from sphinx.util import logging

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MPLBACKEND", "Agg")
_logger = logging.getLogger("flexvox.docs")

project = "flexvox"
author = "flexvox contributors"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.intersphinx", "numpydoc"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# The docs built: the guide, the examples' page and the reference. The other pages are read on GitHub; the guide
# links to them as files.
include_patterns = ["index.rst", "python.md", "examples.md", "api.rst", "reference/**"]
exclude_patterns = ["_build", "reference/_templates/**"]
templates_path = ["reference/_templates"]
myst_heading_anchors = 3
suppress_warnings = ["myst.xref_missing"]  # links to pages read on GitHub (gpu.md, napari.md, real-rig.md)
default_role = "py:obj"  # `name` in a docstring links when it names something documented
autosummary_generate = True
autosummary_generate_overwrite = True
autosummary_imported_members = False
numpydoc_show_class_members = False
numpydoc_validation_checks = set()
# Parameter types link: "ndarray" to numpy's page, a flexvox class to its own.
numpydoc_xref_param_type = True
numpydoc_xref_aliases = {
    "ndarray": "numpy.ndarray", "array": "numpy.ndarray", "dtype": "numpy.dtype", "Generator": "numpy.random.Generator",
    "Path": "pathlib.Path", "zarr.Array": "zarr.Array", "dask.array.Array": "dask.array.Array",
    "Client": "distributed.Client", "LocalCluster": "distributed.LocalCluster",
}
numpydoc_xref_ignore = "all"  # words that are not aliases or documented names stay plain text
autodoc_typehints = "none"
autodoc_member_order = "bysource"
html_theme = "alabaster"
html_theme_options = {"fixed_sidebar": True, "page_width": "1100px", "sidebar_width": "260px"}
html_sidebars = {"**": ["about.html", "navigation.html", "relations.html", "searchbox.html"]}
nitpicky = False

# ----------------------------------------------------------------------------------------------- external links
EXTERNAL = {
    # project: (its documentation's root, version, {name: (role, page relative to the root)})
    "python": ("https://docs.python.org/3/", "3", {
        "pathlib.Path": ("class", "library/pathlib.html#pathlib.Path"),
        "logging": ("module", "library/logging.html#module-logging"),
        "object": ("class", "library/functions.html#object"),
        **{name: ("class", f"library/stdtypes.html#{name}") for name in ("list", "tuple", "str", "dict")},
        **{name: ("class", f"library/functions.html#{name}") for name in ("float", "int", "bool")},
        **{name: ("data", f"library/constants.html#{name}") for name in ("None", "True", "False")},
        "callable": ("function", "library/functions.html#callable"),
        "contextlib.contextmanager": ("function", "library/contextlib.html#contextlib.contextmanager"),
        "collections.namedtuple": ("function", "library/collections.html#collections.namedtuple"),
        # what numpydoc links the words bool, iterable, sequence and generator to
        "bltin-boolean-values": ("std:label", "library/stdtypes.html#bltin-boolean-values"),
        **{term: ("std:term", f"glossary.html#term-{term}") for term in ("iterable", "sequence", "generator")},
    }),
    "numpy": ("https://numpy.org/doc/stable/", "stable", {
        "numpy.ndarray": ("class", "reference/generated/numpy.ndarray.html#numpy.ndarray"),
        "numpy.dtype": ("class", "reference/generated/numpy.dtype.html#numpy.dtype"),
        "numpy.float32": ("class", "reference/arrays.scalars.html#numpy.float32"),
        "numpy.uint16": ("class", "reference/arrays.scalars.html#numpy.uint16"),
        "numpy.random.Generator": ("class", "reference/random/generator.html#numpy.random.Generator"),
        "numpy.random.default_rng": ("function", "reference/random/generator.html#numpy.random.default_rng"),
        "numpy.load": ("function", "reference/generated/numpy.load.html#numpy.load"),
        "numpy.random.RandomState": ("class", "reference/random/legacy.html#numpy.random.RandomState"),
        "numpy.inf": ("data", "reference/constants.html#numpy.inf"),
        "numpy.nan": ("data", "reference/constants.html#numpy.nan"),
        "numpy": ("module", "reference/index.html#module-numpy"),
        # what numpydoc links the words array_like and scalar to
        "array_like": ("std:term", "glossary.html#term-array_like"),
        "arrays.scalars": ("std:label", "reference/arrays.scalars.html#arrays-scalars"),
    }),
    "zarr": ("https://zarr.readthedocs.io/en/v3.1.2/", "3.1", {
        "zarr.Array": ("class", "api/zarr/index.html#zarr.Array"),
        "zarr.Group": ("class", "api/zarr/index.html#zarr.Group"),
        "zarr.open_group": ("function", "api/zarr/index.html#zarr.open_group"),
        "zarr.open_array": ("function", "api/zarr/index.html#zarr.open_array"),
    }),
    "dask": ("https://docs.dask.org/en/stable/", "stable", {
        "dask.array.Array": ("class", "generated/dask.array.Array.html#dask.array.Array"),
        "dask.array.from_zarr": ("function", "generated/dask.array.from_zarr.html#dask.array.from_zarr"),
    }),
    "distributed": ("https://distributed.dask.org/en/stable/", "stable", {
        "distributed.Client": ("class", "api.html#distributed.Client"),
        "distributed.LocalCluster": ("class", "api.html#distributed.LocalCluster"),
    }),
}


def write_inventory(path: Path, project_name: str, version: str, entries: dict) -> Path:
    """A Sphinx inventory (objects.inv, version 2) of ``entries`` ``{name: (role, uri)}`` for intersphinx (a
    role without a domain is Python's: ``class`` is ``py:class``)."""
    body = "".join(f"{name} {role if ':' in role else 'py:' + role} 1 {uri} -\n"
                   for name, (role, uri) in sorted(entries.items()))
    head = (f"# Sphinx inventory version 2\n# Project: {project_name}\n# Version: {version}\n"
            "# The remainder of this file is compressed using zlib.\n")
    path.write_bytes(head.encode() + zlib.compress(body.encode()))
    return path


_INVENTORIES = Path(tempfile.mkdtemp(prefix="flexvox-docs-inv-"))
intersphinx_mapping = {
    name: (url, str(write_inventory(_INVENTORIES / f"{name}.inv", name, version, entries)))
    for name, (url, version, entries) in EXTERNAL.items()
}

# ------------------------------------------------------------------------------------------------ public names
PUBLIC = ("flexvox_core", "rig_drivers", "flexvox_calibration", "flexvox_app.capture")
"""The public packages: each name in their ``__all__`` has its entry in the reference."""


DOCUMENTED_BY_MODULE = (
    "flexvox_core.motion.result.MotionAwareResult", "flexvox_core.capture_reader.CaptureReader",
    "flexvox_core.video_io.VideoStore", "rig_drivers.profile.ProfileRig", "rig_drivers.simulated_rig.SimulatedRig",
    "rig_drivers.simulated_camera.MonotonicClock",
)
"""What the public names return, documented under the module that defines it (docs/reference/*.rst)."""


def public_names() -> dict[str, object]:
    """``{"package.name": object}`` for every name of every public package (submodules and ``__version__``
    included)."""
    out = {}
    for package in PUBLIC:
        module = importlib.import_module(package)
        for name in module.__all__:
            out[f"{package}.{name}"] = getattr(module, name)
    return out


def _aliases() -> dict[str, str]:
    """Where each public class or function is defined (``flexvox_core.design.DesignResult``) → its public name."""
    out = {}
    for public, obj in public_names().items():
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if isinstance(module, str) and isinstance(qualname, str) and f"{module}.{qualname}" != public:
            out.setdefault(f"{module}.{qualname}", public)
    return out


def resolve_by_definition(app, env, node, contnode):
    """A reference to a public name by its defining module links to its public page."""
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    public = _ALIASES.get(target) or _ALIASES.get(_SHORT.get(target, ""))  # a bare name: its one public page
    if public is None and "." in target:  # a method or attribute of a public class: Class.member
        head, _, member = target.rpartition(".")
        public = f"{_ALIASES[head]}.{member}" if head in _ALIASES else None
    if public is None:
        return None
    domain = env.get_domain("py")
    return domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], public, node, contnode)


def check_every_public_name_is_documented(app, env):
    """Warn (-W: fail) for a name in a public package's ``__all__`` without its entry in the reference."""
    documented = set(env.get_domain("py").objects)
    missing = sorted(name for name in public_names() if name not in documented)
    if missing:
        _logger.warning("names of public packages missing from the reference: %s", ", ".join(missing))


# ------------------------------------------------------------------------------------------- generated tables
def _table(header: list[str], rows: list[list[str]], widths: list[int]) -> list[str]:
    lines = [".. list-table::", "   :header-rows: 1", f"   :widths: {' '.join(map(str, widths))}", ""]
    for row in [header, *rows]:
        lines.append(f"   * - {row[0]}")
        lines += [f"     - {cell}" for cell in row[1:]]
    return lines


class _Generated(Directive):
    has_content = False

    def rst(self) -> list[str]:
        raise NotImplementedError

    def run(self):
        container = nodes.container()
        self.state.nested_parse(StringList(self.rst(), source="flexvox-generated"), self.content_offset, container)
        return container.children


class ScenesTable(_Generated):
    """``.. flexvox-scenes::``: the built-in scenes (:data:`flexvox_core.SCENES`), each with what it shows."""

    def rst(self):
        from flexvox_core import SCENES

        return _table(["name", "what it shows"], [[f"``{n}``", s.description] for n, s in SCENES.items()], [15, 85])


class EffectsTable(_Generated):
    """``.. flexvox-effects::``: the simulated effects (:data:`flexvox_core.EFFECTS`) in the order they apply, with
    their stage, what they do and their parameters (unit, default, range)."""

    def rst(self):
        from flexvox_core import EFFECTS

        rows = []
        for name, effect in EFFECTS.items():
            params = "; ".join(f"``{p.name}`` ({p.description}): {p.default:g} {p.unit}, {p.minimum:g} to "
                               f"{p.maximum:g}{', whole' if p.integer else ''}" for p in effect.params) or "none"
            rows.append([f"``{name}``", effect.stage, effect.description, params])
        return _table(["name", "stage", "what it does", "parameters: default, range"], rows, [14, 8, 38, 40])


EXAMPLES = ROOT / "examples"
_EXAMPLE_OUTPUT: dict[str, str] = {}


def _run_example(script: str) -> tuple[str, str]:
    """Run ``examples/script`` at tiny size (FLEXVOX_EXAMPLE_TINY=1) in a scratch folder; what it printed."""
    with tempfile.TemporaryDirectory(prefix="flexvox-example-") as scratch:
        env = {**os.environ, "FLEXVOX_EXAMPLE_TINY": "1", "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
        proc = subprocess.run([sys.executable, str(EXAMPLES / script)], cwd=scratch, env=env, capture_output=True,
                              text=True, timeout=600)
    if proc.returncode != 0:
        return script, f"(exit status {proc.returncode})\n{proc.stdout}{proc.stderr[-3000:]}"
    return script, proc.stdout


def run_examples(app):
    """Run every example once, two at a time, before the pages are read."""
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))
    with ThreadPoolExecutor(max_workers=2) as pool:
        _EXAMPLE_OUTPUT.update(pool.map(_run_example, scripts))


class ExampleBlock(Directive):
    """``.. flexvox-example:: NAME.py``: the script's code, then what it printed at tiny size during this build."""

    required_arguments = 1
    option_spec = {"caption": directives.unchanged}

    def run(self):
        script = self.arguments[0]
        path = EXAMPLES / script
        if not path.is_file():
            raise self.error(f"no example {script} in {EXAMPLES}")
        output = _EXAMPLE_OUTPUT.get(script)
        if output is None or output.startswith("(exit status"):
            raise self.error(f"examples/{script} failed during the build: {output}")
        self.state.document.settings.record_dependencies.add(str(path))
        code = nodes.literal_block(path.read_text(encoding="utf-8"), path.read_text(encoding="utf-8"),
                                   language="python")
        code["caption"] = f"examples/{script}"
        printed = nodes.literal_block(output, output, language="none")
        return [nodes.rubric(text=f"examples/{script}"), code,
                nodes.paragraph(text="What it prints (FLEXVOX_EXAMPLE_TINY=1, this build):"), printed]


def clean_generated(app):
    """Start from no generated page: a name taken out of a package leaves no stale page behind."""
    shutil.rmtree(HERE / "reference" / "generated", ignore_errors=True)


_ALIASES: dict[str, str] = {}
_SHORT: dict[str, str] = {}
"""A documented name written bare (``SimulatedRig``, as a docstring of its own package may write it) → its full one."""


def setup(app):
    _ALIASES.update(_aliases())
    shorts = {}
    for full in [*_ALIASES, *DOCUMENTED_BY_MODULE]:
        shorts.setdefault(full.rpartition(".")[2], set()).add(full)
    _SHORT.update({short: next(iter(f)) for short, f in shorts.items() if len(f) == 1})
    _ALIASES.update({name: name for name in DOCUMENTED_BY_MODULE})
    app.connect("config-inited", lambda app, config: clean_generated(app), priority=100)
    app.connect("builder-inited", run_examples)
    app.connect("missing-reference", resolve_by_definition)
    app.connect("env-check-consistency", check_every_public_name_is_documented)
    app.add_directive("flexvox-scenes", ScenesTable)
    app.add_directive("flexvox-effects", EffectsTable)
    app.add_directive("flexvox-example", ExampleBlock)
    return {"parallel_read_safe": True}
