"""Compile CasADi functions to native code once, and cache the result on disk.

The generated C source of a set of functions is hashed (SHA-256, with the compiler command); the
shared library lives under that hash in the cache folder (``$TOYWALK_CACHE``, else
``$XDG_CACHE_HOME/toywalk``, else ``~/.cache/toywalk``), so a second run loads it in milliseconds
instead of compiling again. The library is written under a temporary name and renamed into place,
so a killed compile never leaves a broken cache entry. Without a C compiler, or with
``TOYWALK_JIT=0``, the functions run in CasADi's virtual machine (same numbers; slower, by a
factor that `make bench` measures: 1.6-1.8 for one right-hand side through preallocated buffers).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca

__all__ = ["cache_dir", "compile_functions", "compile_with_derivatives"]

# -O1, not -O2: gcc 12 compiles the 3D walker's library in 43 s against 75 s (planar 9 s against
# 17 s), and its functions run as fast (a step 35.8 against 36.1 us, the final state's Jacobian
# 326 against 310 us, a fold of 64 steps 8.0 against 7.7 ms); -O0 compiles in 8 s but runs 1.6 to
# 4.5 times slower. Measured 2026-11-24 on this project's generated sources.
_CFLAGS = ("-O1", "-fPIC", "-shared", "-fno-math-errno")


def cache_dir() -> Path:
    """The folder that holds compiled libraries (created on demand)."""
    env = os.environ.get("TOYWALK_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "toywalk"


def _compiler() -> str | None:
    if os.environ.get("TOYWALK_JIT", "1") == "0":
        return None
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


def compile_functions(
    name: str, functions: dict[str, ca.Function], verbose: bool = True
) -> dict[str, ca.Function]:
    """Native versions of ``functions`` (same names, inputs and outputs), compiled once and cached.

    Parameters
    ----------
    name : str
        Stem of the generated library (for people reading the cache folder).
    functions : dict of str to casadi.Function
        The functions to compile together.
    verbose : bool
        Print one line to stderr when a compile is paid (it can take a minute).

    Returns
    -------
    dict of str to casadi.Function
        Compiled functions, or the originals when no compiler is available.
    """
    lib = _library(name, list(functions.values()), verbose)
    if lib is None:
        return dict(functions)
    return {key_: ca.external(fn.name(), str(lib)) for key_, fn in functions.items()}


def compile_with_derivatives(fn: ca.Function, verbose: bool = True) -> ca.Function:
    """A native ``fn`` that brings its own first and second derivatives, for use inside an NLP.

    CasADi differentiates an external function only through functions that its library holds
    under derivative names: ``fwd1_NAME`` and ``adj1_NAME`` (an NLP's constraint Jacobian, by
    forward directions, and its gradients) and ``fwd1_adj1_NAME`` (forward over reverse: the
    Lagrangian's Hessian). Those are generated from ``fn`` here, each with its Jacobian's
    sparsity, so that the NLP's derivative sparsity stays that of the symbolic function (without
    it every mapped call's Hessian block is taken as dense). A ``jac_NAME`` is left out: CasADi
    3.8 cannot load one generated with its sparsity, and the forward derivatives serve.
    Compiled and cached like :func:`compile_functions`; the original ``fn`` when no compiler is
    available. Second derivatives only: a third (the Hessian's Jacobian) is an error.

    Parameters
    ----------
    fn : casadi.Function
        An SX function (its derivatives are generated symbolically).
    verbose : bool
        Print one line to stderr when a compile is paid.
    """
    adj = fn.reverse(1)
    derived = [fn, fn.forward(1), adj, adj.forward(1)]
    lib = _library(f"{fn.name()}_ad", derived, verbose, with_sparsity=True)
    if lib is None:
        return fn
    return ca.external(fn.name(), str(lib), {"enable_fd": False})


def _library(name: str, functions: list[ca.Function], verbose: bool,
             with_sparsity: bool = False) -> Path | None:
    """Path of the cached shared library of ``functions`` (compiled now if missing), or None
    when there is no compiler or the compile fails."""
    cc = _compiler()
    if cc is None:
        return None
    gen = ca.CodeGenerator(f"{name}.c", {"with_header": False, "casadi_real": "double"})
    for fn in functions:
        gen.add(fn, with_sparsity)
    source = gen.dump()
    key = hashlib.sha256((source + " ".join((cc, *_CFLAGS))).encode()).hexdigest()[:20]
    folder = cache_dir()
    lib = folder / f"{name}-{key}.so"
    if not lib.exists():
        folder.mkdir(parents=True, exist_ok=True)
        if verbose:
            print(f"toywalk: compiling {name} (once; cached in {folder})", file=sys.stderr)
        with tempfile.TemporaryDirectory(dir=folder) as tmp:
            src = Path(tmp) / f"{name}.c"
            src.write_text(source)
            out = Path(tmp) / lib.name
            try:
                subprocess.run(
                    [cc, *_CFLAGS, str(src), "-o", str(out), "-lm"],
                    check=True,
                    capture_output=True,
                    text=True,
                )
            except (OSError, subprocess.CalledProcessError) as err:
                detail = getattr(err, "stderr", "") or str(err)
                print(
                    f"toywalk: compiling {name} failed, using CasADi's virtual machine: "
                    f"{detail.strip().splitlines()[-1] if detail.strip() else err}",
                    file=sys.stderr,
                )
                return None
            os.replace(out, lib)
    return lib
