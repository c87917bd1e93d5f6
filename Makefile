# Two entry points: `make run` (set up, run the flagship scenario) and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
FLAGSHIP ?= scenarios/jeffcott_rigid_stator.toml
OUT ?= results/jeffcott_rigid_stator

.PHONY: setup run test fuzz lint format bench bench-stale bench-engines bench-analysis bench-basins gallery clean

setup: $(STAMP)

# setuptools announces its editable finder (the layout maps components/, fmus/ and
# orchestrator/ into rubcosim.*) with an information-only warning; that one is silenced.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	PYTHONWARNINGS='ignore:Editable installation' $(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# Compile every bundled model's engines into the cache once, in two processes that
# share the models out (make test starts with it: without it the two test workers would
# compile the same model at the same time).  make run does not: the flagship compiles
# its own model on first use, and says so.
WARM := $(VENV)/.warm-stamp
$(WARM): $(STAMP) $(wildcard components/*.py rubcosim/reference/*.py orchestrator/*.py rubcosim/analysis/*.py)
	@echo "compiling every bundled model's engines into the cache once (rubcosim warm-up)"
	$(VENV)/bin/rubcosim warm-up
	touch $(WARM)

run: $(STAMP)
	$(VENV)/bin/rubcosim run $(FLAGSHIP) --engine accurate --out $(OUT)
	$(VENV)/bin/rubcosim check $(FLAGSHIP) --out $(OUT)-check

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

test: lint $(WARM)
	$(PY) -m pytest -n 2 --dist worksteal --durations=15

# the FMI call-sequence fuzzing at length: 10000 sequences per FMU (about 20 min; the
# test run draws 60)
fuzz: $(STAMP)
	RUBCOSIM_FUZZ_EXAMPLES=10000 $(PY) -m pytest -q tests/test_fmi_sequences.py

# every benchmark the documents quote (benchmarks/catalog.py), then their tables copied
# into README.md and BENCHMARKS.md; `make bench-stale` re-runs only the stale ones
bench: $(STAMP)
	$(PY) benchmarks/catalog.py run
	$(PY) benchmarks/readme_tables.py

bench-stale: $(STAMP)
	$(PY) benchmarks/catalog.py run --stale
	$(PY) benchmarks/readme_tables.py

bench-engines: $(STAMP)
	$(PY) benchmarks/bench_engines.py --periods 200

bench-analysis: $(STAMP)
	$(PY) benchmarks/bench_analysis.py --repeats 3

bench-basins: $(STAMP)
	$(PY) benchmarks/bench_basins.py --repeats 3

gallery: $(STAMP)
	sh docs/make_gallery.sh

clean:
	rm -rf $(VENV) build results .pytest_cache
