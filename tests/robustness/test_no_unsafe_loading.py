"""No user file is ever unpickled or evaluated: a static check of the source tree.

Every file a user hands the toolkit (parameters, trajectories, camera and marker layouts, fit and
chain files, videos, images) is read by a parser of data (tomllib, csv, json, h5py, OpenCV).
Unpickling (pickle, shelve, marshal, dill, joblib, ``numpy.load(allow_pickle=True)``,
``pandas.read_pickle``, ``torch.load``), ``yaml.load`` and ``eval``/``exec`` run code that a file
can carry. The check reads the syntax tree of every module of the three packages (``model``,
``tracking``, ``sysid``) and of the bundled data scripts; it is shown to find each pattern in a
planted example.
"""

from __future__ import annotations

import ast

from ..conftest import ROOT

#: Modules whose import alone means objects are rebuilt from bytes.
UNSAFE_MODULES = {"pickle", "cPickle", "_pickle", "shelve", "marshal", "dill", "joblib", "cloudpickle"}
#: Built-ins that run code from a string.
UNSAFE_BUILTINS = {"eval", "exec", "__import__"}
#: Calls (last two name parts) that unpickle or run code from a file.
UNSAFE_CALLS = {("pd", "read_pickle"), ("pandas", "read_pickle"), ("torch", "load"), ("yaml", "load"),
                ("yaml", "unsafe_load"), ("yaml", "full_load")}


def _dotted(node) -> tuple[str, ...]:
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
    return tuple(reversed(parts))


def unsafe_uses(source: str, name: str = "<string>") -> list[str]:
    """Where ``source`` imports an unpickling module, calls eval/exec, or loads with pickling."""
    found = []
    for node in ast.walk(ast.parse(source, name)):
        where = f"{name}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.Import):
            found += [f"{where}: import {a.name}" for a in node.names
                      if a.name.split(".")[0] in UNSAFE_MODULES]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in UNSAFE_MODULES:
            found.append(f"{where}: from {node.module} import ...")
        elif isinstance(node, ast.Call):
            dotted = _dotted(node.func)
            if len(dotted) == 1 and dotted[0] in UNSAFE_BUILTINS:
                found.append(f"{where}: {dotted[0]}(...)")
            if tuple(dotted[-2:]) in UNSAFE_CALLS:
                found.append(f"{where}: {'.'.join(dotted)}(...)")
            for kw in node.keywords:
                if kw.arg == "allow_pickle" and not (isinstance(kw.value, ast.Constant)
                                                     and kw.value.value is False):
                    found.append(f"{where}: {'.'.join(dotted)}(allow_pickle=...)")
    return found


def _sources():
    folders = [ROOT / "model", ROOT / "tracking", ROOT / "sysid", ROOT / "data"]
    return sorted(p for folder in folders for p in folder.rglob("*.py"))


def test_the_check_finds_each_pattern():
    """The check is not vacuous: each unsafe pattern, planted, is found; safe look-alikes are not."""
    planted = {
        "import pickle\n": 1, "from pickle import load\n": 1, "import shelve, marshal\n": 2,
        "x = eval(text)\n": 1, "exec(code)\n": 1, "np.load(path, allow_pickle=True)\n": 1,
        "numpy.load(path, allow_pickle=flag)\n": 1, "yaml.load(fh)\n": 1, "pd.read_pickle(p)\n": 1,
        "torch.load(p)\n": 1,
        # safe: a method named eval, numpy without pickles, literal_eval, json, tomllib
        "model.eval()\nnp.load(path)\nnp.load(path, allow_pickle=False)\nast.literal_eval(s)\n"
        "json.loads(s)\ntomllib.loads(s)\n": 0,
    }
    for source, count in planted.items():
        assert len(unsafe_uses(source)) == count, (source, unsafe_uses(source))


def test_no_unpickling_or_eval():
    sources = _sources()
    assert len(sources) > 40  # the packages were found
    found = [use for path in sources for use in unsafe_uses(path.read_text(), str(path.relative_to(ROOT)))]
    assert found == []
