"""The bundled data folder (issue 12): every file listed in data/README.md with its hash, the whole
folder under 20 MB, every parameter set readable, the paper's measurements a table of numbers."""

import csv
import hashlib
import re

import pytest
from toywalk.model.parameters import load_params

from .conftest import DATA

#: The issue's limit on the whole folder.
LIMIT_BYTES = 20 * 2**20
_HASH_LINE = re.compile(r"^([0-9a-f]{64})  (\S+)$", re.MULTILINE)


def _files():
    return sorted(p.relative_to(DATA).as_posix() for p in DATA.rglob("*")
                  if p.is_file() and p.name != "README.md" and "__pycache__" not in p.parts)


def _listed() -> dict[str, str]:
    return {name: digest for digest, name in _HASH_LINE.findall((DATA / "README.md").read_text())}


def test_every_file_is_listed_with_its_hash():
    """A file added, removed or changed without the README following fails here, naming it."""
    listed = _listed()
    assert sorted(listed) == _files()
    changed = [name for name, digest in listed.items()
               if hashlib.sha256((DATA / name).read_bytes()).hexdigest() != digest]
    assert not changed, f"hash in data/README.md out of date: {changed}"


def test_every_file_is_described():
    """Each file is described by name, not only in the hash list (the calibration views by their
    folder's row; the script that makes the sample by its command)."""
    text = _HASH_LINE.sub("", (DATA / "README.md").read_text())
    missing = [name for name in _files() if f"`{name}`" not in text and name != "make_sample.py"
               and not (name.startswith("sample/calibration/") and "`sample/calibration/" in text)]
    assert not missing, missing
    assert "python data/make_sample.py" in text


def test_the_folder_is_under_20_mb():
    size = sum((DATA / name).stat().st_size for name in _files())
    assert size < LIMIT_BYTES, f"{size / 2**20:.1f} MB"


@pytest.mark.parametrize("name", sorted(p.name for p in (DATA / "params").glob("*.toml")))
def test_every_parameter_set_reads(name):
    params = load_params(DATA / "params" / name)
    assert params.leg_length > 0


def test_the_papers_measurements():
    """The table's numbers are the paper's (Coleman & Ruina 1998, as docs/model.md section 7 quotes them)."""
    with open(DATA / "paper" / "measurements.csv", newline="") as f:
        rows = {r["quantity"]: r for r in csv.DictReader(f)}
    expected = {"slope": (4.5, "deg"), "stride_time": (0.47, "s"), "stride_length": (0.013, "m"),
                "lean_amplitude": (4.0, "deg"), "total_mass": (120.0, "g")}
    for quantity, (value, unit) in expected.items():
        assert float(rows[quantity]["value"]) == value and rows[quantity]["unit"] == unit
        assert float(rows[quantity]["resolution"]) > 0
    assert rows["can_stand"]["value"] == "false"
