"""The basin in MuJoCo against the model's: hand launches and kicks (docs/gaits.md section 8).

    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_basin_mujoco.py   # about 3 minutes

For docs/robust_best.toml (the design search's best, section 7) and data/params/clearing-toy.toml,
from three kinds of start, each walked at most 60 steps:

- the gait's fixed point (the reference: does the engine walk the gait at all?);
- the hand launch at 1.5 and 2.5 times the gait's lean amplitude (``launch_state``: at rest, legs
  parallel and normal to the ramp, tipped onto the left foot, the right leg 1e-5 rad back);
- the fixed point with its four rates kicked by 0.02 rad/s with random signs, seeds 0-7
  (``np.random.default_rng(seed)``, as docs/make_basin.py kicks them; seeds 2 and 3 draw the
  same signs, and so do 4 and 7, so there are six distinct kicks).

The model walks with the step map (``Walker.step``) until a step fails (fell, no heel strike) or
its swing foot scuffs (a failure for these two gaits, which clear, as in ``recovers``). MuJoCo
walks with ``walk_in_mujoco`` at four contact settings (time constant, friction): the checked
build (1 ms, 2) and (1 ms, 1), (2 ms, 1), (2 ms, 0.6) from issue 44's range, 1e-4 s steps, giving
up after twice the gait's time for 60 steps. Writes docs/basin_mujoco.csv, one row per walker,
engine setting and start: ``steps`` walked (MuJoCo's alternating heel strikes), ``outcome``
(model: ``walked``, ``fell``, ``no_heel_strike``, ``scuffed``; MuJoCo: ``walked``, ``fell`` (a
hip down to half the leg length), ``same foot twice`` (which ``walk_in_mujoco`` also reports as
a fall; ``..., walked on`` when 60 heel strikes came all the same: the landing foot bounced once),
``timed out``), ``heel_strikes`` (all of them, alternating or not), ``scuffs``, ``end_time_s``
(model: its last heel strike; MuJoCo: the end of the walk, the fall's time), ``end_distance``
(model: from the fixed point at its last heel strike, state_scale units),
``last10_step_time_ms`` (MuJoCo: mean of its last ten steps), and the seconds each walk took.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, find_gait, load_params
from toywalk.model.basin import launch_state
from toywalk.model.gait import state_scale
from toywalk.model.mujoco_check import walk_in_mujoco
from toywalk.model.walker import StepFailure

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
WALKERS = {"robust-best": HERE / "robust_best.toml",
           "clearing-toy": ROOT / "data" / "params" / "clearing-toy.toml"}
CAP = 60  # steps walked at most
LAUNCH_MULTIPLES = (1.5, 2.5)  # tip angles, times the gait's lean amplitude (issue 44)
KICK = 0.02  # rad/s on each of the four rates, random signs (issue 44)
SEEDS = range(8)
# MuJoCo's contacts: (time constant (s), friction coefficient); the first is the checked build.
SETTINGS = ((1e-3, 2.0), (1e-3, 1.0), (2e-3, 1.0), (2e-3, 0.6))
TIMESTEP = 1e-4  # s, walk_in_mujoco's default


def _starts(gait) -> list[tuple[str, float, np.ndarray]]:
    """(label, tip angle (deg, NaN for none), public state just after a left heel strike or at
    release)."""
    out = [("fixed point", math.nan, gait.fixed_point.copy())]
    for m in LAUNCH_MULTIPLES:
        tip = m * gait.lean_amplitude
        out.append((f"launch {m} x lean", math.degrees(tip), launch_state(tip)))
    for seed in SEEDS:
        z = gait.fixed_point.copy()
        z[[1, 3, 5, 7]] += KICK * np.random.default_rng(seed).choice([-1.0, 1.0], 4)
        out.append((f"kick seed {seed}", math.nan, z))
    return out


def _model_walk(gait, walker: Walker, z0: np.ndarray) -> tuple[int, str, int, float, float]:
    """(steps walked, how it ended, scuffs, distance from the fixed point at the last heel strike
    (state_scale units), time to the last heel strike (s))."""
    scale = state_scale(gait.params)
    z, side, distance, elapsed = z0, 1, math.nan, 0.0
    for k in range(CAP):
        try:
            step = walker.step(z, side=side)
        except StepFailure as err:
            return k, err.status, 0, distance, elapsed
        z, side = step.z_plus, -side
        elapsed += step.step_time
        distance = float(np.linalg.norm((z - gait.fixed_point) / scale))
        if step.scuffs:
            return k + 1, "scuffed", step.scuffs, distance, elapsed
    return CAP, "walked", 0, distance, elapsed


def measure() -> list[dict]:
    rows = []
    for name, path in WALKERS.items():
        gait = find_gait(load_params(path))
        params, walker = gait.params, Walker(gait.params)
        stable = bool(np.max(np.abs(gait.eigenvalues)) < 1.0)
        print(f"{name}: max |eigenvalue| {np.max(np.abs(gait.eigenvalues)):.4f} (stable: {stable}), "
              f"step time {gait.step_time:.4f} s, lean amplitude {math.degrees(gait.lean_amplitude):.3f} deg",
              flush=True)
        max_time = 2.0 * CAP * gait.step_time
        for label, tip, z0 in _starts(gait):
            t = time.perf_counter()
            steps, reason, scuffs, distance, elapsed = _model_walk(gait, walker, z0)
            rows.append(dict(walker=name, engine="model", contact_time_ms="", friction="", start=label,
                             tip_deg=tip, steps=steps, outcome=reason, heel_strikes=steps, scuffs=scuffs,
                             end_time_s=elapsed,
                             end_distance=distance, last10_step_time_ms=math.nan,
                             seconds=time.perf_counter() - t))
            for contact_time, friction in SETTINGS:
                t = time.perf_counter()
                walk = walk_in_mujoco(params, z0, steps=CAP, timestep=TIMESTEP, friction=friction,
                                      contact_time=contact_time, max_time=max_time)
                if walk.status == "completed":
                    outcome = "walked"
                elif walk.message.startswith("no "):
                    outcome = "timed out"
                elif "same foot" in walk.message and len(walk.feet) >= CAP:
                    # a landing foot that left the ramp for over 2 ms and landed again (a bounce):
                    # walk_in_mujoco stops counting steps there, but the walker walked on
                    outcome = "same foot twice, walked on"
                elif "same foot" in walk.message:
                    outcome = "same foot twice"
                else:
                    outcome = "fell"
                last = walk.step_times[-10:]
                last_ms = round(1e3 * float(np.mean(last)), 3) if len(last) else math.nan
                rows.append(dict(walker=name, engine="mujoco", contact_time_ms=1e3 * contact_time,
                                 friction=friction, start=label, tip_deg=tip, steps=walk.steps,
                                 outcome=outcome, heel_strikes=len(walk.feet), scuffs=walk.scuffs,
                                 end_time_s=walk.duration,
                                 end_distance=math.nan,
                                 last10_step_time_ms=last_ms,
                                 seconds=time.perf_counter() - t))
            print(f"  {label:18s} model {steps:2d} {reason:15s} | MuJoCo "
                  + "  ".join(f"{r['steps']:2d} {r['outcome']}" for r in rows[-len(SETTINGS):]), flush=True)
    return rows


def main() -> None:
    start = time.perf_counter()
    rows = measure()
    with open(HERE / "basin_mujoco.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote docs/basin_mujoco.csv ({len(rows)} rows) in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
