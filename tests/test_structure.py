"""The package's structure, read statically from its source (``ast``, nothing imported): no new
import cycle, no new import inside a function that closes one, and no new import of another
module's private name. What two modules share is a public, documented name of one of them; an
import cycle, even one put off into a function, is a sign that a piece lives in the wrong module:
move it (a list both modules need to a module of its own, shared result types to theirs). And no
test file imports from another: what they share lives in helper modules (tests/README.md).

The modules are those of ``model/``, ``tracking/`` and ``sysid/`` (``toywalk.model``, ...). An
import is *module-level* when it runs as the module is imported: at the top, or inside an ``if``,
``try``, ``with`` or class body there (not under ``if TYPE_CHECKING:``); an import inside a function
is *deferred*. A cycle is a strongly connected component of the graph of module-level imports
(``from toywalk.model import Walker`` is an edge to the package ``toywalk.model``, not to the
module its lazy ``__getattr__`` loads: imports through ``importlib`` are not seen). A deferred
import *closes a cycle* when the module it imports reaches the importing module through
module-level imports: it is a cycle put off to run time. A private import is a name starting with
one underscore (not a dunder) taken from another module of the package, by ``from M import _name``
or as ``m._name`` of a module ``m`` imported by name.

Each of the three has an explicit list below of the ones that exist today, each with what removes
it. A new one fails its test, and so does a listed one that no longer exists: remove it from the
list, which only shrinks.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

from .conftest import ROOT

#: Source folder and the package it installs as (pyproject.toml, [tool.setuptools.package-dir]).
PACKAGES = {"model": "toywalk.model", "tracking": "toywalk.tracking", "sysid": "toywalk.sysid"}

#: Import cycles of module-level imports today, each by its modules (sorted), and what removes it.
KNOWN_CYCLES: dict[tuple[str, ...], str] = {}

#: Imports inside a function that close a cycle today: (importing module, imported module).
KNOWN_DEFERRED_CYCLES: dict[tuple[str, str], str] = {}

#: Private names imported from another module today: (importing module, defining module, name).
KNOWN_PRIVATE_IMPORTS: dict[tuple[str, str, str], str] = {}


# ------------------------------------------------------------------------------ reading the source
def _module_files() -> dict[str, Path]:
    """Every module of the package, by its dotted name."""
    modules = {}
    for folder, package in PACKAGES.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join([package, *parts])] = path
    return modules


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _import_statements(nodes, deferred: bool):
    """(import statement, deferred) for every import under ``nodes``, ``deferred`` once inside a
    function; those under ``if TYPE_CHECKING:`` never run and are left out."""
    for node in nodes:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node, deferred
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            yield from _import_statements(ast.iter_child_nodes(node), True)
        elif isinstance(node, ast.If) and _is_type_checking(node):
            yield from _import_statements(node.orelse, deferred)
        else:
            yield from _import_statements(ast.iter_child_nodes(node), deferred)


def _imports(module: str, text: str, modules) -> tuple[dict[str, bool], dict[tuple[str, str], int]]:
    """What ``module`` (source ``text``) imports of the package whose modules are ``modules``
    (dotted names; a package's own name stands for its ``__init__.py``, and ``P.__init__`` is
    among them for each package P).

    Returns
    -------
    (dict, dict)
        Each imported module and whether every import of it is deferred; each private name taken
        from another module, (defining module, name), and the line it is taken on.
    """
    tree = ast.parse(text)
    own_package = module if f"{module}.__init__" in modules else module.rpartition(".")[0]
    edges: dict[str, bool] = {}
    private: dict[tuple[str, str], int] = {}
    aliases: dict[str, str] = {}  # a local name bound to a module of the package

    def edge(target, deferred):
        if target != module:
            edges[target] = edges.get(target, True) and deferred

    for node, deferred in _import_statements(tree.body, False):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules:
                    edge(alias.name, deferred)
                    if alias.asname:
                        aliases[alias.asname] = alias.name
            continue
        if node.level:
            parts = own_package.split(".")
            base = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
        else:
            base = node.module
        if base not in modules:
            continue
        for alias in node.names:
            if f"{base}.{alias.name}" in modules:  # from PACKAGE import MODULE
                edge(f"{base}.{alias.name}", deferred)
                aliases[alias.asname or alias.name] = f"{base}.{alias.name}"
                continue
            edge(base, deferred)
            if _private(alias.name) and base != module:
                private.setdefault((base, alias.name), node.lineno)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id in aliases and _private(node.attr):
            private.setdefault((aliases[node.value.id], node.attr), node.lineno)
    return edges, private


def _cycles(graph: dict[str, set[str]]) -> set[tuple[str, ...]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative),
    each as its sorted module names."""
    index, low, on_stack, stack, found = {}, {}, set(), [], set()
    for root in sorted(graph):
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(sorted(graph[root])))]
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while not component or component[-1] != node:
                    component.append(stack.pop())
                    on_stack.discard(component[-1])
                if len(component) > 1:
                    found.add(tuple(sorted(component)))
    return found


def _path(graph: dict[str, set[str]], start: str, goal: str) -> list[str] | None:
    """A shortest chain of imports from ``start`` to ``goal`` (breadth first), or None."""
    previous, todo = {start: None}, [start]
    while todo:
        node = todo.pop(0)
        if node == goal:
            chain = [node]
            while previous[chain[-1]] is not None:
                chain.append(previous[chain[-1]])
            return chain[::-1]
        for child in sorted(graph.get(node, ())):
            if child not in previous:
                previous[child] = node
                todo.append(child)
    return None


class Structure:
    """The import graph of a set of modules, its cycles, the deferred imports that close one and
    the private names taken across modules."""

    def __init__(self, texts: dict[str, str], packages: set[str]):
        names = set(texts) | {f"{p}.__init__" for p in packages}
        self.module_level: dict[str, set[str]] = {}
        self.deferred: dict[str, set[str]] = {}
        self.private: dict[tuple[str, str, str], int] = {}
        for module, text in texts.items():
            edges, private = _imports(module, text, names)
            self.module_level[module] = {m for m, d in edges.items() if not d}
            self.deferred[module] = {m for m, d in edges.items() if d}
            self.private.update({(module, *key): line for key, line in private.items()})

    def cycles(self) -> set[tuple[str, ...]]:
        return _cycles(self.module_level)

    def deferred_cycles(self) -> dict[tuple[str, str], list[str]]:
        """Each deferred import that closes a cycle and the module-level chain back."""
        found = {}
        for module, targets in self.deferred.items():
            for target in targets:
                chain = _path(self.module_level, target, module)
                if chain:
                    found[(module, target)] = chain
        return found


@cache
def _package_structure() -> Structure:
    files = _module_files()
    return Structure({m: path.read_text() for m, path in files.items()},
                     {m for m, path in files.items() if path.name == "__init__.py"})


def _compare(found: dict, known: dict, what: str) -> None:
    """Fail on an entry of ``found`` not in ``known`` (printed with its value) and on an entry of
    ``known`` no longer found."""
    new = sorted(set(found) - set(known))
    gone = sorted(set(known) - set(found))
    message = []
    if new:
        message.append(f"new {what} (what to do instead: the docstring of tests/test_structure.py):\n"
                       + "\n".join(f"{key!r}: {found[key]}" for key in new))
    if gone:
        message.append(f"{what} listed in tests/test_structure.py that no longer exist: remove them "
                       "from the list:\n" + "\n".join(map(repr, gone)))
    assert not message, "\n\n".join(message)


# ------------------------------------------------------------------------------------------- tests
def test_no_new_import_cycle():
    cycles = _package_structure().cycles()
    _compare({c: " -> ".join(c) for c in cycles}, KNOWN_CYCLES, "import cycles")


def test_no_new_import_inside_a_function_that_closes_a_cycle():
    found = {key: "back through " + " -> ".join(chain)
             for key, chain in _package_structure().deferred_cycles().items()}
    _compare(found, KNOWN_DEFERRED_CYCLES, "imports inside a function that close a cycle")


def test_no_new_private_import():
    files = _module_files()
    found = {key: f"{files[key[0]].relative_to(ROOT)}:{line}"
             for key, line in _package_structure().private.items()}
    _compare(found, KNOWN_PRIVATE_IMPORTS, "imports of another module's private name")


def test_every_known_entry_says_what_removes_it():
    for known in (KNOWN_CYCLES, KNOWN_DEFERRED_CYCLES, KNOWN_PRIVATE_IMPORTS):
        for key, reason in known.items():
            assert reason.startswith("to be removed: ") and "\n" not in reason, key


def test_no_test_file_imports_another():
    """What test files share lives in helper modules (tests/README.md): a test module imported
    from another would run its tests' module-level code twice and hide where a helper lives."""
    found = []
    for path in sorted((ROOT / "tests").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module or ''}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            if any(n.rpartition(".")[2].startswith("test_") for n in names):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not found, "imports from test files: " + ", ".join(found)


def test_the_checks_find_what_they_look_for():
    """A made-up package p: a cycle a -> b -> c -> a at module level, d importing a inside a
    function (a does not reach d: no cycle) and a importing d inside one (d reaches a: it closes
    a cycle), private names taken by name, relatively and absolutely, and as a module's attribute;
    imports under TYPE_CHECKING, of dunders and of a module's own names do not count."""
    texts = {
        "p": "",
        "p.a": "from .b import f\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .e import g\n"
               "def h():\n    from . import d\n",
        "p.b": "import p.c\nfrom p.c import _hidden\n",
        "p.c": "from . import a\n_own = 1\nx = a._inner\nfrom .c import _own\nfrom . import __version__\n",
        "p.d": "from .a import f\ndef k():\n    from .a import _late\n",
        "p.e": "from .a import f\n",
    }
    structure = Structure(texts, {"p"})
    assert structure.cycles() == {("p.a", "p.b", "p.c")}
    assert structure.deferred_cycles() == {("p.a", "p.d"): ["p.d", "p.a"]}
    assert set(structure.private) == {("p.b", "p.c", "_hidden"), ("p.c", "p.a", "_inner"),
                                      ("p.d", "p.a", "_late")}


def test_the_sysid_package_exports_its_main_names_as_objects_not_modules():
    """`from toywalk.sysid import diagnose` gives the function, also after every submodule has been
    imported (a name shared with a submodule would then be the module: fit and sample stay in
    theirs)."""
    import types

    import toywalk.sysid as sysid
    import toywalk.sysid.cli  # noqa: F401  (imports the commands' modules)
    import toywalk.sysid.walks  # noqa: F401

    for name in sysid.__all__:
        assert not isinstance(getattr(sysid, name), types.ModuleType), name
    assert callable(sysid.diagnose) and sysid.Diagnosis.__name__ == "Diagnosis"


def test_a_public_name_shared_with_its_submodule_stays_the_object_whatever_was_imported_first():
    """`toywalk.model.simulate` is a function and a submodule: once the submodule is imported
    (by `from toywalk.model.simulate import gait_walk`, say), the import system sets the
    package's attribute to the module, and `from toywalk.model import simulate` gave the module
    in a fresh interpreter (the order the tests ran in decided it). Checked in a fresh one."""
    import subprocess
    import sys

    code = ("from toywalk.model.simulate import gait_walk\n"
            "from toywalk.model import simulate\n"
            "import toywalk.model as m\n"
            "assert callable(simulate) and m.simulate is simulate and callable(gait_walk), simulate\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
