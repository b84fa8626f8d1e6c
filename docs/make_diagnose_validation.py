"""Measure the discrepancy analysis: its false-alarm rate on walks of the base model, and whether
it names each effect of the library hidden in a walk.

    python docs/make_diagnose_validation.py null [SEEDS]      -> docs/diagnose_null.csv
    python docs/make_diagnose_validation.py effects [--shift S] [NAME ...]
                                                            -> docs/diagnose_effects.csv (and .json)

Walks: the stable toy (data/params/stable-toy.toml), 12 steps from its gait, 0.002 rad of white
noise on every angle (a tracker's level), no contact positions; the base model frees the foot
radius and the lateral mass offset, and the fit its nuisance offsets of lean, steer and pitch.

Each hidden effect at the strength whose change to the gait moves it by SHIFT noise SDs beyond
what the base's free parameters and the nuisance offsets can mimic (:func:`magnitude`; the
largest change of any angle over a stride, phase for phase, after a least-squares refit of those
unknowns, linearised). The first rows of the table were measured with the change before any refit
(column ``scale`` = ``gait``); for two effects of the library that is no test at all: an uneven
build's gait is 97 % a steer offset, and a cross slope only turns the fall line (beyond a steer
offset it moves the gait by 1e-3 SD). A cross slope is therefore measured with the
offsets held (``offsets`` = ``held``: the ramp's frame known, as from markers along its edge).
The library's ``typical`` magnitudes move the stable toy's gait by tens of SDs or leave it without
a gait. Each row is written as soon as it is measured, so a killed run keeps its rows; ``effects``
with names measures only those; ``--shift S`` hides them at S noise SDs beyond instead of
:data:`SHIFT` (rows with ``scale`` = ``beyond S``: where the library's candidates that tie at 3
SDs come apart).
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model.effects import EFFECTS, LIBRARY
from toywalk.model.gait import find_gait
from toywalk.model.parameters import PARAMETER_NAMES, load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.discrepancy import diagnose
from toywalk.sysid.fit import with_values

HERE = Path(__file__).parent
WORKERS = 2
TOY = load_params(HERE.parent / "data" / "params" / "stable-toy.toml")
FREE = ["foot_radius", "com_offset[1]"]
NOISE = 0.002
STEPS = 12
#: How far a hidden effect moves the gait, in noise SDs (the issue: "a few").
SHIFT = 3.0


def stride_curve(params) -> np.ndarray:
    """The gait's lean, steer and pitches over one stride (two steps) at 201 equal phases."""
    gait = find_gait(params)
    traj = simulate(params, gait.fixed_point, 2, sample_rate=5000.0)
    left, right = traj.pitches()
    phase = traj.times / traj.events[-1].time
    grid = np.linspace(0.0, 1.0, 201)
    return np.array([np.interp(grid, phase, s) for s in (traj.lean, traj.steer, left, right)])


def mimicked(base=TOY, offsets: bool = True) -> np.ndarray:
    """Columns (201 * 4, k) of what the base fit can do to the stride curve: the free parameters'
    derivatives (central differences, 1e-3 of each value) and, with ``offsets``, a constant shift
    of lean, of steer and of both pitches."""
    values = dict(zip(PARAMETER_NAMES, base.vector(), strict=True))
    start = {n: float(values[n]) for n in FREE}
    columns = []
    for name in FREE:
        h = 1e-3 * abs(start[name])
        up, down = (stride_curve(with_values(base, FREE, {**start, name: start[name] + d})).ravel()
                    for d in (h, -h))
        columns.append((up - down) / (2 * h))
    if offsets:
        for rows in ([0], [1], [2, 3]):
            shift = np.zeros((4, 201))
            shift[rows] = NOISE
            columns.append(shift.ravel())
    return np.array(columns).T


def shift_sds(params, base=TOY, columns=None) -> tuple[float, float]:
    """How far ``params``' gait lies from ``base``'s, in noise SDs: the largest change of any angle
    over a stride, phase for phase, before and after a least-squares refit on ``columns``
    (:func:`mimicked`)."""
    change = (stride_curve(params) - stride_curve(base)).ravel()
    left = change
    if columns is not None:
        left = change - columns @ np.linalg.lstsq(columns, change, rcond=None)[0]
    return float(np.max(np.abs(change))) / NOISE, float(np.max(np.abs(left))) / NOISE


def magnitude(name: str, base=TOY, offsets: bool = True, shift: float = SHIFT) -> tuple[float, float, float]:
    """The strength of effect ``name`` that moves ``base``'s gait by ``shift`` noise SDs beyond
    what the base fit mimics (:func:`shift_sds`), with the shifts measured there (before, after
    the refit): from the ``typical`` magnitude (or a tenth of it, or a hundredth, where it leaves
    the walker without a gait), two secant steps in the magnitude."""
    columns = mimicked(base, offsets)

    def shifts(m):
        return shift_sds(base.replace(**{f"effects.{name}": m}), base, columns)

    m = EFFECTS[name].typical
    for _ in range(3):
        try:
            s = shifts(m)
            break
        except Exception:  # no gait at this strength: try a tenth of it
            m /= 10.0
    else:
        raise RuntimeError(f"no gait with {name} at a thousandth of its typical magnitude")
    for _ in range(2):
        m *= shift / s[1]
        s = shifts(m)
    return m, *s


def walk(params, seed: int, noise: float = NOISE) -> TrajectoryTable:
    """A simulated walk from the gait with white noise of SD ``noise`` (rad), heel strikes from
    the first."""
    gait = find_gait(params)
    traj = simulate(params, gait.fixed_point, STEPS)
    rng = np.random.default_rng(seed)
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right}
    signals = {k: v + rng.normal(0.0, noise, v.shape) for k, v in signals.items()}
    events = [{"time": 0.0, "foot": "L"}] + [{"time": e.time, "foot": e.foot} for e in traj.events]
    return TrajectoryTable(traj.times, signals, traj.stance, events, {})


def _append(path: Path, row: dict) -> None:
    new = not path.exists()
    with open(path, "a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(row))
        if new:
            writer.writeheader()
        writer.writerow(row)
        fh.flush()


def null(seeds: int) -> None:
    out = HERE / "diagnose_null.csv"
    done = set()
    if out.exists():
        with open(out) as fh:
            done = {int(r["seed"]) for r in csv.DictReader(fh)}
    for seed in range(100, 100 + seeds):
        if seed in done:
            continue
        clock = time.perf_counter()
        d = diagnose(walk(TOY, seed), TOY, free=FREE, model="periodic")
        best = min(d.ranking, key=lambda r: r["score_p"])
        _append(out, {"seed": seed, "verdict": d.verdict, "cause": d.cause,
                      "best_candidate": best["effect"], "best_score_p": f"{best['score_p']:.4g}",
                      "systematic": ";".join(d.residuals.systematic),
                      "seconds": f"{time.perf_counter() - clock:.1f}"})
        print(seed, d.verdict, d.cause, flush=True)


#: Effects measured with the nuisance offsets held (module docstring).
HELD_OFFSETS = ("cross_slope",)


def effects(names=(), shift: float = SHIFT) -> None:
    out = HERE / "diagnose_effects.csv"
    done = set()
    if out.exists():
        with open(out) as fh:
            done = {(r["effect"], r["offsets"], r["scale"]) for r in csv.DictReader(fh)}
    for k, name in enumerate(LIBRARY):
        offsets = name not in HELD_OFFSETS
        key = (f"effects.{name}", "free" if offsets else "held",
               "beyond" if shift == SHIFT else f"beyond {shift:g}")
        if key in done or (names and name not in names):
            continue
        clock = time.perf_counter()
        size, moved, beyond = magnitude(name, offsets=offsets, shift=shift)
        truth = TOY.replace(**{f"effects.{name}": size})
        head = {"effect": key[0], "offsets": key[1], "scale": key[2], "truth": f"{size:.4g}",
                "shift_sd": f"{moved:.2f}", "beyond_sd": f"{beyond:.2f}"}
        try:
            d = diagnose(walk(truth, 200 + k), TOY, free=FREE, model="periodic", workers=WORKERS,
                         offsets=offsets)
        except Exception as err:  # recorded, so the table says what failed and why
            _append(out, {**head, "verdict": "error", "cause": type(err).__name__, "named": False,
                          "interval": str(err)[:120], "covers": False, "runner_up": "",
                          "seconds": f"{time.perf_counter() - clock:.1f}"})
            continue
        row = next((r for r in d.ranking if r["effect"] == f"effects.{name}"), {})
        interval = row.get("interval", {}).get(f"effects.{name}")
        covers = bool(interval and interval[0] < size < interval[1])
        others = [r for r in d.ranking if r["effect"] != f"effects.{name}" and "lr" in r]
        _append(out, {**head, "verdict": d.verdict, "cause": d.cause,
                      "named": d.cause == f"effects.{name}",
                      "interval": f"[{interval[0]:.4g}, {interval[1]:.4g}]" if interval else "",
                      "covers": covers,
                      "runner_up": f"{others[0]['effect']} ({row.get('lr', math.nan) - others[0]['lr']:.1f})"
                      if others else "",
                      "seconds": f"{time.perf_counter() - clock:.1f}"})
        _record(HERE / "diagnose_effects.json", "|".join(key), size, d)
        print(name, f"{size:.4g}", d.verdict, d.cause, interval, flush=True)


def _record(path: Path, key: str, truth: float, d) -> None:
    """The analysis behind a row, for a reader who asks why: its evidence and the fitted
    candidates (likelihood ratio, status or why not fitted, estimate, held-out gain)."""
    store = json.loads(path.read_text()) if path.exists() else {}
    fitted = [{k: r.get(k) for k in ("effect", "score_z", "lr", "fitted", "status", "reason", "estimate",
                                     "held_out_gain")} for r in d.ranking if "fitted" in r]
    store[key] = {"truth": truth, "verdict": d.verdict, "cause": d.cause, "evidence": d.evidence,
                  "noise_source": d.base.noise_source, "fitted": fitted}
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(store, indent=1) + "\n")
    tmp.replace(path)


if __name__ == "__main__":
    if sys.argv[1:2] == ["null"]:
        null(int(sys.argv[2]) if len(sys.argv) > 2 else 20)
    elif sys.argv[1:2] == ["effects"]:
        rest = sys.argv[2:]
        if rest[:1] == ["--shift"]:
            if len(rest) < 2:
                sys.exit("--shift needs a number of noise SDs")
            effects(rest[2:], float(rest[1]))
        else:
            effects(rest)
    else:
        sys.exit(__doc__)
