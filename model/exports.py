"""Public names of a package that load their submodule on first use (PEP 562), one piece for
every package of toywalk: a tool that only reads files does not import CasADi."""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable

__all__ = ["lazy_names"]


class _Package(types.ModuleType):
    """A package whose public names keep their meaning when a submodule of the same name is
    imported: the import system sets the package's attribute to the submodule once it has run
    (``toywalk.model.simulate``, the module, over ``simulate``, the function), and
    ``from toywalk.model import simulate`` would then give the module, depending on which import
    came first."""

    _shadowed: frozenset = frozenset()

    def __setattr__(self, name, value):
        if (name in self._shadowed and isinstance(value, types.ModuleType)
                and value.__name__ == f"{self.__name__}.{name}"):
            value = getattr(value, name)
        super().__setattr__(name, value)


def lazy_names(package: str, where: dict, namespace: dict) -> tuple[Callable, Callable]:
    """The package's ``__getattr__`` and ``__dir__``: each name of ``where`` (name -> submodule)
    is imported from its submodule when first asked for and kept in ``namespace`` (the package's
    globals). A name that is also its submodule's (``simulate``) stays the name's object when the
    submodule is imported (:class:`_Package`)."""
    module = sys.modules[package]
    module.__class__ = _Package
    module._shadowed = frozenset(name for name, sub in where.items() if name == sub)

    def __getattr__(name: str):
        if name in where:
            value = getattr(importlib.import_module(f".{where[name]}", package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(namespace) | set(where))

    return __getattr__, __dir__
