# One command each: `make demo`, `make test` (`make test-fast` without the slow cases), `make bench`.
# Each creates .venv on first use.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast bench lint clean libraries

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# The compiled libraries, built side by side before anything needs them: processes started
# together on an empty cache would each compile all of them (about 2 minutes each on 2 cores,
# against 80-100 s shared out; under a second once cached).
libraries: $(STAMP)
	$(PY) -m toywalk.model.prebuild --jobs 2

demo: libraries
	$(VENV)/bin/toywalk demo

# Two processes, one per core (the tests are single-threaded CasADi and NumPy work); a file's
# tests stay in one process so that its module fixtures are built once. One BLAS thread each:
# with the cores taken, OpenBLAS's threads only wait (a three-walk diagnosis, one process: 95 s
# of CPU with them, 72 s without; 2026-11-27).
ONE_THREAD := OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
test: libraries
	$(ONE_THREAD) $(PY) -m pytest -q -n 2 --dist loadfile --durations=25

# The suite less its cases marked slow (end-to-end analyses, rendered videos): a quick check while
# working; `make test` (and CI) runs everything.
test-fast: libraries
	$(ONE_THREAD) $(PY) -m pytest -q -n 2 --dist loadfile -m "not slow"

bench: libraries
	$(PY) benchmarks/run_all.py
	$(PY) benchmarks/track_accuracy.py
	$(PY) benchmarks/marker_layouts.py
	$(PY) benchmarks/corner_errors.py
	$(PY) benchmarks/corner_errors.py --lossless
	$(PY) benchmarks/sample_speed.py
	$(PY) benchmarks/diagnose_speed.py
	$(PY) benchmarks/transient_speed.py
	$(PY) benchmarks/fit_speed.py
	$(PY) benchmarks/process_start.py
	$(ONE_THREAD) $(PY) benchmarks/soft_heel_speed.py
	$(ONE_THREAD) $(PY) benchmarks/sindy_comparison.py

lint: $(STAMP)
	$(VENV)/bin/ruff check model tracking sysid tests benchmarks

clean:
	rm -rf $(VENV) build *.egg-info
