# flexvox — the two commands a new lab member needs: `make demo` and `make test`.
# Each creates .venv when it is missing and installs the project into it (editable).

# Supported and tested: Python 3.11, 3.12 and 3.13 (.ci/run tests 3.11 and 3.13). Another Python goes in a venv of
# its own: `make test PYTHON=python3.13 VENV=.venv-3.13`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.installed-docs
# Every extra: the Qt application (gui), the napari plugin, GenICam cameras, the tests. `pip install flexvox` alone has no Qt.
EXTRAS := test,gui,genicam,napari

.PHONY: same-python demo test test-slow test-full docs-check lint bench screenshots napari-screenshot docs clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml | same-python
	$(BIN)/python -m pip install --quiet -e ".[$(EXTRAS)]"
	touch $(STAMP)

# A venv that another Python made is never reused in silence: `make test PYTHON=python3.13` beside a 3.11 .venv stops.
same-python: $(BIN)/python
	@want=$$($(PYTHON) -c 'import sys; print("%d.%d" % sys.version_info[:2])') && \
	have=$$($(BIN)/python -c 'import sys; print("%d.%d" % sys.version_info[:2])') && \
	if [ "$$want" != "$$have" ]; then \
		echo "make: $(VENV) holds Python $$have but PYTHON=$(PYTHON) is $$want: give VENV=.venv-$$want" \
		"(or remove $(VENV))" >&2; exit 2; fi

demo: $(STAMP) same-python
	$(BIN)/flexvox demo --overwrite

# Two workers (pytest-xdist), whole test files kept together; tests/test_layering.py runs the import contracts;
# the packages' docstring examples run too (--doctest-modules), and tests/test_types.py runs mypy (pyproject.toml).
# `make test` leaves out the tests marked slow_sim (the GPU path's larger cases under numba-cuda's simulator, and
# a few long end-to-end runs); `make test-slow` runs only those, `make test-full` everything.
# .ci/run runs test, test-slow, docs and docs-check.
test: $(STAMP) same-python
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -n 2 --dist loadfile -m "not slow_sim"

test-slow: $(STAMP) same-python
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -n 2 --dist loadfile -m slow_sim

test-full: $(STAMP) same-python
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -n 2 --dist loadfile

# Every shell line of README.md and docs/*.md, run in order in a scratch folder (tests/docs_check.py);
# `make test` runs its quick part (every line parsed, every named script's --help).
docs-check: $(STAMP) $(DOCS_STAMP)
	$(BIN)/python -m tests.docs_check

lint: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	$(BIN)/python -m ruff check .

bench: $(STAMP)
	$(BIN)/flexvox bench --quick --overwrite

# bench/gpu_check.sh dry-run against the GPU machine's image, on a machine without a GPU (bench/gpu_dry_run.sh): a
# Python 3.12 venv of that image's packages alone (.gpu-venv, bench/image_packages.txt; built once, ~4 min), the
# wheels the check carries (.whl), tiny sizes under numba-cuda's simulator, each stage's launches and bytes counted.
.PHONY: gpu-dry-run
gpu-dry-run:
	bench/gpu_dry_run.sh

screenshots: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m flexvox_app.gui.screenshots docs/screenshots

# napari draws with OpenGL, which Qt's offscreen platform lacks: a virtual X server (xvfb) and Mesa's software GL.
napari-screenshot: $(STAMP)
	xvfb-run -a -s "-screen 0 1600x1000x24" env QT_QPA_PLATFORM=xcb $(BIN)/python -m flexvox_app.napari_plugin.screenshot docs/screenshots/napari.png

# The Python guide, the examples and the API reference (Sphinx, numpydoc, MyST) into docs/_build/html; any warning
# fails it. Installs the `docs` extra into .venv on first use (a fresh clone needs nothing else).
$(DOCS_STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[docs]"
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	rm -rf docs/_build
	MPLBACKEND=Agg $(BIN)/python -m sphinx -W --keep-going -b html docs docs/_build/html

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .hypothesis docs/_build
