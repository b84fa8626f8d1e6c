"""The trajectory files every stage shares (pipeline.md, "Files"): NAME.csv, NAME.events.csv, NAME.json.

``NAME.csv`` has one row per sample with the columns ``time, lean, steer, pitch_left, pitch_right,
stance`` (s, rad, 'L'/'R'), optional ``*_sd`` standard deviations and optional ``contact_x,
contact_y`` (m). Missing samples are empty cells. ``NAME.events.csv`` lists heel strikes
(``time, foot, x, y``, and the optional standard deviations ``time_sd`` (s) of a measured strike
time and ``x_sd, y_sd`` (m) of a measured contact position). ``NAME.json`` holds the metadata.
The three files are written to temporary names and renamed into place together, so an
interrupted write leaves no partial output.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np

__all__ = ["EVENT_SD_COLUMNS", "SIGNALS", "TrajectoryTable", "read_trajectory", "trajectory_paths",
           "write_trajectory"]

#: Angle signals of a trajectory file, in column order (rad).
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
#: Optional standard-deviation columns of the events file: strike time (s), contact position (m).
EVENT_SD_COLUMNS = ("time_sd", "x_sd", "y_sd")


class TrajectoryTable:
    """Columns of a trajectory file as arrays (NaN where a sample is missing).

    Attributes
    ----------
    time : ndarray, shape (n,)
    signals : dict of str to ndarray, shape (n,)
        ``lean, steer, pitch_left, pitch_right`` and any ``*_sd`` and ``contact_x, contact_y``.
    stance : ndarray of str, shape (n,)
    events : list of dict
        ``time, foot, x, y`` and any of :data:`EVENT_SD_COLUMNS`.
    metadata : dict
    """

    def __init__(self, time, signals, stance, events=(), metadata=None):
        self.time = np.asarray(time, dtype=float)
        self.signals = {k: np.asarray(v, dtype=float) for k, v in signals.items()}
        self.stance = np.asarray(stance, dtype="<U1")
        self.events = list(events)
        self.metadata = dict(metadata or {})
        for name, col in self.signals.items():
            if col.shape != self.time.shape:
                raise ValueError(f"column {name} has {col.shape[0]} rows, time has {self.time.shape[0]}")


def trajectory_paths(out: str | Path) -> tuple[Path, Path, Path]:
    """(NAME.csv, NAME.events.csv, NAME.json) for an output path NAME.csv."""
    out = Path(out)
    if out.suffix != ".csv":
        raise ValueError(f"a trajectory file name must end in .csv, got {out}")
    stem = out.with_suffix("")
    return out, stem.with_name(stem.name + ".events.csv"), stem.with_suffix(".json")


def _cell(value) -> str:
    if isinstance(value, str):
        return value
    value = float(value)
    return "" if math.isnan(value) else repr(value)


def write_trajectory(table: TrajectoryTable, out: str | Path) -> tuple[Path, Path, Path]:
    """Write the three files of a trajectory; returns their paths."""
    paths = trajectory_paths(out)
    columns = ["time", *SIGNALS, "stance"]
    extra = [k for k in table.signals if k not in SIGNALS]
    columns += sorted(k for k in extra if k.endswith("_sd"))
    columns += [k for k in ("contact_x", "contact_y") if k in table.signals]
    tmps = [p.with_name(f".{p.name}.tmp") for p in paths]
    try:
        with open(tmps[0], "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(columns)
            for i in range(len(table.time)):
                row = []
                for col in columns:
                    if col == "time":
                        row.append(_cell(table.time[i]))
                    elif col == "stance":
                        row.append(str(table.stance[i]) if table.stance[i] in ("L", "R") else "")
                    else:
                        row.append(_cell(table.signals[col][i]))
                writer.writerow(row)
        with open(tmps[1], "w", newline="") as fh:
            writer = csv.writer(fh)
            extra = [c for c in EVENT_SD_COLUMNS if any(c in ev for ev in table.events)]
            writer.writerow(["time", "foot", "x", "y"] + extra)
            for ev in table.events:
                writer.writerow([_cell(ev["time"]), ev["foot"], _cell(ev.get("x", math.nan)),
                                 _cell(ev.get("y", math.nan))]
                                + [_cell(ev.get(c, math.nan)) for c in extra])
        with open(tmps[2], "w") as fh:
            json.dump(table.metadata, fh, indent=2, sort_keys=True, default=_json_default)
            fh.write("\n")
        for tmp, path in zip(tmps, paths, strict=True):
            os.replace(tmp, path)
    finally:
        for tmp in tmps:
            tmp.unlink(missing_ok=True)
    return paths


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot write {type(obj).__name__} to JSON")


def read_trajectory(path: str | Path) -> TrajectoryTable:
    """Read NAME.csv (and NAME.events.csv, NAME.json where present)."""
    csv_path, events_path, meta_path = trajectory_paths(path)
    if not csv_path.exists():
        raise FileNotFoundError(f"trajectory file not found: {csv_path}")
    with open(csv_path, newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = next(reader)
        except StopIteration as err:
            raise ValueError(f"{csv_path} is empty") from err
        required = ["time", *SIGNALS, "stance"]
        missing = [c for c in required if c not in header]
        if missing:
            raise ValueError(f"{csv_path} lacks column(s) {', '.join(missing)}")
        rows = list(reader)
    idx = {name: i for i, name in enumerate(header)}

    def column(name):
        out = np.full(len(rows), np.nan)
        for r, row in enumerate(rows):
            cell = row[idx[name]].strip() if idx[name] < len(row) else ""
            if cell:
                try:
                    out[r] = float(cell)
                except ValueError as err:
                    raise ValueError(
                        f"{csv_path}: row {r + 2}, column {name}: not a number: {cell!r}"
                    ) from err
        return out

    time = column("time")
    if np.any(np.isnan(time)):
        raise ValueError(f"{csv_path}: every row needs a time")
    signals = {name: column(name) for name in header if name not in ("time", "stance")}
    stance = np.array([row[idx["stance"]].strip() if idx["stance"] < len(row) else "" for row in rows])
    events = []
    if events_path.exists():
        with open(events_path, newline="") as fh:
            for row in csv.DictReader(fh):
                events.append({"time": float(row["time"]), "foot": row["foot"],
                               "x": float(row["x"]) if row.get("x") else math.nan,
                               "y": float(row["y"]) if row.get("y") else math.nan})
                for c in EVENT_SD_COLUMNS:
                    if c in row:
                        events[-1][c] = float(row[c]) if row[c] else math.nan
    metadata = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    return TrajectoryTable(time, signals, stance, events, metadata)
