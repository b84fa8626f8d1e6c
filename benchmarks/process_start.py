"""A new process's time to its compiled kernels: through the cache's index against the naive way.

Run ``.venv/bin/python benchmarks/process_start.py`` (``make bench`` runs it too). It writes
``benchmarks/results/process_start.json`` and prints one line.

Every command, and every worker process of ``sample`` and ``diagnose``, starts by getting the
compiled 3D walker's kernels and the periodic fit's collocation interval. With their libraries in
the cache it can get them two ways:

- ``indexed``: through the index that :func:`toywalk.model.compiled.cached_functions` keeps, keyed
  by a hash of the model package's sources: the libraries are loaded, nothing is built;
- ``built`` (the naive way, and what every process did before the index): build the symbolic
  functions and generate their C code, hash it, and load the library of that hash.

Fresh interpreters, the two ways alternated, ``ROUNDS`` rounds; each reports the seconds from its
first toywalk import (CasADi's import included) to the loaded functions. The libraries are built
first if the cache lacks them. The machine may be shared: compare the ratio within one run.
"""

from __future__ import annotations

import datetime
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "process_start.json"
ROOT = HERE.parent
ROUNDS = 7

INDEXED = """
import time
t = time.perf_counter()
from toywalk.model.collocation import native_interval
from toywalk.model.engine import engine
engine(False)
native_interval(False, 4)
print(time.perf_counter() - t)
"""
BUILT = """
import time
t = time.perf_counter()
from toywalk.model.collocation import interval_equations
from toywalk.model.compiled import compile_functions, compile_with_derivatives
from toywalk.model.engine import _kernel_functions
compile_functions("walker3d", _kernel_functions(False, True))
compile_with_derivatives(interval_equations(False, 4))
print(time.perf_counter() - t)
"""


def once(code: str) -> float:
    """Seconds a fresh interpreter running ``code`` reports."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> dict:
    t0 = time.perf_counter()
    once(BUILT)  # compiles the libraries if the cache lacks them
    once(INDEXED)  # writes their index
    indexed, built = [], []
    for _ in range(ROUNDS):
        built.append(once(BUILT))
        indexed.append(once(INDEXED))
    res = {"timestamp_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
           "cpu_count": os.cpu_count(), "rounds": ROUNDS, "indexed_s": indexed, "built_s": built,
           "indexed_median_s": float(np.median(indexed)), "built_median_s": float(np.median(built)),
           "ratio_median": float(np.median(built) / np.median(indexed))}
    res["total_run_time_s"] = time.perf_counter() - t0
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(RESULTS, res)
    print(f"a new process's 3D kernels (walker, collocation interval), median of {ROUNDS}: "
          f"{res['indexed_median_s'] * 1e3:.0f} ms through the cache's index, "
          f"{res['built_median_s'] * 1e3:.0f} ms built to find them ({res['ratio_median']:.1f}x)")
    print(f"wrote {RESULTS.relative_to(ROOT)} in {res['total_run_time_s']:.0f} s")
    return res


if __name__ == "__main__":
    main()
