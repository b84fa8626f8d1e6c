"""Measure the discrepancy analysis: its false-alarm rate on walks of the base model, and whether
it names each effect of the library hidden in a walk.

    python docs/make_diagnose_validation.py null [SEEDS]      -> docs/diagnose_null.csv
    python docs/make_diagnose_validation.py effects           -> docs/diagnose_effects.csv

Walks: the stable toy (data/params/stable-toy.toml), 12 steps from its gait, 0.002 rad of white
noise on every angle (a tracker's level), no contact positions; the base model frees the foot
radius and the lateral mass offset. Each hidden effect at the magnitude that moves the gait by
SHIFT noise SDs (the largest change of any angle over a stride of the gait, phase for phase:
:func:`magnitude`); the library's ``typical`` magnitudes move the stable toy's gait by tens of
SDs or leave it without a gait. Each row is written as soon as it is measured, so a killed run
keeps its rows.
"""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model.effects import EFFECTS
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.discrepancy import diagnose

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


def magnitude(name: str, base=TOY) -> tuple[float, float]:
    """The strength of effect ``name`` that moves ``base``'s gait by :data:`SHIFT` noise SDs, and
    the shift measured there: from the ``typical`` magnitude (or a tenth of it, or a hundredth,
    where it leaves the walker without a gait), two secant steps in the magnitude."""
    ref = stride_curve(base)

    def shift(m):
        return float(np.max(np.abs(stride_curve(base.replace(**{f"effects.{name}": m})) - ref))) / NOISE

    m = EFFECTS[name].typical
    for _ in range(3):
        try:
            s = shift(m)
            break
        except Exception:  # no gait at this strength: try a tenth of it
            m /= 10.0
    else:
        raise RuntimeError(f"no gait with {name} at a thousandth of its typical magnitude")
    for _ in range(2):
        m *= SHIFT / s
        s = shift(m)
    return m, s


def walk(params, seed: int) -> TrajectoryTable:
    """A simulated walk from the gait with white noise, heel strikes from the first."""
    gait = find_gait(params)
    traj = simulate(params, gait.fixed_point, STEPS)
    rng = np.random.default_rng(seed)
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right}
    signals = {k: v + rng.normal(0.0, NOISE, v.shape) for k, v in signals.items()}
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


def effects() -> None:
    out = HERE / "diagnose_effects.csv"
    done = set()
    if out.exists():
        with open(out) as fh:
            done = {r["effect"] for r in csv.DictReader(fh)}
    for k, name in enumerate(EFFECTS):
        if f"effects.{name}" in done:
            continue
        clock = time.perf_counter()
        size, moved = magnitude(name)
        truth = TOY.replace(**{f"effects.{name}": size})
        head = {"effect": f"effects.{name}", "truth": f"{size:.4g}", "shift_sd": f"{moved:.2f}"}
        try:
            d = diagnose(walk(truth, 200 + k), TOY, free=FREE, model="periodic", workers=WORKERS)
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
        print(name, f"{size:.4g}", d.verdict, d.cause, interval, flush=True)


if __name__ == "__main__":
    if sys.argv[1:2] == ["null"]:
        null(int(sys.argv[2]) if len(sys.argv) > 2 else 20)
    elif sys.argv[1:2] == ["effects"]:
        effects()
    else:
        sys.exit(__doc__)
