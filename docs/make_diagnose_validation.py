"""Measure the discrepancy analysis: its false-alarm rate on walks of the base model, and whether
it names each effect of the library hidden in a walk.

    python docs/make_diagnose_validation.py null [SEEDS]      -> docs/diagnose_null.csv
    python docs/make_diagnose_validation.py effects           -> docs/diagnose_effects.csv

Walks: the stable toy (data/params/stable-toy.toml), 12 steps from its gait, 0.002 rad of white
noise on every angle (a tracker's level), no contact positions; the base model frees the foot
radius and the lateral mass offset. Hidden effects at their library ``typical`` magnitude (one
that visibly changes the toy's gait). Each row is written as soon as it is measured, so a killed
run keeps its rows.
"""

from __future__ import annotations

import csv
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
TOY = load_params(HERE.parent / "data" / "params" / "stable-toy.toml")
FREE = ["foot_radius", "com_offset[1]"]
NOISE = 0.002
STEPS = 12


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
    for k, (name, effect) in enumerate(EFFECTS.items()):
        if f"effects.{name}" in done:
            continue
        truth = TOY.replace(**{f"effects.{name}": effect.typical})
        clock = time.perf_counter()
        try:
            d = diagnose(walk(truth, 200 + k), TOY, free=FREE, model="periodic")
        except Exception as err:  # recorded, so the table says what failed and why
            _append(out, {"effect": f"effects.{name}", "truth": effect.typical, "verdict": "error",
                          "cause": type(err).__name__, "named": False, "interval": str(err)[:120],
                          "covers": False, "seconds": f"{time.perf_counter() - clock:.1f}"})
            continue
        row = next((r for r in d.ranking if r["effect"] == f"effects.{name}"), {})
        interval = row.get("interval", {}).get(f"effects.{name}")
        covers = bool(interval and interval[0] < effect.typical < interval[1])
        _append(out, {"effect": f"effects.{name}", "truth": effect.typical, "verdict": d.verdict,
                      "cause": d.cause, "named": d.cause == f"effects.{name}",
                      "interval": f"[{interval[0]:.4g}, {interval[1]:.4g}]" if interval else "",
                      "covers": covers, "seconds": f"{time.perf_counter() - clock:.1f}"})
        print(name, d.verdict, d.cause, interval, flush=True)


if __name__ == "__main__":
    if sys.argv[1:2] == ["null"]:
        null(int(sys.argv[2]) if len(sys.argv) > 2 else 20)
    elif sys.argv[1:2] == ["effects"]:
        effects()
    else:
        sys.exit(__doc__)
