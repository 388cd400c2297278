# fem_grasp — every target sets itself up; stamps in .stamps/ keep re-runs quick.
SHELL := /bin/bash
SYSPY := /usr/bin/python3
VENV := .venv
PY := $(VENV)/bin/python
STAMPS := .stamps
# Debian packages: dolfinx 0.5.2 and gmsh for /usr/bin/python3 (verification, meshing),
# venv/pip, and SuiteSparse + OpenBLAS for the optional CHOLMOD backend.
APT_PACKAGES := python3-dolfinx python3-gmsh python3-venv python3-pip python3-dev \
                libsuitesparse-dev libopenblas0-pthread
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
PYTEST_ARGS ?=

.PHONY: setup test test-pip docs lint demo verify verify-quick meshes spectral-vs-sparse rest-table grasp-height pinned-reference clean-venv paper-scenes converge

setup: $(STAMPS)/venv

$(STAMPS)/apt:
	@mkdir -p $(STAMPS)
	@if dpkg -s $(APT_PACKAGES) >/dev/null 2>&1; then echo "apt: packages already installed"; else \
	  echo "apt: installing $(APT_PACKAGES)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $(APT_PACKAGES) >/dev/null; fi
	@touch $@

# The venv sees Debian's dolfinx and gmsh; numpy stays at Debian's version, which dolfinx was built against.
# Not the [mesh] extra: Debian's gmsh is no pip distribution, so pip would add PyPI's gmsh in front of it (another
# version than the one the committed meshes and the mesh cache were made with).
$(STAMPS)/venv: $(STAMPS)/apt pyproject.toml
	$(SYSPY) -m venv --system-site-packages $(VENV)
	$(SYSPY) -c "import numpy; print('numpy==' + numpy.__version__)" > $(STAMPS)/constraints.txt
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c $(STAMPS)/constraints.txt -e ".[dev,report,fast,docs,xdmf,examples,search]"
	@# scikit-sparse compiled against Debian's SuiteSparse and the pinned numpy (no build isolation, so Cython comes
	@# first): fem_grasp calls libcholmod itself; the floor benchmark and the friction reference use scikit-sparse.
	$(PY) -m pip install -q -c $(STAMPS)/constraints.txt "cython>=0.29" setuptools wheel && \
	  $(PY) -m pip install -q -c $(STAMPS)/constraints.txt --no-build-isolation -e ".[cholmod]" \
	  || echo "WARNING: scikit-sparse did not build (fem_grasp calls libcholmod directly; the floor benchmark needs it)"
	$(PY) -c "import dolfinx, gmsh, numpy; print('venv ok: dolfinx', dolfinx.__version__, 'numpy', numpy.__version__)"
	@# Compile the numba kernels once here (cached), not in the first pickup.
	$(PY) -c "from fem_grasp.contact import warm_up; from fem_grasp.contact.kernels import jit; t = warm_up(); print('inner loops:', jit.backend_name(), f'(compiled in {t:.1f} s)')"
	@touch $@

test: setup
	$(PY) -m pytest $(PYTEST_ARGS)

.PHONY: test-pip
# The plain pip route, as a user without Debian's packages takes it: a wheel of the package installed with the
# [dev] extra (pytest, hypothesis, ruff) into a fresh venv without system site packages, made from a Python that
# is not Debian's (PIP_PYTHON, default: the python3 first on PATH). From a folder outside the source tree:
# `fem-grasp --version`, a one-level pickup of the shipped tomato (its committed mesh, no gmsh; plain-Python
# kernels, no numba) and the test suite against the installed wheel (a copy of tests/ and of the README, whose
# snippets it runs; fem_grasp must come from the venv). No extra is installed, so the tests of gmsh, numba, pyvista, dask/pandas, dolfinx and of the
# verification/bench/examples/scripts folders skip, each saying why (tests/conftest.py). The tests marked slow are
# left out (-m "not slow"): on the plain-Python kernels they take more than 10 minutes each (a pickup test rerun
# under OpenBLAS's oldest kernels); the rest takes about 10 minutes on 2 cores.
PIP_PYTHON ?= $(shell command -v python3)
PIP_VENV := $(STAMPS)/pip-venv
PIP_WHEELS := $(STAMPS)/pip-wheels
test-pip:
	@if [ -z "$(PIP_PYTHON)" ] || [ "$$(readlink -f "$(PIP_PYTHON)")" = "$$(readlink -f $(SYSPY))" ]; then \
	  echo "test-pip: PIP_PYTHON='$(PIP_PYTHON)' must be a Python other than Debian's $(SYSPY) (make test-pip PIP_PYTHON=...)"; \
	  exit 2; fi
	rm -rf $(PIP_VENV) $(PIP_WHEELS)
	"$(PIP_PYTHON)" -m venv $(PIP_VENV)
	$(PIP_VENV)/bin/python -m pip install -q --upgrade pip
	$(PIP_VENV)/bin/python -m pip wheel -q --no-deps -w $(PIP_WHEELS) .
	$(PIP_VENV)/bin/python -m pip install -q "$$(ls $(PIP_WHEELS)/fem_grasp-*.whl)[dev]"
	@venv="$(abspath $(PIP_VENV))"; tmp="$$(mktemp -d)"; trap 'rm -rf "$$tmp"' EXIT; \
	  cp -r tests pyproject.toml README.md "$$tmp"/ && cd "$$tmp" && set -x && \
	  "$$venv/bin/python" -c "import sys, fem_grasp; print('fem_grasp', fem_grasp.__version__, 'from', \
	    fem_grasp.__file__); sys.exit(not fem_grasp.__file__.startswith('$$venv/'))" && \
	  "$$venv/bin/fem-grasp" --version && \
	  { "$$venv/bin/fem-grasp" run tomato --accuracy off --no-cache --out run-tomato; [ $$? -le 1 ]; } && \
	  test -s run-tomato/result.json && \
	  FEM_GRASP_INSTALLED=1 "$$venv/bin/python" -m pytest -p no:cacheprovider -m "not slow" $(PYTEST_ARGS) tests

# The API reference from the docstrings and docs/*.md: docs/_build/html/index.html. A docstring that
# does not render (bad reStructuredText) fails the build.
docs: setup
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "Look at:  docs/_build/html/index.html"

# Unused or undefined names and import order (ruff); the floors of the package are checked by the tests.
lint: setup
	$(PY) -m ruff check fem_grasp tests verification bench scripts examples

# The tomato scene end to end: result.json, a ParaView time series and report.html in out/tomato.
DEMO_SCENE ?= tomato
demo: setup
	$(PY) -m fem_grasp run $(DEMO_SCENE) --out out/$(DEMO_SCENE) --report $(DEMO_ARGS); status=$$?; \
	  if [ $$status -gt 1 ]; then exit $$status; fi; \
	  echo; echo "Look at:  out/$(DEMO_SCENE)/report.html   (pictures, w(rho), event timeline)"; \
	  echo "          out/$(DEMO_SCENE)/object.pvd    (ParaView; with finger1.pvd, finger2.pvd, table.vtu)"; \
	  echo "          out/$(DEMO_SCENE)/result.json   (summary, events, forces)"; \
	  echo "Other scenes: $(PY) -m fem_grasp scenes;  quick variant: make demo DEMO_ARGS=--quick"

# Every study of the verification (python -m verification --help lists them): cross-checks against dolfinx,
# manufactured solutions, locking, stability, Hertz, round-off, random scenes, the pickup convergence study (hours
# from an empty cache), the frictional-contact reference and the softness study; writes
# verification/out/report.html and summary.json. verify-quick: about 10 minutes.
verify: setup
	$(PY) -m verification all

verify-quick: setup
	$(PY) -m verification all --quick

.PHONY: friction-reference softness
# One scene against the independent frictional-contact reference (exit 1 when they disagree), and the Table III
# study (softness against the rigid grasp); both studies are part of `make verify` too.
SCENE ?= tomato
friction-reference: setup
	$(PY) -m verification friction compare $(SCENE) $(FRICTION_ARGS)

softness: setup
	@mkdir -p verification/out
	$(PY) -m verification softness --fine --json verification/out/softness.json --plot verification/out/softness.png

meshes: setup
	$(PY) scripts/make_meshes.py

spectral-vs-sparse: setup
	$(PY) scripts/spectral_vs_sparse.py

# How rho* depends on the grasp's height (the steam bun by default; GRASP_HEIGHT_ARGS="tomato --offsets -2 0 2").
grasp-height: setup
	$(PY) scripts/grasp_height.py $(GRASP_HEIGHT_ARGS)

# The answer at the placement rule's own grasp points: uniform meshes with them as nodes, the loop beside
# (the tomato by default; PINNED_ARGS="orange --vertices 19200 38400 --divisions 4 --write-reference").
pinned-reference: setup
	$(PY) scripts/pinned_reference.py $(PINNED_ARGS)

# The rest table of the guide: printed, and written between its markers in docs/physics.md.
rest-table: setup
	$(PY) scripts/rest_table.py --into docs/physics.md

.PHONY: search
# Where to grasp: a placement search on the local cores (Dask), out/search-tomato/report.html and results.parquet.
SEARCH_SCENE ?= tomato
SEARCH_CANDIDATES ?= 64
search: setup
	$(PY) -m fem_grasp search $(SEARCH_SCENE) --candidates $(SEARCH_CANDIDATES) --out out/search-$(SEARCH_SCENE) $(SEARCH_ARGS); \
	  status=$$?; if [ $$status -gt 1 ]; then exit $$status; fi

.PHONY: bench
# Benchmarks (bench/README.md): contact solve against dolfinx, cost against vertex count (1k-100k), per-object
# pickups, sparse against spectral, compiled against plain kernels, column batches, the floor of the method (flops
# against the dense peak; about 10 GiB at 100k), the placement search serially and on Dask (section search), the
# time to a 10/5/2 % answer (section converge, from the cached study of `make converge`), and the pickup engine
# against a baseline commit side by side (section tracker; BENCH_ARGS="--only tracker --baseline REV"), and each
# shipped scene's actual error against the study's reference, one run, as shipped and adaptive at 5 % (section
# accuracy; objects without a cached reference are skipped); tables on
# stdout and bench/out/bench.json (long: shorter with BENCH_ARGS="--max-vertices 10000").
bench: setup
	$(PY) -m bench.bench $(BENCH_ARGS)

.PHONY: converge
# The pickup answer (verdict, rho*, finger forces, patches, w(rho)) of the five shipped scenes under
# uniform and graded refinement, halved increments and seeds, and the adaptive accuracy loop; one subprocess per
# run, cached in verification/out/converge/cache (a re-run only reads). Tables on stdout, converge.json and plots
# in verification/out/converge. From an empty cache: hours on 2 cores (CONVERGE_ARGS=--quick: minutes).
converge: setup
	$(PY) -m verification converge $(CONVERGE_ARGS)

.PHONY: paper
# Our figures beside the paper's Tables II and III: one process per object (logs in out/paper/), then the tables.
paper: setup
	@mkdir -p out/paper
	@for o in tomato orange steam_bun football; do \
	  $(PY) -m fem_grasp.paper --objects $$o --json out/paper/$$o.json > out/paper/$$o.log 2>&1 & done; wait
	$(PY) -m fem_grasp.paper --merge out/paper/*.json

.PHONY: paper-scenes
# The table of docs/physics.md ("The paper's objects"): Table I's moduli as printed, and the paper scenes' effective moduli (no search).
paper-scenes: setup
	@mkdir -p out/paper-scenes
	@for o in tomato orange steam_bun football; do \
	  $(PY) -m fem_grasp.paper --objects $$o --no-search --young scene --json out/paper-scenes/$$o.json \
	    > out/paper-scenes/$$o.log 2>&1 & done; wait
	$(PY) -m fem_grasp.paper --merge out/paper-scenes/*.json

clean-venv:
	rm -rf $(VENV) $(STAMPS)
