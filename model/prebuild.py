"""Build every compiled library the toolkit uses before anything needs it (``make libraries``).

The libraries themselves are compiled and cached by :mod:`toywalk.model.compiled` when a
module first asks for its functions (:mod:`toywalk.model.engine`, the walker's;
:mod:`toywalk.model.collocation`, the fit's collocation intervals). This module lists them with
their builders and builds them side by side, ``jobs`` processes at a time; it imports both
builders, so that the compiled-library cache itself depends on neither.

Run ``python -m toywalk.model.prebuild --jobs 2``: it prints each library's seconds.
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

from . import collocation, engine
from .compiled import compiler

__all__ = ["LIBRARIES", "build_libraries"]


#: Every library the toolkit compiles, as ``(name, builder, args)`` with the builder a function
#: of ``toywalk.model.engine`` (``native_interval``, ``soft_link``: of ``toywalk.model.collocation``),
#: longest to compile first:
#: seconds on this project's 2-core machine with gcc 12 at -O1 (2026-11-27), the walker's
#: engine 49 and 10 (3D, planar), the fit's collocation intervals 38 and 22 (3D, degrees 4 and
#: 3 of the periodic and transient fits), about 1 each planar; the compliant heel strike's
#: (the ``soft_heel`` effect) 5 and 1 (3D, planar; 2026-11-28; the same again at 80 RK4 steps per
#: tau, the folded step being one), and its form in the fits'
#: collocation with first derivatives about 40 (3D; 2026-11-29).
LIBRARIES = (
    ("3D walker", "engine", (False,)),
    ("3D collocation interval, degree 4", "native_interval", (False, 4)),
    ("3D collocation interval, degree 3", "native_interval", (False, 3)),
    ("3D soft heel strike in collocation", "soft_link", (False,)),
    ("planar walker", "engine", (True,)),
    ("3D soft heel strike", "soft_heel_kernels", (False,)),
    ("3D soft heel strike, 80 steps per tau (toywalk gait's resolution check)", "soft_heel_kernels",
     (False, True, 80)),
    ("planar collocation interval, degree 4", "native_interval", (True, 4)),
    ("planar collocation interval, degree 3", "native_interval", (True, 3)),
    ("planar soft heel strike", "soft_heel_kernels", (True,)),
)


def _build(entry: tuple[str, str, tuple]) -> float:
    """Build one of :data:`LIBRARIES` (compiling it if its library is not cached); seconds taken."""
    _, builder, args = entry
    start = time.perf_counter()
    getattr(collocation if builder in ("native_interval", "soft_link") else engine, builder)(*args)
    return time.perf_counter() - start


def build_libraries(jobs: int = 2) -> dict[str, float]:
    """Compile every library in :data:`LIBRARIES` that the cache lacks, ``jobs`` at a time.

    Each process that needs a library compiles it where it is missing, so processes started
    together on an empty cache (the test suite's workers, a sampler's pool) each compile all of
    them, one after another. Built first, ``jobs`` processes share them out: on 2 cores 80-100 s
    (measured in `make test` from fresh clones, 2026-11-27) against about 120 s that each process
    would otherwise spend. With every library cached and indexed this only loads them.

    Parameters
    ----------
    jobs : int
        Processes that compile at once (one per core).

    Returns
    -------
    dict of str to float
        Seconds each library took in its process (load or compile).
    """
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    if jobs == 1 or compiler() is None:
        return {entry[0]: _build(entry) for entry in LIBRARIES}
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
        return dict(zip((entry[0] for entry in LIBRARIES), pool.map(_build, LIBRARIES), strict=True))


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(prog="python -m toywalk.model.prebuild",
                                     description="Compile every library the toolkit uses, once.")
    parser.add_argument("--jobs", type=int, default=2, help="processes compiling at once")
    for library, seconds in build_libraries(parser.parse_args().jobs).items():
        print(f"{library}: {seconds:.1f} s")
