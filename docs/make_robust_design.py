"""A walker you can launch by hand? The design search of docs/gaits.md section 7 (issue 44, part 2).

Hand launch (:func:`toywalk.model.basin.hand_launch`) is all or nothing, and no shipped walker has
one that converges, so the search scores a design by a *continuous* measure of how close its
launches come to the gait, and by its basin in random directions:

- ``launch``: for tips of :data:`LAUNCH_MULTIPLES` times the gait's lean amplitude, a launch from
  rest (as ``hand_launch`` starts it) walks up to :data:`LAUNCH_STEPS` steps; its score is
  ``min(1, -log10(d_min) / 4)``, d_min the closest the walk's post-strike states come to the fixed
  point (state_scale units; 1 when it recovers, as ``recovers`` counts it, within 1e-4), plus
  0.1 x the share of the step budget it walked before failing. ``launch`` is the mean over tips
  (0 .. 1.1);
- ``basin``: the median :func:`~toywalk.model.basin.basin_radius` over :data:`N_DIRECTIONS`
  random directions (seed 0, bracketed to 10 %), state_scale units;
- ``score = launch + 0.5 min(1, basin / 0.05)``, for designs that are *feasible*: a gait with max
  |eigenvalue| < 0.999, the swing foot clear by 1 mm over the whole swing, and ``can_stand`` False
  (checked last, 0.5 s); the parameters must make a rigid leg (``Params`` refuses an inertia whose
  principal moments break the triangle inequality, and a lateral foot radius above the fore-aft one).
- ``rest`` (stages 2-3, no gait needed): the steps a launch from rest walks before it fails, at
  tips of :data:`REST_TIPS` (up to :data:`REST_STEPS` steps each), as a share of the budget,
  weighted half by whether its last steps still advance (:func:`rest_tip_score`; a first version
  without that weight bred walkers that rock in place with shrinking steps), averaged over the
  tips (0 .. 1). A launch that walks the whole budget ends near an attracting
  gait if the walker has one: Newton from its last state finds it, and the design gets the full
  evaluation above.

The box (:data:`BOUNDS`): docs/make_clearance_design.py's eleven parameters and bounds (15 cm legs,
feet no larger than a spool, hips at most 16 cm apart, balance masses within 25 cm of the leg,
ramps up to 6 degrees). Leg mass is fixed at 50 g: with an essentially massless axle the dynamics
depend on the legs' inertia only through I / m, and the inertia is free, so 30-70 g legs are
covered by the same box.

Stages, every design evaluated written to the logs (``--log``, CSV, one row a design; the
launches from rest to ``<log>_rest.csv``):

1. ``scan``: Latin-hypercube designs over the whole box (``--scan`` of them), each solved by Newton
   from both seeds' fixed points (clearing-toy and stable-toy): how often a random design in the
   box has a gait within reach;
2. ``rest scan``: Latin-hypercube designs over the whole box (``--rest``) launched from rest
   (``rest`` score, no gait needed; a few ms a design);
3. ``rest evolve``: an evolutionary walk on the rest objective (``--rest-budget`` s): a parent drawn
   from the 30 best so far (rank-weighted), perturbed in every parameter by a normal step of
   0.3-10 % of its range; a design whose launch walks the whole budget gets its gait and full score;
4. ``spread``: the same walk on the full score among feasible designs (``--spread``, ``--budget``),
   from the seeds and whatever stage 3 found, each gait solved by Newton warm-started from the
   parent's fixed point (continuation from the parent, tried first, cost 4 s a design that has no
   gait and found none in a trial of 60 designs, so it is left out);
5. ``local``: Nelder-Mead (:func:`minimise_max_eigenvalue` with the score as objective and
   feasibility as constraint) from the best design (``--maxiter``);
6. the best few designs and the two seeds: ``hand_launch`` itself over tips 0.25-4 x lean and
   headings 0, +-2 degrees, 20 random-direction radii, the slope window in which their gait stays
   stable (followed in slope both ways), ``can_stand``; written to docs/robust_best.csv, the best
   to docs/robust_best.toml.

Cost (2 cores shared with other jobs, compiled kernels cached): a launch from rest that fails
takes about 1 ms, so a design of stages 2-3 a few ms; stages 1 and 4 about 0.05 s a design without
a stable gait, 1-2 s a feasible one (the basin radii and ``can_stand`` dominate). Run::

    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python docs/make_robust_design.py \
        --scan 400 --rest 20000 --rest-budget 900 --budget 480 --maxiter 150 --log L.csv
    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python docs/make_robust_design.py --scan 0 \
        --slice 21 --rest 20000 --rest-budget 300 --rest-min-margin 0 --spread 0 --maxiter 0 --finalists 0 \
        --seed 1 --log M.csv

(the second keeps stage 3 to walkers that cannot stand fore and aft on parallel legs, ``Search``,
after a grid through clearing-toy, :func:`rest_slice`).
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
from toywalk.model import Walker, can_stand, load_params, save_params, solve_fixed_point, static_margin
from toywalk.model.basin import basin_radius, hand_launch, launch_state, random_directions
from toywalk.model.gait import GaitNotFound, continue_gait, state_scale
from toywalk.model.optimize import minimise_max_eigenvalue
from toywalk.model.parameters import ParameterError
from toywalk.model.walker import StepFailure

sys.path.insert(0, str(Path(__file__).resolve().parent))
# The seeds' fixed points, the free parameters and their box: the clearance design's own.
from make_clearance_design import BOUNDS, FREE, Z_CLEARING, Z_STABLE  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
LO = np.array([BOUNDS[n][0] for n in FREE])
HI = np.array([BOUNDS[n][1] for n in FREE])
#: Tips (degrees) and step budget of the gait-free launches from rest of stages 2-3.
REST_TIPS = (0.5, 1.0, 2.0, 3.0, 4.0)
REST_STEPS = 80
#: The last steps whose advance is averaged, and the advance a step (m) that counts as walking on
#: (the toy's is 6.5 mm, Coleman & Ruina 1998).
REST_LAST = 10
REST_ADVANCE = 0.003
REST_COLUMNS = ["stage", "design", "parent", *FREE, "rest", *(f"steps_{t:g}" for t in REST_TIPS),
                *(f"reason_{t:g}" for t in REST_TIPS), *(f"advance_{t:g}" for t in REST_TIPS),
                "fore_aft_margin", "static_margin", "gait",
                "feasible", "why", "score", "seconds"]
MIN_CLEARANCE = 0.001  # m, issue 44's 1 mm
#: Tips of the scored launches, as multiples of the gait's lean amplitude (issue 44: 1.5 and 2.5).
LAUNCH_MULTIPLES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
#: Step budget of a scored launch: a converging one reaches 1e-4 in about 45 steps at |lambda| 0.85.
LAUNCH_STEPS = 150
LAUNCH_TOL = 1e-4  # state_scale units, basin.TOL
N_DIRECTIONS = 3
BASIN_FULL = 0.05  # state_scale units: a basin this wide scores its full 0.5
COLUMNS = ["stage", "design", "parent", *FREE, "feasible", "why", "score", "launch", "basin",
           "max_abs_eigenvalue", "clearance", "static_margin", "step_time", "stride_length",
           "lean_amplitude", "swing_period", "rock_time", "launch_steps_1.5", "launch_reason_1.5",
           "launch_dmin_1.5", "launch_steps_2.5", "launch_reason_2.5", "launch_dmin_2.5",
           "first_ahead_1.5", "first_time_1.5", "seconds", *(f"z{i}" for i in range(8))]


def in_box(x: np.ndarray) -> np.ndarray:
    """``x`` clipped to the box, with the feet's lateral radius at most their fore-aft one (the
    model's torus foot, :class:`Params`)."""
    x = np.clip(np.asarray(x, dtype=float), LO, HI)
    x[2] = min(x[2], x[1])
    return x


def swing_period(params) -> float:
    """Small-swing period of one leg about the axle (s): 2 pi sqrt(I_pitch / (m g |d_z|)), I_pitch
    = I_yy + m (d_x^2 + d_z^2)."""
    m, (dx, _, dz) = params.leg_mass, params.com_offset
    pitch = params.inertia[1] + m * (dx**2 + dz**2)
    return 2 * math.pi * math.sqrt(pitch / (m * params.gravity * max(-dz, 1e-9)))


def rock_time(params) -> float:
    """Time scale of the sideways fall about the stance foot (s), sqrt(I_roll / (M g h)): I_roll the
    walker's roll inertia about the foot's lateral centre of curvature (legs upright, no lean), h
    the static margin; the time in which a tip grows e-fold when rocking about that centre."""
    m, (_, dy, dz) = params.leg_mass, params.com_offset
    w, l, rho = params.hip_width, params.leg_length, params.foot_lateral_radius
    roll = 0.0
    for y in (w / 2 + dy, -w / 2 - dy):
        roll += params.inertia[0] + m * ((y - w / 2) ** 2 + (l + dz - rho) ** 2)
    margin = static_margin(params)
    return math.sqrt(roll / (params.total_mass * params.gravity * margin)) if margin > 0 else math.nan


def fore_aft_margin(params) -> float:
    """Centre-of-mass height above the feet's fore-aft centre of curvature, legs upright (m): the
    fore-aft counterpart of :func:`static_margin`. Positive: rolling on the foot does not hold the
    walker up fore and aft, and from rest it falls forward (on a ramp, over its slope); the
    smaller, the slower."""
    return static_margin(params) + params.foot_lateral_radius - params.foot_radius


def rest_walk(walker: Walker, tip: float, steps: int = REST_STEPS) -> tuple[int, str, np.ndarray, float]:
    """A hand launch (:func:`launch_state`, heading 0) walked without a gait to compare with:
    (steps walked, why it stopped (``"walking"`` after ``steps``), last post-strike state, mean
    advance of the last :data:`REST_LAST` steps (m, down the ramp)). A first landing that scuffs
    fails, as in :func:`hand_launch`."""
    z, side, advance = launch_state(tip), 1, []
    for k in range(steps):
        try:
            step = walker.step(z, side=side)
        except StepFailure as err:
            return k, err.status, z, _mean_tail(advance)
        if step.scuffs and k == 0:
            return k + 1, "scuffed", z, 0.0
        advance.append(float(step.contact[0]))
        z, side = step.z_plus, -side
    return steps, "walking", z, _mean_tail(advance)


def _mean_tail(advance: list) -> float:
    return float(np.mean(advance[-REST_LAST:])) if advance else 0.0


def rest_tip_score(walk: tuple) -> float:
    """A launch from rest's share of the step budget walked, weighted half by itself and half by
    whether its last steps still advance (their mean advance over :data:`REST_ADVANCE`, at most 1):
    a walker that rocks in place with shrinking steps for the whole budget scores 0.5, one that
    walks on 1."""
    walked = min(walk[0], REST_STEPS) / REST_STEPS
    return walked * (0.5 + 0.5 * min(1.0, max(0.0, walk[3]) / REST_ADVANCE))


def launch_walk(walker: Walker, gait, tip: float, steps: int = LAUNCH_STEPS) -> dict:
    """A hand launch as :func:`hand_launch` starts it (heading 0), walked up to ``steps`` steps,
    recording how close it comes to the gait: ``recovered``, ``steps`` walked, ``reason``,
    ``dmin`` (state_scale units; inf when no step completes), the first landing's distance
    ahead of the stance foot (m) and its time (s)."""
    scale = state_scale(walker.params)
    fail_on_scuff = sum(s.scuffs for s in gait.steps) == 0
    z, side, dmin = launch_state(tip), 1, math.inf
    out = {"recovered": False, "steps": 0, "reason": "", "dmin": math.inf, "ahead": math.nan,
           "time": math.nan}
    for k in range(steps):
        try:
            step = walker.step(z, side=side)
        except StepFailure as err:
            out.update(reason=err.status, steps=k, dmin=dmin)
            return out
        if k == 0:
            out.update(ahead=float(step.contact[0]), time=float(step.step_time))
        if step.scuffs and (k == 0 or fail_on_scuff):
            out.update(reason="scuffed", steps=k + 1, dmin=dmin)
            return out
        z, side = step.z_plus, -side
        d = float(np.linalg.norm((z - gait.fixed_point) / scale))
        dmin = min(dmin, d)
        if d <= LAUNCH_TOL and (gait.period == 1 or side == 1):
            out.update(recovered=True, reason="recovered", steps=k + 1, dmin=d)
            return out
    out.update(reason="not_converged", steps=steps, dmin=dmin)
    return out


def launch_score(walk: dict) -> float:
    if walk["recovered"]:
        return 1.0 + 0.1
    closeness = min(1.0, max(0.0, -math.log10(walk["dmin"]) / 4)) if math.isfinite(walk["dmin"]) else 0.0
    return closeness + 0.1 * walk["steps"] / LAUNCH_STEPS


def infeasibility(params, gait, stand: bool = True) -> tuple[float, str]:
    """How far a design is from feasible (0 when feasible; m of leg), and why: a stable gait, 1 mm
    of clearance and, when ``stand`` and those hold, ``can_stand`` False (then a violation of 1e-4 m,
    a step the constraint's penalty can see)."""
    violations = {
        "unstable": (gait.max_abs_eigenvalue - 0.999) * params.leg_length,
        "clearance": MIN_CLEARANCE - gait.clearance,
    }
    worst = max(violations, key=violations.get)
    if violations[worst] > 0:
        return violations[worst], worst
    if stand and can_stand(params).can_stand:
        return 1e-4, "can stand"
    return 0.0, ""


class Search:
    """Evaluates designs, keeps the feasible ones and writes every row to the log."""

    def __init__(self, log: Path, rest_min_margin: float = -math.inf):
        self.rest_min_margin = rest_min_margin
        self.log = open(log, "w", newline="")  # noqa: SIM115 (closed in close())
        self.writer = csv.writer(self.log)
        self.writer.writerow(COLUMNS)
        rest = log.with_name(log.stem + "_rest" + log.suffix)
        self.rest_log = open(rest, "w", newline="")  # noqa: SIM115 (closed in close())
        self.rest_writer = csv.writer(self.rest_log)
        self.rest_writer.writerow(REST_COLUMNS)
        self.rest_archive: list[dict] = []  # every rest-walk design: {"x", "rest", "objective", "design"}
        self.count = 0
        self.archive: list[dict] = []  # feasible designs: {"x", "gait", "score", "design"}
        self.base = load_params(ROOT / "data" / "params" / "clearing-toy.toml")

    def close(self) -> None:
        self.log.close()
        self.rest_log.close()

    def rest_evaluate(self, stage: str, x: np.ndarray, parent: int = -1) -> dict:
        """Launches from rest at :data:`REST_TIPS` (no gait needed); a design whose launch walks
        the whole budget goes on to :meth:`evaluate` from that walk's last state. Objective: the
        rest score, plus 1 + the full score for a feasible design (so any beats every other)."""
        t0 = time.perf_counter()
        x = in_box(x)
        self.count += 1
        row = {"stage": stage, "design": self.count, "parent": parent, **dict(zip(FREE, x, strict=True))}
        out = {"x": x, "rest": 0.0, "objective": -1.0, "design": self.count, "full": None}
        try:
            params = self.params_at(x)
        except ParameterError as err:
            row.update(why="inertia" if "inertia" in str(err) else "parameters", rest=-1)
            self.rest_writer.writerow([_fmt(row.get(c, "")) for c in REST_COLUMNS])
            return out
        walker = Walker(params)
        walks = [rest_walk(walker, math.radians(t)) for t in REST_TIPS]
        rest = float(np.mean([rest_tip_score(w) for w in walks]))
        row.update(rest=rest, fore_aft_margin=fore_aft_margin(params), static_margin=static_margin(params),
                   **{f"steps_{t:g}": w[0] for t, w in zip(REST_TIPS, walks, strict=True)},
                   **{f"reason_{t:g}": w[1] for t, w in zip(REST_TIPS, walks, strict=True)},
                   **{f"advance_{t:g}": w[3] for t, w in zip(REST_TIPS, walks, strict=True)})
        out.update(rest=rest, objective=rest)
        shortfall = self.rest_min_margin - fore_aft_margin(params)
        if shortfall > 0:  # below the fore-aft margin asked for: pushed back, continuously
            out["objective"] = rest - 1.0 - shortfall / 0.01
            row["why"] = "fore-aft margin"
        walking = [w[2] for w in walks if w[0] >= REST_STEPS and shortfall <= 0]
        if walking:
            full = self.evaluate(f"{stage} gait", x, walking[:2], parent=self.count)
            out["full"] = full
            row.update(gait=int(full["gait"] is not None), feasible=int(full["feasible"]),
                       why=full.get("why", ""), score=full["score"] if full["feasible"] else "")
            if full["feasible"]:
                out["objective"] = rest + 1.0 + full["score"]
        row["seconds"] = time.perf_counter() - t0
        self.rest_writer.writerow([_fmt(row.get(c, "")) for c in REST_COLUMNS])
        self.rest_log.flush()
        self.rest_archive.append(out)
        return out

    def params_at(self, x: np.ndarray):
        return self.base.replace(**dict(zip(FREE, map(float, x), strict=True)))

    def gait_at(self, params, starts: list) -> object | None:
        """Newton from each start (a fixed point), then continuation from the first start's walker
        when one is given as (params, z)."""
        walker = Walker(params)
        for z in starts:
            if isinstance(z, tuple):
                try:
                    return continue_gait(z[0], params, z[1], min_ds=0.1)
                except GaitNotFound:
                    continue
            try:
                return solve_fixed_point(walker, np.asarray(z))
            except GaitNotFound:
                continue
        return None

    def evaluate(self, stage: str, x: np.ndarray, starts: list, parent: int = -1) -> dict:
        t0 = time.perf_counter()
        x = in_box(x)
        self.count += 1
        row = {"stage": stage, "design": self.count, "parent": parent, **dict(zip(FREE, x, strict=True))}
        why = ""
        try:
            params = self.params_at(x)
        except ParameterError as err:
            params, why = None, "inertia" if "inertia" in str(err) else "parameters"
        gait = None if params is None else self.gait_at(params, starts)
        result = {"x": x, "gait": gait, "score": -math.inf, "design": self.count, "feasible": False,
                  "violation": math.inf}
        if params is None:
            row.update(feasible=0, why=why)
        elif gait is None or not np.all(np.isfinite(gait.eigenvalues)):
            row.update(feasible=0, why="no gait", static_margin=static_margin(params))
            gait = result["gait"] = None
            result["why"] = "no gait"
        else:
            violation, why = infeasibility(params, gait)
            row.update(feasible=int(violation == 0), why=why, max_abs_eigenvalue=gait.max_abs_eigenvalue,
                       clearance=gait.clearance, static_margin=static_margin(params),
                       step_time=gait.step_time, stride_length=gait.stride_length,
                       lean_amplitude=gait.lean_amplitude, swing_period=swing_period(params),
                       rock_time=rock_time(params), **{f"z{i}": v for i, v in enumerate(gait.fixed_point)})
            result["violation"] = violation
            result["why"] = why
            if violation == 0:
                score = self.score(params, gait, row)
                result.update(score=score, feasible=True)
                self.archive.append(result)
        row["seconds"] = time.perf_counter() - t0
        self.writer.writerow([_fmt(row.get(c, "")) for c in COLUMNS])
        self.log.flush()
        return result

    def score(self, params, gait, row: dict) -> float:
        walker = Walker(params)
        lean = gait.lean_amplitude
        walks = {m: launch_walk(walker, gait, m * lean) for m in LAUNCH_MULTIPLES}
        launch = float(np.mean([launch_score(w) for w in walks.values()]))
        radii = [basin_radius(params, u, gait, walker=walker, rtol=0.1).radius
                 for u in random_directions(params, gait, N_DIRECTIONS, 0)]
        basin = float(np.median(radii))
        score = launch + 0.5 * min(1.0, basin / BASIN_FULL)
        row.update(score=score, launch=launch, basin=basin)
        for m in (1.5, 2.5):
            row.update({f"launch_steps_{m}": walks[m]["steps"], f"launch_reason_{m}": walks[m]["reason"],
                        f"launch_dmin_{m}": walks[m]["dmin"]})
        row.update({"first_ahead_1.5": walks[1.5]["ahead"], "first_time_1.5": walks[1.5]["time"]})
        return score

    def best(self) -> dict:
        return max(self.archive, key=lambda r: r["score"])


def _fmt(v):
    return f"{v:.6g}" if isinstance(v, float) else v


def _latin_designs(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` Latin-hypercube designs over the box (rows in :data:`FREE`'s order), each with its
    lateral foot radius no larger than its fore-aft one (the two swapped where drawn the other
    way round)."""
    u = (rng.permuted(np.tile(np.arange(n), (len(FREE), 1)), axis=1).T + rng.random((n, len(FREE)))) / n
    x = LO + u * (HI - LO)
    x[:, 1], x[:, 2] = np.maximum(x[:, 1], x[:, 2]), np.minimum(x[:, 1], x[:, 2])
    return x


def scan(search: Search, n: int, rng: np.random.Generator) -> None:
    """Latin-hypercube designs over the whole box, Newton from both seeds."""
    t0 = time.perf_counter()
    for k, x in enumerate(_latin_designs(n, rng)):
        search.evaluate("scan", x, [Z_CLEARING, Z_STABLE])
        if (k + 1) % 50 == 0:
            print(f"scan {k + 1}/{n}: {len(search.archive)} feasible, {time.perf_counter() - t0:.0f} s",
                  flush=True)


def rest_scan(search: Search, n: int, rng: np.random.Generator) -> None:
    """Latin-hypercube designs over the whole box, launched from rest (no gait needed)."""
    t0 = time.perf_counter()
    for k, x in enumerate(_latin_designs(n, rng)):
        search.rest_evaluate("rest scan", x)
        if (k + 1) % 1000 == 0:
            b = max(search.rest_archive, key=lambda r: r["objective"])
            print(f"rest scan {k + 1}/{n}: best rest {b['rest']:.3f} objective {b['objective']:.3f} "
                  f"(design {b['design']}), {len(search.archive)} feasible, {time.perf_counter() - t0:.0f} s",
                  flush=True)


def rest_slice(search: Search, n: int) -> None:
    """clearing-toy with its fore-aft foot radius (10.7-30 mm) and its legs' centre-of-mass height
    (d_z -114 to -145 mm) varied on an n x n grid, everything else kept, launched from rest: how
    the launch depends on the fore-aft margin alone."""
    base = np.array([search.base.get(n_) for n_ in FREE])
    for r in np.linspace(base[1], 0.03, n):
        for dz in np.linspace(base[5], -0.145, n):
            x = base.copy()
            x[1], x[5] = r, dz
            search.rest_evaluate("rest slice", x)


def rest_evolve(search: Search, n: int, rng: np.random.Generator, budget: float = math.inf) -> None:
    """Evolutionary walk on the rest objective from the best rest designs (as :func:`spread`)."""
    t0 = time.perf_counter()
    for k in range(n):
        if time.perf_counter() - t0 > budget:
            break
        pool = sorted(search.rest_archive, key=lambda r: -r["objective"])[:30]
        weights = 1.0 / (1.0 + np.arange(len(pool)))
        parent = pool[rng.choice(len(pool), p=weights / weights.sum())]
        sigma = rng.choice([0.003, 0.01, 0.03, 0.1])
        x = parent["x"] + sigma * (HI - LO) * rng.standard_normal(len(FREE))
        search.rest_evaluate(f"rest evolve {sigma:g}", x, parent["design"])
        if (k + 1) % 500 == 0:
            b = max(search.rest_archive, key=lambda r: r["objective"])
            print(f"rest evolve {k + 1}: best rest {b['rest']:.3f} objective {b['objective']:.3f} "
                  f"(design {b['design']}), {len(search.archive)} feasible, {time.perf_counter() - t0:.0f} s",
                  flush=True)


def spread(search: Search, n: int, rng: np.random.Generator, seeds: list, budget: float = math.inf) -> None:
    """Evolutionary walk from the seeds: rank-weighted parents, normal steps of 0.3-10 % of the
    box's range in every parameter; stops after ``n`` designs or ``budget`` s."""
    t0 = time.perf_counter()
    for k in range(n):
        if time.perf_counter() - t0 > budget:
            break
        pool = sorted(search.archive, key=lambda r: -r["score"])[:30]
        pool = pool + [s for s in seeds if all(s is not q for q in pool)]
        weights = 1.0 / (1.0 + np.arange(len(pool)))
        parent = pool[rng.choice(len(pool), p=weights / weights.sum())]
        sigma = rng.choice([0.003, 0.01, 0.03, 0.1])
        x = parent["x"] + sigma * (HI - LO) * rng.standard_normal(len(FREE))
        gait = parent["gait"]
        search.evaluate(f"spread {sigma:g}", x, [gait.fixed_point], parent["design"])
        if (k + 1) % 50 == 0:
            b = search.best()
            print(f"spread {k + 1}/{n}: {len(search.archive)} feasible, best score {b['score']:.4f} "
                  f"(design {b['design']}), {time.perf_counter() - t0:.0f} s", flush=True)


def local(search: Search, start: dict, maxiter: int) -> None:
    """Nelder-Mead from ``start`` on the score, feasibility as the constraint."""

    def objective(gait):
        res = search.evaluate("local", np.array([gait.params.get(n) for n in FREE]), [gait.fixed_point])
        return -res["score"] if res["feasible"] else 0.0

    def constraint(params, gait):  # can_stand is in the objective's evaluation already
        return -infeasibility(params, gait, stand=False)[0]

    result = minimise_max_eigenvalue(start["gait"], FREE, BOUNDS, constraint=constraint,
                                     objective=objective, maxiter=maxiter, initial_step=0.05)
    print(f"local: score {-result.start_value:.4f} -> {-result.value:.4f}, {result.evaluations} "
          f"evaluations, {result.failures} without a gait", flush=True)


def slope_window(gait, step: float = 0.0005, reach: float = 0.05) -> tuple[float, float]:
    """The slopes (rad) between which the gait, followed in slope both ways by Newton from the last
    fixed point, stays stable: the last stable slope on either side."""
    ends = []
    for sign in (-1, 1):
        g, last = gait, gait.params.slope
        s = gait.params.slope
        while abs(s - gait.params.slope) < reach:
            s += sign * step
            if s <= 0:
                break
            try:
                g = solve_fixed_point(Walker(g.params.replace(slope=s)), g.fixed_point)
            except (GaitNotFound, ParameterError):
                break
            if g.max_abs_eigenvalue >= 1:
                break
            last = s
        ends.append(last)
    return ends[0], ends[1]


def finalists(search: Search, n: int) -> None:
    """The best ``n`` designs: hand_launch over tips and headings, 20 random radii, slope window,
    can_stand; docs/robust_best.csv and the best to docs/robust_best.toml."""
    top = []
    for r in sorted(search.archive, key=lambda r: -r["score"]):
        # distinct designs: more than 1 % of the box apart from every one kept
        if all(np.max(np.abs(r["x"] - q["x"]) / (HI - LO)) > 0.01 for q in top):
            top.append(r)
        if len(top) == n:
            break
    seeds = {"clearing-toy": Z_CLEARING, "stable-toy": Z_STABLE}
    rows = []
    for name, z in seeds.items():
        p = load_params(ROOT / "data" / "params" / f"{name}.toml")
        top.append({"gait": solve_fixed_point(Walker(p), np.array(z)), "design": name, "score": math.nan})
    multiples = (0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0)
    for r in top:
        g = r["gait"]
        p = g.params
        t0 = time.perf_counter()
        launch = hand_launch(p, [m * g.lean_amplitude for m in multiples],
                             headings=[0.0, math.radians(2), -math.radians(2)], gait=g)
        ok = launch.recovered()
        walker = Walker(p)
        radii = [basin_radius(p, u, g, walker=walker).radius for u in random_directions(p, g, 20, 0)]
        lo, hi = slope_window(g)
        row = {"design": r["design"], "score": r["score"], "max_abs_eigenvalue": g.max_abs_eigenvalue,
               "clearance_mm": 1e3 * g.clearance, "can_stand": can_stand(p).can_stand,
               "static_margin_mm": 1e3 * static_margin(p), "step_time": g.step_time,
               "stride_mm": 1e3 * g.stride_length, "lean_deg": math.degrees(g.lean_amplitude),
               "launch_ok_heading0": " ".join(f"{m:g}" for m, k in zip(multiples, ok[0], strict=True) if k),
               "launch_ok_any": int(ok.sum()), "launch_reasons": " ".join(
                   res.reason[:4] + str(res.steps) for res in launch.results[0]),
               "radius_min": min(radii), "radius_median": float(np.median(radii)), "radius_max": max(radii),
               "slope": p.slope, "slope_low": lo, "slope_high": hi,
               "seconds": time.perf_counter() - t0, **{n: p.get(n) for n in FREE}}
        rows.append(row)
        print({k: _fmt(v) for k, v in row.items()}, flush=True)
    with open(HERE / "robust_best.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows({k: _fmt(v) for k, v in row.items()} for row in rows)
    best = top[0]["gait"]
    row = rows[0]
    save_params(dataclasses.replace(best.params, gait_start=tuple(float(v) for v in best.fixed_point)),
                HERE / "robust_best.toml",
                header=f"The best design of docs/make_robust_design.py (docs/gaits.md section 7), score "
                       f"{top[0]['score']:.4f}: max |eigenvalue| {row['max_abs_eigenvalue']:.3f}, clearance "
                       f"{row['clearance_mm']:.2f} mm, can_stand {row['can_stand']},\nrandom-direction basin "
                       f"radius {row['radius_min']:.4f} .. {row['radius_max']:.4f} (median "
                       f"{row['radius_median']:.4f}, 20 directions, seed 0), stable on slopes "
                       f"{row['slope_low']:.4f} .. {row['slope_high']:.4f} rad.\nNo hand launch converges "
                       f"(tips 0.25-4 x its lean amplitude, headings 0 and +-2 degrees). [gait] start is its "
                       f"fixed point.")


def summarise(log: Path) -> None:
    """From the logs: per stage the designs evaluated, with valid parameters, with a gait, stable,
    clearing by 1 mm and feasible, and the best scores (printed); the rest walks binned by the
    fore-aft margin (printed); the figure docs/<log's name>.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(log) as f:
        rows = list(csv.DictReader(f))
    with open(log.with_name(log.stem + "_rest" + log.suffix)) as f:
        rest = list(csv.DictReader(f))

    def num(r, c):
        return float(r[c]) if r.get(c, "") not in ("", None) else math.nan

    stages = {r["stage"].split(" ")[0] if not r["stage"].startswith("rest") else r["stage"].rsplit(" ", 1)[0]
              for r in rows}
    for name in sorted(stages):
        sel = [r for r in rows if r["stage"] == name or r["stage"].startswith(name + " ")]
        lam = np.array([num(r, "max_abs_eigenvalue") for r in sel])
        clr = np.array([num(r, "clearance") for r in sel])
        feas = [r for r in sel if r["feasible"] == "1"]
        best = max(feas, key=lambda r: float(r["score"])) if feas else None
        print(f"{name}: {len(sel)} designs, {sum(r['why'] not in ('inertia', 'parameters') for r in sel)} "
              f"valid, {int(np.isfinite(lam).sum())} with a gait, {int((lam < 1).sum())} stable, "
              f"{int(((lam < 1) & (clr >= MIN_CLEARANCE)).sum())} stable and clear by 1 mm, {len(feas)} "
              f"feasible; best score {best['score'] if best else '-'} (launch "
              f"{best['launch'] if best else '-'}, basin {best['basin'] if best else '-'})")
    valid = [r for r in rest if r["rest"] not in ("", "-1")]
    score = np.array([float(r["rest"]) for r in valid])
    margin = 1e3 * np.array([float(r["fore_aft_margin"]) for r in valid])
    full = np.array([any(r[f"reason_{t:g}"] == "walking" for t in REST_TIPS) for r in valid])
    print(f"rest walks: {len(rest)} designs, {len(valid)} valid, {int(full.sum())} walked "
          f"{REST_STEPS} steps from at least one tip, {sum(r['gait'] == '1' for r in valid)} of those with "
          f"a gait found from the walk, {sum(r['feasible'] == '1' for r in valid)} feasible")
    for lo, hi in ((-np.inf, -10), (-10, -5), (-5, 0), (0, 5), (5, 10), (10, 20), (20, np.inf)):
        sel = (margin >= lo) & (margin < hi)
        if sel.any():
            print(f"  fore-aft margin {lo:g}..{hi:g} mm: {int(sel.sum())} designs, rest score mean "
                  f"{score[sel].mean():.3f}, max {score[sel].max():.3f}, {int(full[sel].sum())} walked "
                  "the budget")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.3))
    ax = axes[0]
    scan_sel = np.array([r["stage"] == "rest scan" for r in valid])
    ax.plot(margin[~scan_sel], score[~scan_sel], ".", ms=2, color="tab:orange", alpha=0.4,
            label="evolved (stage 3)")
    ax.plot(margin[scan_sel], score[scan_sel], ".", ms=2, color="k", alpha=0.4,
            label="Latin hypercube (stage 2)")
    ax.axvline(0, color="0.5", lw=0.8)
    ax.set_xlim(-30, 100)
    ax.set_xlabel("fore-aft margin: COM height above the foot's fore-aft centre of curvature (mm)")
    ax.set_ylabel("launch-from-rest score (stages 2-3)")
    ax.legend(fontsize=7, markerscale=4)
    ax = axes[1]
    feas = [r for r in rows if r["feasible"] == "1"]
    colours = (("seed", "k"), ("spread", "tab:blue"), ("local", "tab:green"), ("rest", "tab:red"))
    for prefix, colour in colours:
        sel = [r for r in feas if r["stage"].startswith(prefix)]
        if sel:
            ax.plot([float(r["max_abs_eigenvalue"]) for r in sel], [float(r["basin"]) for r in sel], ".",
                    ms=4 if prefix != "seed" else 10, color=colour, alpha=0.6, label=f"{prefix} ({len(sel)})")
    ax.set_xlabel("step-map max |eigenvalue|")
    ax.set_ylabel("median random-direction basin radius (3 directions)")
    ax.set_title("feasible designs: stable, clear by 1 mm, cannot stand", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(HERE / f"{log.stem}.png", dpi=110)


def archive_from_log(log: Path, base) -> list[dict]:
    """The feasible designs of a log, their gaits solved again from the logged fixed points."""
    out = []
    with open(log) as f:
        for r in csv.DictReader(f):
            if r["feasible"] != "1":
                continue
            x = np.array([float(r[n]) for n in FREE])
            params = base.replace(**dict(zip(FREE, map(float, x), strict=True)))
            gait = solve_fixed_point(Walker(params), np.array([float(r[f"z{i}"]) for i in range(8)]))
            out.append({"x": x, "gait": gait, "score": float(r["score"]), "design": int(r["design"])})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scan", type=int, default=300, help="Latin-hypercube designs")
    parser.add_argument("--rest", type=int, default=5000, help="Latin-hypercube designs launched from rest")
    parser.add_argument("--slice", type=int, default=0,
                        help="n: an n x n grid of clearing-toy's foot radius and COM height, from rest")
    parser.add_argument("--rest-budget", type=float, default=900.0, help="s for the rest evolution")
    parser.add_argument("--spread", type=int, default=1500, help="evolutionary designs")
    parser.add_argument("--budget", type=float, default=math.inf, help="s for the spread stage at most")
    parser.add_argument("--maxiter", type=int, default=300, help="Nelder-Mead iterations")
    parser.add_argument("--finalists", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--log", type=Path, default=HERE / "robust_search.csv")
    parser.add_argument("--rest-min-margin", type=float, default=-math.inf,
                        help="m: stage 3 keeps to designs whose fore-aft margin is at least this")
    parser.add_argument("--finalists-only", action="store_true",
                        help="only stage 6, from the feasible designs of the log")
    parser.add_argument("--summary-only", action="store_true", help="only summarise the logs")
    args = parser.parse_args()
    if args.summary_only:
        summarise(args.log)
        return
    if args.finalists_only:
        search = Search.__new__(Search)
        search.base = load_params(ROOT / "data" / "params" / "clearing-toy.toml")
        search.archive = archive_from_log(args.log, search.base)
        finalists(search, args.finalists)
        return
    rng = np.random.default_rng(args.seed)
    search = Search(args.log, args.rest_min_margin)
    t0 = time.perf_counter()
    seeds = [search.evaluate("seed", np.array([load_params(ROOT / "data" / "params" / f"{name}.toml").get(n)
                                               for n in FREE]), [z])
             for name, z in (("clearing-toy", Z_CLEARING), ("stable-toy", Z_STABLE))]
    # stable-toy scuffs (clearance -0.017 mm): it seeds the walk but is not feasible itself.
    for s in seeds:
        if s["gait"] is not None and not s["feasible"]:
            s["score"] = -1.0
    seeds = [s for s in seeds if s["gait"] is not None]
    scan(search, args.scan, rng)
    rest_slice(search, args.slice)
    rest_scan(search, args.rest, rng)
    rest_evolve(search, 10**9, rng, args.rest_budget)
    spread(search, args.spread, rng, seeds, args.budget)
    if args.maxiter:
        local(search, search.best(), args.maxiter)
    print(f"{search.count} designs, {len(search.archive)} feasible, {time.perf_counter() - t0:.0f} s",
          flush=True)
    search.close()
    if args.finalists:
        finalists(search, args.finalists)
    summarise(args.log)


if __name__ == "__main__":
    main()
