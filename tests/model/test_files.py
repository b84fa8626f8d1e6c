"""Small file helpers (toywalk.model.files)."""

import json
import math

import numpy as np
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
