"""Every document the code, README and docs cite is in the repository.

The model's physics is ``docs/model.md``; file formats, the command line and the repository layout
are ``docs/formats.md``, ``docs/cli.md`` and ``README.md``. Citations of the developers' design
notes, which a user of the package cannot open, are refused: ``pipeline.md`` anywhere, ``model.md``
other than as ``docs/model.md`` (inside ``docs/*.md`` the sibling ``model.md`` is the same page), and
paths that climb out of the repository (``../shared``, ``../reference``), and the design notes'
reference numbers and style rules (``anchors.md``, ``style.md``: docs/model.md section 7 holds the
published numbers, tests/README.md the rules for tests). This reads files only: it
imports nothing of toywalk.
"""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("model", "tracking", "sysid", "tests", "benchmarks", "docs", "data", "notebooks")
SKIPPED = {".venv", "__pycache__", ".git"}
THIS = Path(__file__).resolve()
# (file, fragment of a line) allowed to cite such a document: none (F.json's unit label, which
# cited the design document, now cites docs/formats.md)
ALLOWED: set = set()

# "model.md" as a file name, not the tail of a longer one ("toymodel.md"), and the path before it.
_MODEL_MD = re.compile(r"(?<![\w-])model\.md")
_PATH_BEFORE = re.compile(r"[\w./~-]*$")
_OUTSIDE = ("pipeline.md", "../shared", "../reference", "anchors.md", "style.md", "shared/design",
            "shared/reference")


def _sources() -> list[Path]:
    files = [ROOT / "README.md"]
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*")):
            if (path.suffix in (".py", ".md") and path.is_file() and path != THIS
                    and not SKIPPED & set(path.parts)):
                files.append(path)
    return files


def bad_citations(path: Path, text: str) -> list[str]:
    """The citations in ``text`` (the contents of ``path``) of documents the repository lacks."""
    sibling_ok = path.suffix == ".md" and path.parent == ROOT / "docs"
    found = []
    name = path.relative_to(ROOT).as_posix()
    for number, line in enumerate(text.splitlines(), 1):
        if any(name == file and fragment in line for file, fragment in ALLOWED):
            continue
        where = f"{name}:{number}"
        found += [f"{where}: {marker}" for marker in _OUTSIDE if marker in line]
        for match in _MODEL_MD.finditer(line):
            prefix = _PATH_BEFORE.search(line, 0, match.start()).group(0)
            if prefix in ("docs/", "./docs/"):
                continue  # docs/model.md (also ./docs/model.md)
            if sibling_ok and prefix == "":
                continue  # model.md or (model.md) beside it in docs/
            found.append(f"{where}: {match.group(0)}")
    return found


def test_the_check_can_fail():
    """Each kind of citation the repository cannot hold is caught; its own forms pass."""
    docs_page, module = ROOT / "docs" / "x.md", ROOT / "model" / "x.py"
    for text in ("see pipeline.md, \"Files\"", "(model.md section 3)", "shared/design/model.md",
                 "``shared/design/pipeline.md``", "../shared/paper", "../reference/anchors.md",
                 "[model.md](../model.md)"):
        assert bad_citations(module, text), text
    for text in ("pipeline.md", "shared/design/model.md section 2", "[x](../shared/x.md)"):
        assert bad_citations(docs_page, text), text
    for text in ("docs/model.md section 3", "(docs/model.md section 6)", "`docs/model.md`",
                 "docs/formats.md, \"Trajectory\"", "toymodel.md"):
        assert not bad_citations(module, text), text
    for text in ("model.md section 3", "[model.md](model.md) section 4", "(model.md sections 1-2)",
                 "formats.md#conventions-model-md-sections-1-2"):
        assert not bad_citations(docs_page, text), text


def test_no_citation_of_a_document_the_repository_does_not_hold():
    files = _sources()
    assert len(files) > 100  # the walk found the packages, not an empty folder
    bad = [hit for path in files for hit in bad_citations(path, path.read_text(encoding="utf-8"))]
    assert not bad, f"{len(bad)} citations of documents outside the repository:\n" + "\n".join(bad)
