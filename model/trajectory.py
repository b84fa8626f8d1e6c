"""The trajectory files every stage shares (docs/formats.md, "Trajectory"): NAME.csv, NAME.events.csv,
NAME.json.

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
import io
import json
import math
from pathlib import Path

import numpy as np

from .files import staged_files

__all__ = ["EVENT_SD_COLUMNS", "SIGNALS", "TrajectoryError", "TrajectoryTable", "read_trajectory",
           "trajectory_paths", "write_trajectory"]

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
    with staged_files(paths) as tmps:
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
    return paths


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot write {type(obj).__name__} to JSON")


class TrajectoryError(ValueError):
    """A trajectory file is missing, unreadable or malformed; the message (one line) names the
    file, and the row and column where there is one."""


def _first_line(err: BaseException) -> str:
    lines = str(err).splitlines()
    return lines[0] if lines else type(err).__name__


def _read_text(path: Path, what: str) -> str:
    """A file's text (UTF-8, an initial byte-order mark dropped), or one-line errors."""
    if not path.is_file():
        raise TrajectoryError(f"{what} {path} is not a file")
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise TrajectoryError(f"{path} is not a text file (not UTF-8 at byte {err.start})") from err
    except OSError as err:
        raise TrajectoryError(f"cannot read {what} {path}: {err.strerror or err}") from err


def _csv_rows(path: Path, text: str) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header (names stripped) and (line number, cells) of every non-blank row. Every row must
    have as many cells as the header: a short last row is a file cut short."""
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as err:
        raise TrajectoryError(f"{path} is not a CSV file: {_first_line(err)}") from err
    if not rows or not any(cell.strip() for cell in rows[0]):
        raise TrajectoryError(f"{path} is empty (no header row)")
    header = [cell.strip() for cell in rows[0]]
    seen = set()
    for name in header:
        if not name.isprintable():
            raise TrajectoryError(f"{path}: the column name {name!r} holds a control character")
        if name in seen:
            raise TrajectoryError(f"{path}: column {name!r} appears more than once in the header")
        seen.add(name)
    body = []
    for line, row in enumerate(rows[1:], start=2):
        if not row or (len(row) == 1 and not row[0].strip()):  # a blank line
            continue
        if len(row) != len(header):
            raise TrajectoryError(f"{path}: row {line} has {len(row)} cells, the header {len(header)} "
                                  "(a truncated or malformed file)")
        body.append((line, row))
    return header, body


def _number(path: Path, line: int, name: str, cell: str, *, sd: bool = False) -> float:
    """A cell's value: NaN for an empty cell (a missing value), else a finite number (a standard
    deviation: positive, +inf meaning unknown)."""
    cell = cell.strip()
    if not cell:
        return math.nan
    try:
        value = float(cell)
    except ValueError as err:
        raise TrajectoryError(f"{path}: row {line}, column {name}: not a number: {cell[:40]!r}") from err
    if math.isnan(value):
        raise TrajectoryError(f"{path}: row {line}, column {name}: NaN (a missing value is an empty "
                              "cell)")
    if sd:
        if not value > 0:
            raise TrajectoryError(f"{path}: row {line}, column {name}: a standard deviation must be "
                                  f"positive, got {cell[:40]!r}")
    elif not math.isfinite(value):
        raise TrajectoryError(f"{path}: row {line}, column {name}: not finite: {cell[:40]!r}")
    return value


def _foot(path: Path, line: int, name: str, cell: str, *, empty: bool) -> str:
    cell = cell.strip()
    if cell in ("L", "R") or (empty and not cell):
        return cell
    allowed = "'L', 'R' or empty" if empty else "'L' or 'R'"
    raise TrajectoryError(f"{path}: row {line}, column {name}: must be {allowed}, got {cell[:40]!r}")


def read_trajectory(path: str | Path) -> TrajectoryTable:
    """Read NAME.csv (and NAME.events.csv, NAME.json where present).

    Raises
    ------
    FileNotFoundError
        NAME.csv does not exist.
    TrajectoryError
        A file is unreadable or malformed (one line naming the file, and the row and column): not
        UTF-8 text, a missing or repeated column, a row with more or fewer cells than the header (a
        file cut short), a cell that is not a number, NaN text (a missing value is an empty cell),
        an infinite value, a standard deviation that is not positive, a stance or foot other than
        ``L``/``R``, times that are missing or do not increase, metadata that is not a JSON object.
    """
    csv_path, events_path, meta_path = trajectory_paths(path)
    if not csv_path.exists():
        raise FileNotFoundError(f"trajectory file not found: {csv_path}")
    header, rows = _csv_rows(csv_path, _read_text(csv_path, "trajectory file"))
    required = ["time", *SIGNALS, "stance"]
    missing = [c for c in required if c not in header]
    if missing:
        raise TrajectoryError(f"{csv_path} lacks column(s) {', '.join(missing)}")
    idx = {name: i for i, name in enumerate(header)}

    def column(name):
        sd = name.endswith("_sd")
        return np.array([_number(csv_path, line, name, row[idx[name]], sd=sd) for line, row in rows],
                        dtype=float).reshape(len(rows))

    time = column("time")
    if np.any(np.isnan(time)):
        line = rows[int(np.flatnonzero(np.isnan(time))[0])][0]
        raise TrajectoryError(f"{csv_path}: every row needs a time (row {line} has none)")
    back = np.flatnonzero(np.diff(time) <= 0)
    if back.size:
        k = int(back[0])
        raise TrajectoryError(f"{csv_path}: times must increase: row {rows[k + 1][0]} "
                              f"({float(time[k + 1])!r} s) is not after row {rows[k][0]} "
                              f"({float(time[k])!r} s)")
    signals = {name: column(name) for name in header if name not in ("time", "stance")}
    stance = np.array([_foot(csv_path, line, "stance", row[idx["stance"]], empty=True)
                       for line, row in rows], dtype="<U1").reshape(len(rows))
    events = []
    if events_path.exists():
        names, event_rows = _csv_rows(events_path, _read_text(events_path, "events file"))
        missing = [c for c in ("time", "foot") if c not in names]
        if missing:
            raise TrajectoryError(f"{events_path} lacks column(s) {', '.join(missing)}")
        at = {name: i for i, name in enumerate(names)}
        for line, row in event_rows:
            t = _number(events_path, line, "time", row[at["time"]])
            if math.isnan(t):
                raise TrajectoryError(f"{events_path}: row {line}: every heel strike needs a time")
            event = {"time": t, "foot": _foot(events_path, line, "foot", row[at["foot"]], empty=False)}
            for c in ("x", "y", *EVENT_SD_COLUMNS):
                if c in at:
                    event[c] = _number(events_path, line, c, row[at[c]], sd=c.endswith("_sd"))
                elif c in ("x", "y"):
                    event[c] = math.nan
            events.append(event)
    metadata = {}
    if meta_path.exists():
        text = _read_text(meta_path, "metadata file")
        try:
            metadata = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as err:
            raise TrajectoryError(f"{meta_path} is not valid JSON: {_first_line(err)}") from err
        except ValueError as err:  # e.g. an integer too long to convert
            raise TrajectoryError(f"cannot read {meta_path}: {_first_line(err)}") from err
        if not isinstance(metadata, dict):
            raise TrajectoryError(f"{meta_path} must hold a JSON object (the trajectory's metadata)")
    return TrajectoryTable(time, signals, stance, events, metadata)
