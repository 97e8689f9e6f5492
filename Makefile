# Quick start: `make demo` and `make test`. Both set up everything they need first.
VENV   := .venv
PY     := $(VENV)/bin/python
OUT    ?= out/humvvex
SPP    ?= 16

.PHONY: setup demo test test-fast bench schemas clean

setup:
	@./tools/setup.sh

demo: setup
	@$(VENV)/bin/humv-usd compose examples/humvvex.toml -o $(OUT)
	@$(VENV)/bin/humv-usd render $(OUT)/stage.usda -o $(OUT)/render --spp $(SPP)
	@echo "demo: stage at $(OUT)/stage.usda, images in $(OUT)/render (see manifest.json there)"

test: setup
	@$(PY) -m pytest -q

bench: setup
	@$(VENV)/bin/humv-usd bench pipeline examples/humvvex.toml --spp $(SPP)

schemas: setup
	@$(PY) tools/gen_schemas.py

clean:
	rm -rf out .pytest_cache
