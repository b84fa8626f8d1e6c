"""Wall time of a full discrepancy analysis of a 30-stride walk, serial against 2 workers.

Run ``.venv/bin/python benchmarks/diagnose_speed.py`` (``make bench`` runs it too). It writes
``benchmarks/results/diagnose_speed.json`` and prints a table. The walk: 60 simulated steps (30
strides) of data/params/stable-toy.toml with a trailing-foot share of 0.1 and 0.002 rad of noise,
analysed with the base model that lacks the share (foot radius and lateral offset free, every
candidate of the library and the held parameters). The same analysis runs in one process and
with 2 local processes for the candidates' fits and the held-out folds (spawned: imports and
compiled functions loaded from the cache included); the share of each stage and of each
candidate's fit is recorded. The aim (issue 10): under 5 minutes on 2 cores. The machine may be
shared: compare the two runs within one invocation.
"""

from __future__ import annotations

import datetime
import os
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.discrepancy import diagnose

HERE = Path(__file__).parent
STEPS = 60
FREE = ["foot_radius", "com_offset[1]"]


def walk(params, seed: int = 7) -> TrajectoryTable:
    gait = find_gait(params)
    traj = simulate(params, gait.fixed_point, STEPS)
    rng = np.random.default_rng(seed)
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right}
    signals = {k: v + rng.normal(0.0, 0.002, v.shape) for k, v in signals.items()}
    events = [{"time": 0.0, "foot": "L"}] + [{"time": e.time, "foot": e.foot} for e in traj.events]
    return TrajectoryTable(traj.times, signals, traj.stance, events, {})


def main() -> None:
    toy = load_params(HERE.parent / "data" / "params" / "stable-toy.toml")
    table = walk(toy.replace(**{"effects.impact_trailing_share": 0.1}))
    runs = {}
    for workers in (1, 2):
        clock = time.perf_counter()
        d = diagnose(table, toy, free=FREE, model="periodic", workers=workers)
        wall = time.perf_counter() - clock
        runs[f"workers_{workers}"] = {"wall_s": wall, "cause": d.cause, "seconds": d.seconds}
        print(f"{workers} worker(s): {wall:6.1f} s, cause {d.cause}", flush=True)
        for stage, s in d.seconds.items():
            print(f"    {stage:<34s} {s:6.1f} s", flush=True)
    data = {
        "benchmark": "diagnose_speed", "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "steps": STEPS, "cpus": os.cpu_count(), "python": sys.version.split()[0], **runs,
        "speedup_2_workers": runs["workers_1"]["wall_s"] / runs["workers_2"]["wall_s"],
        "aim_s": 300.0,
    }
    out = HERE / "results" / "diagnose_speed.json"
    atomic_write_json(out, data)
    print(f"speed-up with 2 workers {data['speedup_2_workers']:.2f}x -> {out}")


if __name__ == "__main__":
    main()
