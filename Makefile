# Two commands set everything up on a fresh clone: `make demo` and `make test` (`make docs` builds the site).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    := samples/out

.PHONY: demo test docs docs-pictures lint bench bench-peers bench-tiles calibrate check-gl clean

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 10))' || \
	  { echo "error: Python 3.10 or newer is needed (found $$($(PYTHON) --version))"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,docs,plot]'
	@touch $@

# Headless OpenGL needs Mesa's EGL and its software driver (llvmpipe).
check-gl:
	@ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1 ' && \
	 { ldconfig -p | grep -q 'libEGL_mesa.so.0' || ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1 || \
	   ls /usr/share/glvnd/egl_vendor.d/*nvidia* >/dev/null 2>&1; } || \
	 { echo "error: headless OpenGL (EGL) is missing. Install it with:"; \
	   echo "  sudo apt-get install -y libegl1 libgl1 libgl1-mesa-dri libegl-mesa0"; exit 1; }

# The demo runs on whatever executor `auto` finds (the CPU executor without EGL) and says which.
demo: $(STAMP)
	$(PY) -m pyramid_cli.demo $(OUT)

# OpenSeadragon and playwright-core for the viewer tests (tests/system/test_viewers_osd.py), pinned by the lock
# file; they drive the system's chromium (no browser download). Without npm those tests skip (CI must have it).
OSD := tests/helpers/osd
$(OSD)/node_modules/.installed: $(OSD)/package-lock.json
	@if command -v npm >/dev/null; then \
	   npm ci --prefix $(OSD) --no-audit --no-fund --loglevel=error && touch $@; \
	 else echo "npm is missing: the OpenSeadragon tests will skip (Node.js 20 or newer with npm runs them)"; fi

# pytest across the cores (pytest-xdist; at most 4 workers: every one holds a GL context and numba kernels).
# TEST_JOBS=0 runs the tests in this process, one after another. tests/system/test_docs.py builds the docs site as
# `make docs` does (warnings are errors), so `make test` does not build it twice.
# PYTHONDONTWRITEBYTECODE is dropped for pytest, as bench/peers.py drops it for its timings: without bytecode each
# of the ~400 `pyramid` processes the suite starts compiles the package from source (0.25 s a run, a fifth of the
# examples' time) and each worker rewrites every test module again. The caches are git-ignored.
TEST_JOBS ?= auto
test: $(STAMP) check-gl $(OSD)/node_modules/.installed
	$(PY) -m ruff check pyramid_cli tests samples scripts bench
	$(VENV)/bin/lint-imports
	$(PY) -m mypy
	env -u PYTHONDONTWRITEBYTECODE $(PY) -m pytest -n $(TEST_JOBS) --maxprocesses 4 --dist worksteal

# The Sphinx site: warnings are errors and every cross-reference must resolve (-n).
DOCS_OUT := build/docs
docs: $(STAMP)
	rm -rf docs/api/generated
	$(PY) -m sphinx -q -W --keep-going -n -b html docs $(DOCS_OUT)
	@echo "docs: $(DOCS_OUT)/index.html"

# Redraw the committed pictures of the docs (docs/_static/*.png) with the package itself, on the CPU executor.
docs-pictures: $(STAMP)
	$(PY) docs/_scripts/pictures.py docs/_static

lint: $(STAMP)
	$(PY) -m ruff check pyramid_cli tests samples scripts bench

bench: $(STAMP) check-gl
	$(PY) -m pip install -q -e '.[test,docs,plot,bench]'
	$(PY) bench/run.py

# pyramid against libvips, maketx, oiiotool and OpenCV (fresh processes, interleaved; about 10 minutes on 2 cores):
# bench/results/peers-DATE.json and .png. REPEAT=N sets the rounds, PEERS_ARGS passes more (--only, --pyramid-tree).
REPEAT ?= 5
bench-peers: $(STAMP) check-gl
	$(PY) -m pip install -q -e '.[test,docs,plot,bench]'
	$(PY) bench/peers.py --repeat $(REPEAT) $(PEERS_ARGS)

# `pyramid tiles` against libvips `dzsave` and `tiffsave --tile --pyramid` (issue 27): a zone plate's levels against
# the ideal reduction, then time and peak memory at 8K and 16K and ours alone at 32K (fresh processes, interleaved;
# about 10 minutes on 2 cores): bench/results/tiles-DATE.json and .png. TILES_ARGS passes more (--only, --sizes,
# --pyramid-tree); `pyramid tiles` missing from the checkout leaves its rows "not available".
bench-tiles: $(STAMP)
	$(PY) -m pip install -q -e '.[test,docs,plot,bench]'
	$(PY) bench/tiles.py --repeat $(REPEAT) $(TILES_ARGS)

# Re-measure the planner's cost model on this machine's GL (about a minute) and
# check the docs' fetch table against the new model.
calibrate: $(STAMP) check-gl
	$(PY) bench/calibrate.py --write
	$(PY) scripts/fetch_table.py --check || echo "docs/performance.md's fetch table changed: update it with $(PY) scripts/fetch_table.py"

clean:
	rm -rf $(VENV) $(OUT) build docs/api/generated *.egg-info $(OSD)/node_modules
