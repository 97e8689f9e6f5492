# Quick start: `make demo` and `make test`. Both set up everything they need first.
VENV   := .venv
PY     := $(VENV)/bin/python
OUT    ?= out/humvvex
SPP    ?=

.PHONY: setup demo test test-fast test-extended lint format bench schemas screenshots docs docs-data gallery clean

setup:
	@./tools/setup.sh

demo: setup
	@$(VENV)/bin/humv-usd compose examples/humvvex.toml -o $(OUT)
	@# --force: a re-run after an update or a scenario edit renders again (without it, images of
	@# other settings or another stage are refused, as they should be for a user's own folders)
	@$(VENV)/bin/humv-usd render $(OUT)/stage.usda -o $(OUT)/render --force $(if $(SPP),--spp $(SPP))
	@echo "demo: stage at $(OUT)/stage.usda, images in $(OUT)/render (see manifest.json there)"

# two worker processes (pytest-xdist, whole files per worker: module fixtures built once), one
# BLAS thread each (two workers on two cores: OpenBLAS's own threads only contend)
TEST_WORKERS ?= 2
test: setup
	@OPENBLAS_NUM_THREADS=1 $(PY) -m pytest -q -m "not extended" -n $(TEST_WORKERS) --dist loadfile

# the long end-to-end checks left out of `make test` (each has a cheaper check in the suite)
test-extended: setup
	@$(PY) -m pytest -q -m extended

# everything but the tests marked slow (renders, end-to-end CLI runs, JOS-3, Blender)
test-fast: setup
	@$(PY) -m pytest -q -m "not slow and not extended"

lint: setup
	@$(VENV)/bin/ruff check humv_usd tests tools
	@$(VENV)/bin/ruff format --check humv_usd tests tools

format: setup
	@$(VENV)/bin/ruff check --fix humv_usd tests tools
	@$(VENV)/bin/ruff format humv_usd tests tools

bench: setup
	@$(VENV)/bin/humv-usd bench pipeline examples/humvvex.toml $(if $(SPP),--spp $(SPP))

schemas: setup
	@$(PY) tools/gen_schemas.py

# the editor's tabs on examples/humvvex.toml (headless chromium) -> docs/editor/<tab>.png
screenshots: setup
	@$(PY) tools/editor_screenshots.py docs/editor

# the manual (docs/, Sphinx + MyST + furo): reference pages generated from the sources at build
# time (-E: read every page again, so code changes show); warnings are errors, every
# cross-reference must resolve (-n); offline
docs: setup
	@$(PY) -m sphinx -E -W --keep-going -n -q -b html docs build/docs/html
	@echo "docs: build/docs/html/index.html"

# the physics pages' bench data: error against run time from the project's benches (render, q_rad,
# time steps; a few minutes, niced) -> docs/physics/data/*.csv (commit them; make docs plots them)
docs-data: setup
	@nice -n 10 $(PY) docs/_ext/bench_data.py

# the manual's gallery: every imager of the examples at 1/4 size, with label overlays
# -> docs/gallery/ (commit the PNGs and gallery.json; make docs shows them)
gallery: setup
	@$(PY) docs/_ext/gallery.py

clean:
	rm -rf out .pytest_cache
