"""Bad trajectories (a measured walk's CSV, events and metadata files) for the robustness tests of
every command that reads one (tests/robustness/test_inputs.py, test_sampling.py): each a change
of a good walk's files and the words the command's one-line refusal must hold."""

from __future__ import annotations

from .conftest import STABLE_TOY, write

__all__ = ["BINARY", "TRAJECTORIES", "bad_trajectory", "cell", "cut_mid_row", "drop_column"]

#: Invalid UTF-8 from byte 128 on (a stray binary file, e.g. an image).
BINARY = bytes(range(256)) * 4


def cell(row: int, column: str, value: str):
    """A change of one cell (``row`` counts data rows from 1) of a CSV text."""
    def change(text):
        lines = text.splitlines()
        header = lines[0].split(",")
        cells = lines[row].split(",")
        cells[header.index(column)] = value
        lines[row] = ",".join(cells)
        return "\n".join(lines) + "\n"
    return change


def drop_column(column: str):
    """A change of a CSV text that drops its column ``column``."""
    def change(text):
        lines = [line.split(",") for line in text.splitlines()]
        k = lines[0].index(column)
        return "\n".join(",".join(c for i, c in enumerate(cells) if i != k) for cells in lines) + "\n"
    return change


def cut_mid_row(text):
    """The file cut inside a row, as a copy or a write interrupted there leaves it."""
    lines = text.splitlines(keepends=True)
    half = "".join(lines[:len(lines) // 2])
    return half + lines[len(lines) // 2][:12]


#: name: ({"csv" | "events" | "json" | "path": change}, words naming the problem). A change is a
#: function of the file's text, new content (None: a folder), or False (no such file).
TRAJECTORIES = {
    "empty": ({"csv": ""}, ["is empty"]),
    "cut inside a row": ({"csv": cut_mid_row}, ["cells, the header", "truncated"]),
    "a missing column": ({"csv": drop_column("steer")}, ["lacks column(s) steer"]),
    "a repeated column": ({"csv": lambda t: t.replace(",lean_sd,", ",lean,", 1)},
                          ["'lean' appears more than once"]),
    "a parameter file (mislabelled)": ({"csv": STABLE_TOY.read_text()}, ["truncated or malformed"]),
    "binary": ({"csv": BINARY}, ["not a text file"]),
    "NaN": ({"csv": cell(5, "lean", "nan")}, ["row 6, column lean: NaN"]),
    "an infinite angle": ({"csv": cell(5, "pitch_left", "inf")}, ["row 6, column pitch_left: not finite"]),
    "an infinite time": ({"csv": cell(5, "time", "-inf")}, ["row 6, column time: not finite"]),
    "time going back": ({"csv": cell(5, "time", "0.0")}, ["times must increase", "row 6"]),
    "text for a number": ({"csv": cell(5, "steer", "abc")}, ["row 6, column steer: not a number"]),
    "a stance other than L or R": ({"csv": cell(5, "stance", "Left")}, ["column stance"]),
    "a negative standard deviation": ({"csv": cell(5, "lean_sd", "-0.002")},
                                      ["lean_sd: a standard deviation must be positive"]),
    "events empty": ({"events": ""}, ["walk.events.csv is empty"]),
    "events cut inside a row": ({"events": cut_mid_row}, ["walk.events.csv", "truncated"]),
    "events without a foot column": ({"events": lambda t: t.replace("foot", "feet", 1)},
                                     ["lacks column(s) foot"]),
    "events with a foot other than L or R": ({"events": cell(2, "foot", "X")}, ["column foot"]),
    "events with an infinite time": ({"events": cell(2, "time", "inf")}, ["not finite"]),
    "metadata not JSON": ({"json": "{units: s"}, ["walk.json is not valid JSON"]),
    "metadata not an object": ({"json": "[1, 2]"}, ["must hold a JSON object"]),
    "metadata binary": ({"json": BINARY}, ["walk.json is not a text file"]),
    "a folder": ({"path": None}, ["is not a file"]),
    "missing": ({"path": False}, ["trajectory file not found"]),
}


def bad_trajectory(walk, folder, case):
    """A copy of ``walk`` (its three files) in ``folder``, changed as TRAJECTORIES[case] says."""
    changes, words = TRAJECTORIES[case]
    target = folder / "walk.csv"
    if "path" in changes:
        if changes["path"] is None:
            target.mkdir()
        return target, words
    for kind, suffix in (("csv", ".csv"), ("events", ".events.csv"), ("json", ".json")):
        source = walk.with_name(walk.stem + suffix)
        change = changes.get(kind)
        content = change(source.read_text()) if callable(change) else change
        write(folder / ("walk" + suffix), source.read_bytes() if change is None else content)
    return target, words
