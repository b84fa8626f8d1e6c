"""Small file helpers (toywalk.model.files)."""

import json
import math

import numpy as np
import pytest
from toywalk.model.files import atomic_write_json, strict_json


def test_strict_json_writes_null_for_what_json_cannot_hold(tmp_path):
    data = {"a": math.nan, "b": [1.0, math.inf, (-math.inf, 2)], "c": np.float64(np.nan),
            "d": np.float64(0.5), "e": np.int64(3), "f": "NaN", "g": True}
    out = strict_json(data)
    assert out == {"a": None, "b": [1.0, None, [None, 2]], "c": None, "d": 0.5, "e": 3,
                   "f": "NaN", "g": True}
    path = tmp_path / "x.json"
    atomic_write_json(path, out)
    # Python's reader accepts NaN unless told not to: this one fails on any non-finite constant
    assert json.loads(path.read_text(), parse_constant=lambda c: 1 / 0) == out


def test_staged_files_write_all_or_nothing(tmp_path):
    """The one all-or-nothing writer of several files (trajectory files, a continuation's three,
    a rendered video's six): every file in place after the block, none after an error in it, and
    no staging folder left either way."""
    from toywalk.model.files import staged_files

    paths = [tmp_path / "a.csv", tmp_path / "a.json"]
    with staged_files(paths) as (csv_path, json_path):
        csv_path.write_text("1\n")
        json_path.write_text("{}\n")
    assert [p.read_text() for p in paths] == ["1\n", "{}\n"]
    others = [tmp_path / "b.csv", tmp_path / "b.json"]
    with pytest.raises(RuntimeError, match="stopped"), staged_files(others) as (csv_path, _):
        csv_path.write_text("half")
        raise RuntimeError("stopped")
    assert not any(p.exists() for p in others)
    # a file the block did not write: nothing placed, not even the one it did
    with pytest.raises(FileNotFoundError), staged_files(others) as (csv_path, _):
        csv_path.write_text("only one")
    assert not any(p.exists() for p in others)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "a.json"]
    with pytest.raises(ValueError, match="distinct"), staged_files([tmp_path / "x", tmp_path / "d" / "x"]):
        pass
