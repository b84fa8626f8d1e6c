"""Compile CasADi functions to native code once, and cache the result on disk.

The generated C source of a set of functions is hashed (SHA-256, with the compiler command); the
shared library lives under that hash in the cache folder (``$TOYWALK_CACHE``, else
``$XDG_CACHE_HOME/toywalk``, else ``~/.cache/toywalk``), so a second run loads it in milliseconds
instead of compiling again. The library is written under a temporary name and renamed into place,
so a killed compile never leaves a broken cache entry.

Finding a library by the hash of its code means building the symbolic functions and generating
their code first: 1.0-1.5 s a process for the 3D walker and its collocation intervals, paid by
every command and every worker process. :func:`cached_functions` and
:func:`cached_with_derivatives` skip that: an index file, keyed by a hash of this package's
Python sources, CasADi's version and the compiler's command, names the library those sources
generate. Any change to the model's code gives another key, and the slow way is taken once
(and the index written again). Without a C compiler, or with
``TOYWALK_JIT=0``, the functions run in CasADi's virtual machine (same numbers; slower, by a
factor that `make bench` measures: 1.6-1.8 for one right-hand side through preallocated buffers).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from functools import cache
from pathlib import Path

import casadi as ca

__all__ = ["cache_dir", "cached_functions", "cached_with_derivatives", "compile_functions",
           "compile_with_derivatives", "compiler"]

# -O1, not -O2: gcc 12 compiles the 3D walker's library in 43 s against 75 s (planar 9 s against
# 17 s), and its functions run as fast (a step 35.8 against 36.1 us, the final state's Jacobian
# 326 against 310 us, a fold of 64 steps 8.0 against 7.7 ms); -O0 compiles in 8 s but runs 1.6 to
# 4.5 times slower. Measured 2026-11-24 on this project's generated sources.
_CFLAGS = ("-O1", "-fPIC", "-shared", "-fno-math-errno")
#: Options of an external function that brings its own derivatives: never finite differences.
_WITH_DERIVATIVES = {"enable_fd": False}


def cache_dir() -> Path:
    """The folder that holds compiled libraries (created on demand)."""
    env = os.environ.get("TOYWALK_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "toywalk"


def compiler() -> str | None:
    """The C compiler's command (``$CC``, else ``gcc``, else ``cc`` on the path), or None where
    there is none or ``TOYWALK_JIT=0``: then the functions run in CasADi's virtual machine."""
    if os.environ.get("TOYWALK_JIT", "1") == "0":
        return None
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


@cache
def _sources_digest() -> str:
    """SHA-256 of this package's Python sources (the code that builds every compiled function)."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def _index(name: str, variant: str, cc: str) -> Path:
    """The index file naming the library that this package's sources give ``name, variant``."""
    key = " | ".join((_sources_digest(), ca.__version__, f"{sys.version_info[:2]}", cc, *_CFLAGS,
                      name, variant))
    return cache_dir() / f"{name}-{hashlib.sha256(key.encode()).hexdigest()[:20]}.index.json"


def _from_index(index: Path) -> dict[str, ca.Function] | None:
    """The functions an index names, loaded from its library; None when either is missing or
    unreadable (the caller then builds them)."""
    try:
        entry = json.loads(index.read_text())
        lib = index.parent / entry["library"]
        if not lib.is_file():
            return None
        return {key: ca.external(fn_name, str(lib), entry["options"])
                for key, fn_name in entry["functions"].items()}
    except (OSError, ValueError, KeyError, TypeError, RuntimeError):
        return None


def _write_index(index: Path, lib: Path, functions: dict[str, str], options: dict) -> None:
    """Write the index atomically; where the cache cannot be written (a shared, read-only cache
    of compiled libraries) there is none, and each process builds the functions to find them."""
    text = json.dumps({"library": lib.name, "functions": functions, "options": options})
    tmp = None
    try:
        with tempfile.NamedTemporaryFile("w", dir=index.parent, delete=False, suffix=".tmp") as f:
            tmp = f.name
            f.write(text)
        os.replace(tmp, index)
    except OSError:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)


def cached_functions(name: str, variant: str, build: Callable[[], dict[str, ca.Function]],
                     verbose: bool = True) -> dict[str, ca.Function]:
    """:func:`compile_functions` of ``build()``, without calling ``build`` when a library that
    this package's sources generate for ``name, variant`` is cached.

    Parameters
    ----------
    name : str
        Stem of the library.
    variant : str
        What distinguishes this set among those of one ``name`` (the arguments of its builder).
    build : callable
        Returns the functions to compile (symbolic), as for :func:`compile_functions`.
    verbose : bool
        Print one line to stderr when a compile is paid.
    """
    return _cached(name, variant, build,
                   lambda functions: _library(name, list(functions.values()), verbose), {})


def cached_with_derivatives(variant: str, build: Callable[[], ca.Function],
                            verbose: bool = True, curvature: bool = True) -> ca.Function:
    """:func:`compile_with_derivatives` of ``build()``, without calling ``build`` when its
    library is cached (as :func:`cached_functions`; ``variant`` names the builder's arguments).

    ``curvature`` False: the second derivative the library brings is zero (its forward over
    reverse function returns zeros), so that an NLP's Lagrangian Hessian leaves out this
    function's own curvature, as a Gauss-Newton method does, where computing it would cost more
    than the iterations it saves. The first derivatives, and so the NLP's solution and its
    convergence test, are exact."""
    return _cached("derivatives", variant + ("" if curvature else " curvature=0"), lambda: {"fn": build()},
                   lambda functions: _derivatives_library(functions["fn"], verbose, curvature),
                   _WITH_DERIVATIVES)["fn"]


def _cached(name: str, variant: str, build: Callable[[], dict[str, ca.Function]],
            library: Callable[[dict[str, ca.Function]], Path | None],
            options: dict) -> dict[str, ca.Function]:
    """The functions ``build`` gives, loaded with ``options`` from the library that the index of
    ``name, variant`` names; else built, their library found or compiled by ``library`` (None:
    no compiler, the built functions serve) and the index written."""
    cc = compiler()
    if cc is None:
        return dict(build())
    index = _index(name, variant, cc)
    found = _from_index(index)
    if found is not None:
        return found
    functions = build()
    lib = library(functions)
    if lib is None:
        return dict(functions)
    names = {key_: fn.name() for key_, fn in functions.items()}
    _write_index(index, lib, names, options)
    return {key_: ca.external(fn_name, str(lib), options) for key_, fn_name in names.items()}


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
    lib = _derivatives_library(fn, verbose)
    if lib is None:
        return fn
    return ca.external(fn.name(), str(lib), _WITH_DERIVATIVES)


def _derivatives_library(fn: ca.Function, verbose: bool, curvature: bool = True) -> Path | None:
    """The cached library of ``fn`` and its first and second derivatives (as
    :func:`compile_with_derivatives` describes; without ``curvature`` the second is zero,
    :func:`cached_with_derivatives`), or None without a compiler."""
    adj = fn.reverse(1)
    second = adj.forward(1)
    if not curvature:
        inputs = [ca.MX.sym(second.name_in(i), second.sparsity_in(i)) for i in range(second.n_in())]
        zeros = [ca.MX(second.size1_out(i), second.size2_out(i)) for i in range(second.n_out())]
        second = ca.Function(second.name(), inputs, zeros, second.name_in(), second.name_out())
    derived = [fn, fn.forward(1), adj, second]
    return _library(f"{fn.name()}_ad" + ("" if curvature else "_gn"), derived, verbose, with_sparsity=True)


def _library(name: str, functions: list[ca.Function], verbose: bool,
             with_sparsity: bool = False) -> Path | None:
    """Path of the cached shared library of ``functions`` (compiled now if missing), or None
    when there is no compiler or the compile fails."""
    cc = compiler()
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
