"""Writing files so that an interrupted write never leaves a half-written file behind, and reading
JSON files with one clear line when they are missing or malformed."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

__all__ = ["DATA_DIR", "atomic_write_figure", "atomic_write_json", "atomic_write_text", "read_json_object",
           "software_version", "staged_files", "strict_json"]

#: The bundled data (data/README.md): beside the packages in the source tree, and installed with
#: them as ``toywalk/data`` from a wheel, so the same relative path finds it in both.
DATA_DIR = Path(__file__).resolve().parents[1] / "data"


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it into place."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def staged_files(paths: Sequence[str | Path]) -> Iterator[list[Path]]:
    """Write several files all or nothing: yields, for each of ``paths``, a path of the same name
    in a hidden folder beside the first, to write there; when the block ends without an error each
    is renamed into place (those already placed are removed again if a later rename fails). On an
    error, or an interrupt, nothing is written and the folder is removed: no half-written output.
    The names must differ (they share the folder); a file the block did not write is an error."""
    paths = [Path(p) for p in paths]
    if len({p.name for p in paths}) != len(paths):
        raise ValueError(f"staged files need distinct names, got {[p.name for p in paths]}")
    folder = Path(tempfile.mkdtemp(prefix=f".{paths[0].stem}.", dir=paths[0].parent))
    done: list[Path] = []
    try:
        staged = [folder / p.name for p in paths]
        yield staged
        for tmp, path in zip(staged, paths, strict=True):
            os.replace(tmp, path)
            done.append(path)
    except BaseException:
        for path in done:
            path.unlink(missing_ok=True)
        raise
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def atomic_write_json(path: str | Path, data) -> None:
    """Write ``data`` as indented JSON, atomically (see :func:`atomic_write_text`)."""
    atomic_write_text(path, json.dumps(data, indent=2) + "\n")


def atomic_write_figure(path: str | Path, fig, dpi: int = 110) -> None:
    """Save the Matplotlib figure ``fig`` to ``path`` at ``dpi``, atomically (see
    :func:`atomic_write_text`): drawn to a hidden temporary file beside it, with its suffix (the
    format Matplotlib infers), then renamed into place."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{path.suffix}")
    try:
        fig.savefig(tmp, dpi=dpi)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def strict_json(data):
    """``data`` with every non-finite float (NaN, infinity) replaced by None and NumPy scalars by
    Python numbers, recursively through dicts, lists and tuples: strict JSON has no NaN."""
    if isinstance(data, dict):
        return {k: strict_json(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [strict_json(v) for v in data]
    if hasattr(data, "item") and getattr(data, "ndim", None) == 0:  # a NumPy scalar
        data = data.item()
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


def read_json_object(path: str | Path, what: str, error: type[Exception]) -> dict:
    """The JSON object in ``path``; ``error`` with one line naming ``what`` (e.g. "camera file")
    if the file is missing, unreadable, not JSON (a JSONDecodeError, an integer too long to
    convert, a ValueError both; nesting too deep, a RecursionError) or not a JSON object."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError as err:
        raise error(f"{what} not found: {path}") from err
    except (OSError, ValueError, RecursionError) as err:
        raise error(f"cannot read {what} {path}: {str(err).splitlines()[0]}") from err
    if not isinstance(data, dict):
        raise error(f"{what} {path} must hold a JSON object")
    return data


def software_version() -> str:
    """``toywalk X.Y`` as installed, for the metadata of every file the toolkit writes."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"toywalk {version('toywalk')}"
    except PackageNotFoundError:
        return "toywalk (not installed)"
