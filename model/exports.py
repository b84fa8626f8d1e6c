"""Public names of a package that load their submodule on first use (PEP 562), one piece for
every package of toywalk: a tool that only reads files does not import CasADi."""

from __future__ import annotations

import importlib
from collections.abc import Callable

__all__ = ["lazy_names"]


def lazy_names(package: str, where: dict, namespace: dict) -> tuple[Callable, Callable]:
    """The package's ``__getattr__`` and ``__dir__``: each name of ``where`` (name -> submodule)
    is imported from its submodule when first asked for and kept in ``namespace`` (the package's
    globals)."""

    def __getattr__(name: str):
        if name in where:
            value = getattr(importlib.import_module(f".{where[name]}", package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(namespace) | set(where))

    return __getattr__, __dir__
