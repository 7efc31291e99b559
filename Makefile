# hingelab — the two commands: `make demo` (set up + main job) and `make test` (set up + tests).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out/demo

.PHONY: demo test test-all lint bench clean crosscheck

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/hingelab cycle --out $(OUT)

# pytest exits 5 when it collected no test: that must fail, not pass silently.
test: $(STAMP)
	$(BIN)/python -m pytest -q; rc=$$?; if [ $$rc -eq 5 ]; then echo "no tests ran" >&2; exit 1; fi; exit $$rc

test-all: $(STAMP)
	$(BIN)/python -m pytest -q -m "slow or not slow"

lint: $(STAMP)
	$(BIN)/ruff check cad mesh fe model rsm studies validation tests
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b; done

# Our loops against CalculiX on the same mesh (docs/calculix_crosscheck.md); installs ccx if missing.
crosscheck: $(STAMP)
	@command -v ccx >/dev/null || { echo "ccx missing: installing CalculiX with apt-get (needs root)"; \
		apt-get update && apt-get install -y calculix-ccx; }
	$(BIN)/python -m pytest -q -m "slow or not slow" tests/fe/interop/test_inp.py tests/fe/interop/test_ccx_crosscheck.py

clean:
	rm -rf $(VENV) out .pytest_cache
