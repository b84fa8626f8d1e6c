# One command each: `make demo`, `make test` (`make test-fast` without the slow cases), `make bench`.
# Each creates .venv on first use.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/toywalk demo

# Two processes, one per core (the tests are single-threaded CasADi and NumPy work); a file's
# tests stay in one process so that its module fixtures are built once.
test: $(STAMP)
	$(PY) -m pytest -q -n 2 --dist loadfile --durations=25

# The suite less its cases marked slow (end-to-end analyses, rendered videos): a quick check while
# working; `make test` (and CI) runs everything.
test-fast: $(STAMP)
	$(PY) -m pytest -q -n 2 --dist loadfile -m "not slow"

bench: $(STAMP)
	$(PY) benchmarks/run_all.py
	$(PY) benchmarks/track_accuracy.py
	$(PY) benchmarks/marker_layouts.py
	$(PY) benchmarks/corner_errors.py
	$(PY) benchmarks/corner_errors.py --lossless
	$(PY) benchmarks/sample_speed.py
	$(PY) benchmarks/diagnose_speed.py

lint: $(STAMP)
	$(VENV)/bin/ruff check model tracking sysid tests benchmarks

clean:
	rm -rf $(VENV) build *.egg-info
