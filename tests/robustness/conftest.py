"""Shared inputs and checks of the robustness suite.

The commands run in this process through :func:`toywalk.sysid.cli.main` (the console script's
own entry point, which only adds ``sys.exit``), with the output captured at the file descriptors
(``capfd``), so that a message a C library (FFmpeg, HDF5, IPOPT) writes itself is seen too. An
exception escaping ``main`` is what the console script would print as a traceback: the helper
turns it into a test failure that names it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import pytest
from toywalk.sysid.cli import main

from ..conftest import DATA

STABLE_TOY = DATA / "params" / "stable-toy.toml"
#: A walker whose gait is unstable (step-map max |eigenvalue| 6.0): from its fixed point it falls
#: within 20 steps, as rounding grows by that factor every step.
TOY_SIZED = DATA / "params" / "toy-sized.toml"
CAMERA = DATA / "camera" / "default.json"
MARKERS = DATA / "markers" / "default.json"

#: The compiled-function cache prints this once per machine when it compiles (model/compiled.py):
#: information about a one-time cost, not an error line.
_COMPILE_NOTICE = "toywalk: compiling "
#: Progress lines on stderr (diagnose's stages; sample's tenths of each ensemble where stderr is
#: not a terminal, as under pytest): not error lines either.
_PROGRESS = "... "


@dataclasses.dataclass
class Outcome:
    """What one command did: exit status and what it wrote to stdout and stderr."""

    command: str
    code: int
    out: str
    err: str

    @property
    def err_lines(self) -> list[str]:
        return [line for line in self.err.splitlines()
                if line.strip() and not line.startswith((_COMPILE_NOTICE, _PROGRESS))]


def toywalk(capfd, *argv) -> Outcome:
    """Run ``toywalk ARGV`` in this process; an exception escaping it fails the test."""
    capfd.readouterr()  # drop what earlier steps printed
    argv = [str(a) for a in argv]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own usage errors
        code = exc.code
    except BaseException as exc:  # noqa: BLE001 - any escape is the defect being tested for
        out, err = capfd.readouterr()
        pytest.fail(f"`toywalk {' '.join(argv)}` raised {type(exc).__name__}: {exc} (the console "
                    f"script would print a traceback); stderr: {err}")
    out, err = capfd.readouterr()
    return Outcome(argv[0], code, out, err)


def assert_refused(outcome: Outcome, *words: str) -> None:
    """Exit status 2 and exactly one line on stderr, ``toywalk CMD: error: ...``, holding every
    one of ``words`` (what names the problem)."""
    lines = outcome.err_lines
    assert outcome.code == 2, (outcome.code, outcome.err)
    assert len(lines) == 1, f"expected one line on stderr, got:\n{outcome.err}"
    assert lines[0].startswith(f"toywalk {outcome.command}: error: "), lines[0]
    assert "Traceback" not in outcome.err
    for word in words:
        assert word in lines[0], f"{word!r} not in {lines[0]!r}"


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (hidden and temporary ones too) and a hash of its bytes."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def write(path: Path, content) -> Path:
    """Write text or bytes (or, for None, make a folder of that name)."""
    if content is None:
        path.mkdir()
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


@pytest.fixture(scope="session")
def walk(tmp_path_factory):
    """A measured walk: 6 steps of stable-toy with 2 mrad angle noise (``walk.csv`` with its
    events and metadata), written by ``toywalk simulate``."""
    folder = tmp_path_factory.mktemp("walk")
    path = folder / "walk.csv"
    assert main(["simulate", "--params", str(STABLE_TOY), "--steps", "6", "--noise", "0.002",
                 "--seed", "3", "--out", str(path)]) == 0
    return path


@pytest.fixture(scope="session")
def fit_file(walk, tmp_path_factory):
    """``toywalk fit`` of the walk's foot radius (periodic model): a fit file to sample from.
    10 collocation intervals a step (30 by default) make it quicker; it converges all the same."""
    path = tmp_path_factory.mktemp("fit") / "fit.json"
    assert main(["fit", str(walk), "--params", str(STABLE_TOY), "--free", "foot_radius",
                 "--model", "periodic", "--intervals", "10", "--out", str(path)]) == 0
    report = json.loads(path.read_text())
    assert report["success"], report["status"]
    return path


@pytest.fixture(scope="session")
def video(walk, tmp_path_factory):
    """A short synthetic video of the walk (``toywalk render``, 320x240, 13 frames) with the
    camera and marker layout it was filmed with beside it."""
    path = tmp_path_factory.mktemp("video") / "tiny.mp4"
    assert main(["render", str(walk), "--params", str(STABLE_TOY), "--size", "320x240", "--fps", "30",
                 "--duration", "0.4", "--seed", "1", "--out", str(path)]) == 0
    return path
