"""A local search for a hand launch that walks from 1.5 and 2.5 x lean, around docs/launch_converging.toml.

docs/launch_converging.toml (the first walker whose hand launch converges into its stable gait, at
1.0-1.2 x its lean amplitude) walks 12 steps from 1.5 x lean and 3 from 2.5 x. Issue 44 asks for
30 steps from both. This script walks the eleven parameters of docs/make_clearance_design.py
(:data:`FREE`) around it:

- **objective**: the launches at 1.5 and 2.5 x the gait's lean amplitude, each walked and scored as
  docs/make_robust_design.py walks them (:func:`launch_walk`, up to :data:`LAUNCH_STEPS` steps):
  per tip ``s = steps / LAUNCH_STEPS`` (1 when it converges to the gait), and
  ``score = min(s_1.5, s_2.5) + 0.02 mean(s) + 0.05 mean(closeness)``, closeness
  ``min(1, max(0, -log10(d_min) / 4))``, d_min the walk's closest approach to the fixed point
  (state_scale units), so that designs that walk equally far are ranked by how close they come;
- **feasibility**: a gait found by Newton from the parent's fixed point
  (``solve_fixed_point(Walker(params), z_parent)``) with max |eigenvalue| at most
  ``--max-eigenvalue`` (0.99) and the swing foot's clearance at least ``--min-clearance`` (0.2 mm;
  the start has 0.979 and 0.40 mm). Without these floors a first trial of 450 designs (1 min)
  drifted along the branch towards its fold: the lean amplitude (so the tips) shrank from 0.45 to
  0.12 deg, the clearance to 0.1 mm and max |eigenvalue| rose to 0.996 while the launch at
  2.5 x lean went from 3 to 14 steps, a walker that the kicks in MuJoCo would not survive; ``can_stand`` is
  checked (0.5 s) only for a design that beats the best so far, and one that can stand is not kept
  as the best (it stays a parent: the walk may pass through it);
- **walk**: each new design is a parent drawn from the :data:`PARENTS` best feasible designs,
  every parameter moved by a normal step of ``sigma`` x its range, ``sigma`` log-uniform in
  :data:`SIGMA` (0.3-3 %), the slope's step :data:`SLOPE_FACTOR` times smaller (the good designs
  sit just above the fold at the slow end of their slope window, where a step of 0.3 % of the
  slope's 0.1 rad range would already leave the stable branch);
- **box**: docs/make_clearance_design.py's :data:`BOUNDS`, but foot_radius up to 60 mm (its box ends
  at 30 mm; docs/launch_converging.toml has 39 mm).

Every design goes to ``--log`` (docs/launch_search.csv; parameters, gait, launches, score, the
fixed point) but those ``Params`` refuses (an inertia whose principal moments break the triangle
inequality, a lateral foot radius above the fore-aft one: half the designs of the run in
docs/gaits.md section 7, which are only counted, to keep the log under 2 MB).
Then ``--finalists N``: the N best designs that cannot stand, re-solved and measured
with :func:`hand_launch` at 0.5-3 x lean (400 steps), the clearance, ``can_stand``, and in MuJoCo
(:func:`walk_in_mujoco`): the launches at 1.5 and 2.5 x lean (100 steps) at the contact settings of
:data:`MUJOCO_SETTINGS`, and the kicks of docs/make_basin.py (each of the four rates kicked by
+-0.02 rad/s, signs from seeds 0-7; 60 steps) at :data:`KICK_SETTINGS`. The finalists go to
docs/launch_search_finalists.csv, the best to docs/launch_search_best.toml.

Run (one core of a shared 2-core machine, compiled kernels cached; 0.2-2 s a design)::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python docs/make_launch_search.py --minutes 30
    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python docs/make_launch_search.py --minutes 0 --finalists 3
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, can_stand, load_params, save_params, solve_fixed_point
from toywalk.model.basin import hand_launch, launch_state
from toywalk.model.gait import GaitNotFound
from toywalk.model.parameters import ParameterError
from toywalk.model.walker import StepFailure

sys.path.insert(0, str(Path(__file__).resolve().parent))
# The free parameters and their box (the clearance design's), and the launch as the robust design
# search walks it.
from make_clearance_design import BOUNDS as CLEARANCE_BOUNDS  # noqa: E402
from make_clearance_design import FREE  # noqa: E402
from make_launch_margin import fmt_cell, read_rows  # noqa: E402
from make_robust_design import LAUNCH_STEPS, launch_walk  # noqa: E402

HERE = Path(__file__).resolve().parent
START = HERE / "launch_converging.toml"
#: docs/make_clearance_design.py's box, foot_radius widened from 30 to 60 mm (the start has 39 mm).
BOUNDS = {**CLEARANCE_BOUNDS, "foot_radius": (0.002, 0.06)}
LO = np.array([BOUNDS[n][0] for n in FREE])
HI = np.array([BOUNDS[n][1] for n in FREE])
TIPS = (1.5, 2.5)  # multiples of the gait's lean amplitude: issue 44's launches
PARENTS = 4
SIGMA = (0.003, 0.03)  # normal steps, fraction of each parameter's range
SLOPE_FACTOR = 0.1
#: Finalists: hand_launch tips (x lean), MuJoCo contact settings (time constant s, friction).
CHECK_TIPS = (0.5, 1.0, 1.2, 1.5, 2.0, 2.5, 3.0)
MUJOCO_SETTINGS = ((1e-3, 2.0), (2e-3, 1.0), (4e-3, 0.6))
KICK_SETTINGS = ((1e-3, 2.0), (4e-3, 0.6))
KICK = 0.02  # rad/s
MUJOCO_LAUNCH_STEPS = 100
KICK_STEPS = 60
COLUMNS = ["design", "parent", "sigma", *FREE, "feasible", "why", "max_abs_eigenvalue", "clearance_mm",
           "lean_deg", "step_time", *(f"{k}_{m:g}" for m in TIPS for k in ("steps", "reason", "dmin")),
           "score", "can_stand", *(f"z{i}" for i in range(8))]


def score(walks: list[dict]) -> float:
    """The launches' score (0 .. 1.07): the worse tip's share of the step budget, plus small terms
    for the mean share and the closeness of approach."""
    share = [1.0 if w["recovered"] else w["steps"] / LAUNCH_STEPS for w in walks]
    close = [min(1.0, max(0.0, -math.log10(w["dmin"]) / 4)) if math.isfinite(w["dmin"]) and w["dmin"] > 0
             else (1.0 if w["recovered"] else 0.0) for w in walks]
    return min(share) + 0.02 * float(np.mean(share)) + 0.05 * float(np.mean(close))


class Search:
    """The evolutionary walk: every design evaluated is logged; the feasible ones are the archive."""

    def __init__(self, log: Path, rng: np.random.Generator, max_eigenvalue: float = 0.99,
                 min_clearance: float = 0.2e-3):
        self.max_eigenvalue = max_eigenvalue
        self.min_clearance = min_clearance  # m
        self.base = load_params(START)
        self.rng = rng
        self.archive: list[dict] = []
        self.best: dict | None = None
        self.n = 0
        self.rejected = 0  # designs that Params refuses (not logged, to keep the log small)
        self.file = open(log, "w", newline="")  # noqa: SIM115 -- closed by close()
        self.writer = csv.DictWriter(self.file, fieldnames=COLUMNS)
        self.writer.writeheader()

    def close(self) -> None:
        self.file.close()

    def params_at(self, x: np.ndarray):
        return self.base.replace(**{n: float(v) for n, v in zip(FREE, x, strict=True)})

    def evaluate(self, x: np.ndarray, z: np.ndarray, parent: int = -1, sigma: float = 0.0) -> dict:
        row = {"design": self.n, "parent": parent, "sigma": sigma, **dict(zip(FREE, x, strict=True)),
               "feasible": 0, "why": ""}
        self.n += 1
        try:
            params = self.params_at(x)
            gait = solve_fixed_point(Walker(params), z)
        except ParameterError:
            row["why"] = "parameters"
        except (GaitNotFound, StepFailure):
            row["why"] = "no gait"
        else:
            row.update(max_abs_eigenvalue=gait.max_abs_eigenvalue, clearance_mm=1e3 * gait.clearance,
                       lean_deg=math.degrees(gait.lean_amplitude), step_time=gait.step_time,
                       **{f"z{i}": v for i, v in enumerate(gait.fixed_point)})
            if gait.max_abs_eigenvalue >= 1:
                row["why"] = "unstable"
            elif gait.max_abs_eigenvalue > self.max_eigenvalue:
                row["why"] = "eigenvalue"
            elif gait.clearance < self.min_clearance:
                row["why"] = "clearance"
            else:
                walker = Walker(params)
                walks = [launch_walk(walker, gait, m * gait.lean_amplitude) for m in TIPS]
                for m, w in zip(TIPS, walks, strict=True):
                    row.update({f"steps_{m:g}": w["steps"], f"reason_{m:g}": w["reason"],
                                f"dmin_{m:g}": w["dmin"]})
                row.update(feasible=1, score=score(walks))
                if self.best is None or row["score"] > self.best["score"]:
                    stands = can_stand(params).can_stand
                    row["can_stand"] = int(stands)
                    if not stands:
                        self.best = row
                self.archive.append({**row, "x": np.array(x, dtype=float), "z": gait.fixed_point})
        if row["why"] == "parameters":
            self.rejected += 1
        else:
            self.writer.writerow({k: fmt_cell(v, 10 if k[0] == "z" else 6) for k, v in row.items()})
        return row

    def child(self) -> tuple[np.ndarray, np.ndarray, int, float]:
        """A parent drawn from the :data:`PARENTS` best, moved by a normal step."""
        ranked = sorted(self.archive, key=lambda r: -r["score"])[:PARENTS]
        parent = ranked[self.rng.integers(len(ranked))]
        sigma = float(np.exp(self.rng.uniform(*np.log(SIGMA))))
        step = sigma * (HI - LO) * self.rng.standard_normal(len(FREE))
        step[FREE.index("slope")] *= SLOPE_FACTOR
        return np.clip(parent["x"] + step, LO, HI), parent["z"], parent["design"], sigma


def walk(search: Search, minutes: float) -> None:
    x0 = np.array([search.base.get(n) for n in FREE])
    first = search.evaluate(x0, np.array(search.base.gait_start))
    print(f"start: score {first.get('score')}, steps {first.get('steps_1.5')} / {first.get('steps_2.5')}",
          flush=True)
    t0 = time.perf_counter()
    last = t0
    while time.perf_counter() - t0 < 60 * minutes:
        x, z, parent, sigma = search.child()
        row = search.evaluate(x, z, parent, sigma)
        if row is search.best:
            print(f"{row['design']:5d} new best {row['score']:.4f}: "
                  f"steps {row['steps_1.5']} / {row['steps_2.5']} "
                  f"({row['reason_1.5']} / {row['reason_2.5']}), |lambda| {row['max_abs_eigenvalue']:.4f}, "
                  f"clear {row['clearance_mm']:.2f} mm, sigma {sigma:.4f}, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
        if time.perf_counter() - last > 60:
            last = time.perf_counter()
            feasible = len(search.archive)
            print(f"{search.n:5d} designs, {feasible} stable, best {search.best['score']:.4f}, "
                  f"{last - t0:.0f} s", flush=True)


def _kick_signs() -> list[tuple]:
    """The distinct sign patterns of the kicks of seeds 0-7 (docs/make_basin.py), each with its seeds."""
    signs: dict[tuple, list[int]] = {}
    for seed in range(8):
        signs.setdefault(tuple(np.random.default_rng(seed).choice([-1.0, 1.0], 4)), []).append(seed)
    return list(signs.items())


def finalists(log: Path, n: int, mujoco: int) -> list[dict]:
    """The ``n`` best designs of the log that cannot stand, measured in full; MuJoCo for the first
    ``mujoco`` of them."""
    from toywalk.model.mujoco_check import walk_in_mujoco

    base = load_params(START)
    rows = [r for r in read_rows(log) if r["feasible"] == 1]
    rows.sort(key=lambda r: -r["score"])
    out, seen = [], set()
    for r in rows:
        if len(out) >= n:
            break
        key = tuple(round(float(r[p]), 9) for p in FREE)
        if key in seen:
            continue
        seen.add(key)
        params = base.replace(**{p: float(r[p]) for p in FREE})
        if can_stand(params).can_stand:
            continue
        gait = solve_fixed_point(Walker(params), np.array([float(r[f"z{i}"]) for i in range(8)]))
        lean = gait.lean_amplitude
        launch = hand_launch(params, [m * lean for m in CHECK_TIPS], gait=gait, steps=400)
        res = launch.results[0]
        m = {"design": int(r["design"]), "score": r["score"], "max_abs_eigenvalue": gait.max_abs_eigenvalue,
             "clearance_mm": 1e3 * gait.clearance, "lean_deg": math.degrees(lean), "can_stand": 0,
             "hand_launch": " ".join(f"{t:g}:{x.steps}{'+' if ok else '-'}" for t, x, ok
                                     in zip(CHECK_TIPS, res, launch.recovered()[0], strict=True)),
             "params": params, "gait": gait}
        print(f"design {m['design']}: score {r['score']:.4f}, |lambda| {m['max_abs_eigenvalue']:.4f}, "
              f"clear {m['clearance_mm']:.2f} mm, lean {m['lean_deg']:.3f} deg; hand_launch "
              f"(tip: steps, + converged) {m['hand_launch']}", flush=True)
        if len(out) < mujoco:
            t0 = time.perf_counter()
            for tc, mu in MUJOCO_SETTINGS:
                for tip in TIPS:
                    w = walk_in_mujoco(params, launch_state(tip * lean), steps=MUJOCO_LAUNCH_STEPS,
                                       friction=mu, contact_time=tc,
                                       max_time=3.0 * MUJOCO_LAUNCH_STEPS * gait.step_time)
                    m[f"mj_launch_{tip:g}_{1e3 * tc:g}ms_{mu:g}"] = f"{w.steps} {w.status}"
                    print(f"  MuJoCo launch {tip:g} x lean at ({1e3 * tc:g} ms, {mu:g}): {w.steps} steps, "
                          f"{w.status} ({w.message}), {time.perf_counter() - t0:.0f} s", flush=True)
            for tc, mu in KICK_SETTINGS:
                walked = 0
                for signs, seeds in _kick_signs():
                    z0 = gait.fixed_point.copy()
                    z0[[1, 3, 5, 7]] += KICK * np.array(signs)
                    w = walk_in_mujoco(params, z0, steps=KICK_STEPS, friction=mu, contact_time=tc,
                                       max_time=2.0 * KICK_STEPS * gait.step_time)
                    if w.status == "completed" and w.steps == KICK_STEPS:
                        walked += len(seeds)
                m[f"mj_kicks_{1e3 * tc:g}ms_{mu:g}"] = f"{walked}/8"
                print(f"  MuJoCo kicks at ({1e3 * tc:g} ms, {mu:g}): {walked} of 8 walk {KICK_STEPS} steps, "
                      f"{time.perf_counter() - t0:.0f} s", flush=True)
        out.append(m)
    return out


def write_finalists(found: list[dict]) -> None:
    keys = []
    for m in found:
        keys += [k for k in m if k not in keys and k not in ("params", "gait")]
    with open(HERE / "launch_search_finalists.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows({k: fmt_cell(m.get(k, ""), 6) for k in keys} for m in found)
    best = found[0]
    mj = "; ".join(f"{k[3:]} {v}" for k, v in best.items() if k.startswith("mj_"))
    header = (f"The best design of docs/make_launch_search.py (design {best['design']}, "
              f"score {best['score']:.4f}):\n"
              f"max |eigenvalue| {best['max_abs_eigenvalue']:.4f}, clearance {best['clearance_mm']:.2f} mm, "
              f"lean amplitude {best['lean_deg']:.3f} deg, can_stand False.\n"
              f"hand_launch (400 steps; tip x lean: steps, + converged): {best['hand_launch']}.\n"
              f"MuJoCo: {mj or 'not run'}.\n[gait] start is its fixed point.")
    start = tuple(float(v) for v in best["gait"].fixed_point)
    save_params(dataclasses.replace(best["params"], gait_start=start), HERE / "launch_search_best.toml",
                header=header)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=35.0, help="compute budget of the walk (min)")
    parser.add_argument("--finalists", type=int, default=3)
    parser.add_argument("--mujoco", type=int, default=1, help="finalists checked in MuJoCo")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-eigenvalue", type=float, default=0.99)
    parser.add_argument("--min-clearance", type=float, default=0.2, help="mm")
    parser.add_argument("--log", type=Path, default=HERE / "launch_search.csv")
    args = parser.parse_args()
    if args.minutes > 0:
        search = Search(args.log, np.random.default_rng(args.seed), args.max_eigenvalue,
                        1e-3 * args.min_clearance)
        try:
            walk(search, args.minutes)
        finally:
            search.close()
        reasons = {"parameters (not logged)": search.rejected}
        for r in read_rows(args.log):
            reasons[r["why"] or "stable"] = reasons.get(r["why"] or "stable", 0) + 1
        print(f"{search.n} designs: {reasons}; best {search.best}", flush=True)
    if args.finalists > 0:
        found = finalists(args.log, args.finalists, args.mujoco)
        if found:
            write_finalists(found)


if __name__ == "__main__":
    main()
