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

Options for a margin homotopy (off by default; then the walk and its outputs are as above):

- ``--start-from-log CSV``: instead of docs/launch_converging.toml, seed the archive with the
  :data:`SEEDS` best feasible designs of an earlier log whose launches walk :data:`SEED_STEPS`+ steps
  from both tips (in docs/launch_search.csv all of them can stand), each re-solved by Newton from its
  logged fixed point;
- ``--free-more``: free :data:`MORE` (leg_mass, leg_length, axle_mass) too, in :data:`BOUNDS_MORE`;
- ``--margin-floor=START:END`` (mm): a design whose fore-aft margin (docs/make_robust_design.py's
  :func:`fore_aft_margin`, logged as ``margin_mm``) is below the floor is infeasible (``why``
  ``margin``, no gait solved); the floor rises linearly from START to END over ``--minutes``, and
  the parents are the best designs above the floor (those closest below it while none is above);
  the seeds are evaluated before the floor applies;
- ``--finalists-csv``, ``--best-toml``: where the finalists stage writes;
- ``--start P.toml``: the walk starts from this walker instead (its ``[gait] start`` its fixed
  point), and the finalists are built on it;
- ``--clearance-to MM``: the clearance floor rises from ``--min-clearance`` to MM over the run,
  parents ranked as under the margin floor;
- ``--soft-ceiling=START:END``: a design is feasible only if its gait, followed from the rigid one
  through soft feet of 1, 2 and 4 ms (``soft_gaits`` of docs/make_soft_robust_design.py,
  :data:`SOFT_STEPS` RK4 steps per tau), keeps its max |eigenvalue| at every tau at most the ceiling
  (``why`` ``soft``; a soft gait Newton loses counts as make_soft_robust_design's ``LOST``, 3);
  the ceiling falls linearly from START to END over ``--minutes``, parents ranked as under the
  margin floor; the worst is logged as ``soft_max``, each tau as ``soft_1ms`` ...;
- ``--feasible-only``: the log holds the feasible designs alone (the others are counted in the
  run's last line): docs/launch_push.csv is the run below so logged, 3449 of its 19065 logged
  designs.

Run (one core of a shared 2-core machine, compiled kernels cached; 0.2-2 s a design)::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python docs/make_launch_search.py --minutes 30
    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python docs/make_launch_search.py --minutes 0 --finalists 3
    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python docs/make_launch_search.py --minutes 45 --finalists 0 \
        --start-from-log docs/launch_search.csv --free-more --margin-floor=-7:1 --log docs/launch_push.csv \
        --feasible-only
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
from make_launch_margin import fmt_row, parse_pair, read_rows, write_rows  # noqa: E402
from make_robust_design import LAUNCH_STEPS, fore_aft_margin, launch_walk  # noqa: E402
from make_soft_robust_design import STEPS_PER_TAU, TAUS, soft_gaits, worst  # noqa: E402

HERE = Path(__file__).resolve().parent
START = HERE / "launch_converging.toml"
#: docs/make_clearance_design.py's box, foot_radius widened from 30 to 60 mm (the start has 39 mm).
BOUNDS = {**CLEARANCE_BOUNDS, "foot_radius": (0.002, 0.06)}
#: ``--free-more``: the parameters the walk otherwise holds at the start's values, and their box
#: (buildable: 20-200 g legs, 8-30 cm long, an axle of up to 100 g; foot_radius stays below
#: leg_length, or Params refuses the design).
MORE = ["leg_mass", "leg_length", "axle_mass"]
BOUNDS_MORE = {"leg_mass": (0.02, 0.2), "leg_length": (0.08, 0.3), "axle_mass": (0.0, 0.1)}
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
#: ``--start-from-log``: seeds are the feasible rows of the old log whose launch walks at least
#: this many steps from both tips (the best :data:`SEEDS` by score).
SEED_STEPS = 30
SEEDS = 30
#: ``--soft-ceiling``: RK4 steps per tau of the soft strike (docs/make_soft_robust_design.py's
#: STEPS_PER_TAU: 20 is not converged on these walkers, 80 is within 0.004 of 320).
SOFT_STEPS = STEPS_PER_TAU
SOFT_COLUMNS = [f"soft_{1e3 * tau:g}ms" for tau in TAUS[1:]]


def columns(free: list[str], margin: bool = False, soft: bool = False) -> list[str]:
    """The log's columns: ``margin_mm`` (the fore-aft margin) only with ``--margin-floor``, the soft
    gaits' eigenvalues only with ``--soft-ceiling``."""
    return ["design", "parent", "sigma", *free, "feasible", "why", *(["margin_mm"] if margin else []),
            "max_abs_eigenvalue", "clearance_mm", "lean_deg", "step_time",
            *([*SOFT_COLUMNS, "soft_max"] if soft else []),
            *(f"{k}_{m:g}" for m in TIPS for k in ("steps", "reason", "dmin")), "score", "can_stand",
            *(f"z{i}" for i in range(8))]


COLUMNS = columns(FREE)


def walks_both(row: dict, steps: int = SEED_STEPS) -> bool:
    """Whether a logged (or just evaluated) feasible design walks ``steps`` steps from both tips."""
    return all(row.get(f"steps_{m:g}") not in (None, "") and int(row[f"steps_{m:g}"]) >= steps for m in TIPS)


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
                 min_clearance: float = 0.2e-3, free_more: bool = False,
                 margin_floor: tuple[float, float] | None = None, feasible_only: bool = False,
                 start: Path = START, clearance_to: float | None = None,
                 soft_ceiling: tuple[float, float] | None = None):
        self.max_eigenvalue = max_eigenvalue
        self.min_clearance = min_clearance  # m
        self.free = FREE + MORE if free_more else list(FREE)
        bounds = {**BOUNDS, **BOUNDS_MORE}
        self.lo = np.array([bounds[n][0] for n in self.free])
        self.hi = np.array([bounds[n][1] for n in self.free])
        # ``--margin-floor`` (m): designs whose fore-aft margin is below ``floor`` are infeasible;
        # walk() raises it from margin_floor[0] to margin_floor[1]. None: no floor (the default).
        self.margin_floor = margin_floor
        self.floor: float | None = None
        # ``--soft-ceiling``: walk() lowers ``ceiling`` from soft_ceiling[0] to soft_ceiling[1].
        self.soft_ceiling = soft_ceiling
        self.ceiling: float | None = None
        self.frontier: dict | None = None  # the feasible design of largest margin that walks both tips
        self.base = load_params(start)
        # ``--clearance-to`` (m): walk() raises min_clearance from its start to this. None: fixed.
        self.clearance_range = None if clearance_to is None else (min_clearance, clearance_to)
        self.rng = rng
        self.archive: list[dict] = []
        self.best: dict | None = None
        self.n = 0
        self.rejected = 0  # designs that Params refuses (not logged, to keep the log small)
        self.feasible_only = feasible_only  # --feasible-only: log the feasible designs alone
        self.counts: dict[str, int] = {}  # designs by why (stable: feasible), logged or not
        self.file = open(log, "w", newline="")  # noqa: SIM115 -- closed by close()
        self.writer = csv.DictWriter(self.file, fieldnames=columns(self.free, margin_floor is not None,
                                                                          soft_ceiling is not None))
        self.writer.writeheader()

    def close(self) -> None:
        self.file.close()

    def params_at(self, x: np.ndarray):
        return self.base.replace(**{n: float(v) for n, v in zip(self.free, x, strict=True)})

    def evaluate(self, x: np.ndarray, z: np.ndarray, parent: int = -1, sigma: float = 0.0) -> dict:
        row = {"design": self.n, "parent": parent, "sigma": sigma, **dict(zip(self.free, x, strict=True)),
               "feasible": 0, "why": ""}
        self.n += 1
        margin = math.nan
        try:
            params = self.params_at(x)
            if self.margin_floor is not None:
                margin = fore_aft_margin(params)
                row["margin_mm"] = 1e3 * margin
                if self.floor is not None and margin < self.floor:
                    raise _BelowFloor
            gait = solve_fixed_point(Walker(params), z)
        except ParameterError:
            row["why"] = "parameters"
        except _BelowFloor:
            row["why"] = "margin"
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
            elif self.soft_ceiling is not None and self._soft(gait, row) > (
                    math.inf if self.ceiling is None else self.ceiling):
                row["why"] = "soft"
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
                self.archive.append({**row, "x": np.array(x, dtype=float), "z": gait.fixed_point,
                                     "margin": margin, "soft": row.get("soft_max", math.nan)})
                if self.margin_floor is not None and walks_both(row) and (
                        self.frontier is None or margin > self.frontier["margin"]):
                    self.frontier = self.archive[-1]
        why = row["why"] or "stable"
        self.counts[why] = self.counts.get(why, 0) + 1
        if row["why"] == "parameters":
            self.rejected += 1
        elif row["feasible"] or not self.feasible_only:
            self.writer.writerow(fmt_row(row, 6, fixed_point_digits=10))
        return row

    def _soft(self, gait, row: dict) -> float:
        """The worst max |eigenvalue| of the gait on soft feet of 1-4 ms (logged in ``row``)."""
        gaits = soft_gaits(gait, SOFT_STEPS)
        for name, g in zip(SOFT_COLUMNS, gaits[1:], strict=True):
            row[name] = "" if g is None else g.max_abs_eigenvalue
        row["soft_max"] = worst(gaits[1:])
        return row["soft_max"]

    def child(self) -> tuple[np.ndarray, np.ndarray, int, float]:
        """A parent drawn from the :data:`PARENTS` best, moved by a normal step."""
        if self.floor is None and self.clearance_range is None and self.ceiling is None:
            ranked = sorted(self.archive, key=lambda r: -r["score"])[:PARENTS]
        else:
            # Under a rising floor (margin, clearance) or a falling soft ceiling: the best of those
            # that meet it, else those closest to it (shortfalls in mm; the eigenvalue's x 1 mm).
            def shortfall(r: dict) -> float:
                short = 0.0 if self.floor is None else min(0.0, r["margin"] - self.floor)
                if self.clearance_range is not None:
                    short += min(0.0, 1e-3 * r["clearance_mm"] - self.min_clearance)
                if self.ceiling is not None:
                    short += 1e-3 * min(0.0, self.ceiling - r["soft"])
                return -short
            ranked = sorted(self.archive, key=lambda r: (shortfall(r), -r["score"]))[:PARENTS]
        parent = ranked[self.rng.integers(len(ranked))]
        sigma = float(np.exp(self.rng.uniform(*np.log(SIGMA))))
        step = sigma * (self.hi - self.lo) * self.rng.standard_normal(len(self.free))
        step[self.free.index("slope")] *= SLOPE_FACTOR
        return np.clip(parent["x"] + step, self.lo, self.hi), parent["z"], parent["design"], sigma

    def seed_from_log(self, log: Path, n: int = SEEDS) -> None:
        """Seed the archive with the ``n`` best feasible designs of an earlier log whose launch walks
        :data:`SEED_STEPS` steps from both tips, each re-solved from its logged fixed point (no floor)."""
        rows = [r for r in read_rows(log) if r["feasible"] == 1 and walks_both(r)]
        rows.sort(key=lambda r: -r["score"])
        for r in rows[:n]:
            x = np.array([float(r[p]) if p in r else self.base.get(p) for p in self.free])
            row = self.evaluate(x, np.array([float(r[f"z{i}"]) for i in range(8)]))
            print(f"seed {int(r['design'])} (design {row['design']}): score {row.get('score')}, "
                  f"steps {row.get('steps_1.5')} / {row.get('steps_2.5')}, "
                  f"margin {row.get('margin_mm', math.nan):.2f} mm", flush=True)


class _BelowFloor(Exception):
    """A design whose fore-aft margin is below the current ``--margin-floor``."""


def walk(search: Search, minutes: float, start_from: Path | None = None) -> None:
    if start_from is None:
        x0 = np.array([search.base.get(n) for n in search.free])
        first = search.evaluate(x0, np.array(search.base.gait_start))
        print(f"start: score {first.get('score')}, steps {first.get('steps_1.5')} / {first.get('steps_2.5')}",
              flush=True)
    else:
        search.seed_from_log(start_from)
    t0 = time.perf_counter()
    last = t0
    while time.perf_counter() - t0 < 60 * minutes:
        progress = min(1.0, (time.perf_counter() - t0) / (60 * minutes))
        if search.margin_floor is not None:
            lo, hi = search.margin_floor
            search.floor = lo + (hi - lo) * progress
        if search.soft_ceiling is not None:
            lo, hi = search.soft_ceiling
            search.ceiling = lo + (hi - lo) * progress
        if search.clearance_range is not None:
            lo, hi = search.clearance_range
            search.min_clearance = lo + (hi - lo) * progress
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
            best = "none" if search.best is None else f"{search.best['score']:.4f}"
            line = f"{search.n:5d} designs, {feasible} stable, best {best}, {last - t0:.0f} s"
            if search.clearance_range is not None:
                clear = [r for r in search.archive if 1e-3 * r["clearance_mm"] >= search.min_clearance]
                line += (f"; clearance floor {1e3 * search.min_clearance:.3f} mm: {len(clear)} feasible "
                         f"above it, {sum(walks_both(r) for r in clear)} walk {SEED_STEPS}+ from both")
            if search.ceiling is not None:
                under = [r for r in search.archive if r["soft"] <= search.ceiling]
                line += (f"; soft ceiling {search.ceiling:.4f}: {len(under)} feasible under it, "
                         f"{sum(walks_both(r) for r in under)} walk {SEED_STEPS}+ from both; lowest soft "
                         f"{min((r['soft'] for r in search.archive), default=math.nan):.4f}")
            if search.floor is not None:
                above = [r for r in search.archive if r["margin"] >= search.floor]
                f = search.frontier
                front = "none" if f is None else f"{1e3 * f['margin']:+.2f} mm (design {f['design']})"
                line += (f"; floor {1e3 * search.floor:+.2f} mm: {len(above)} feasible above it, "
                         f"{sum(walks_both(r) for r in above)} walk {SEED_STEPS}+ from both; largest margin "
                         f"walking both {front}")
            print(line, flush=True)


def _kick_signs() -> list[tuple]:
    """The distinct sign patterns of the kicks of seeds 0-7 (docs/make_basin.py), each with its seeds."""
    signs: dict[tuple, list[int]] = {}
    for seed in range(8):
        signs.setdefault(tuple(np.random.default_rng(seed).choice([-1.0, 1.0], 4)), []).append(seed)
    return list(signs.items())


def logged_params(base, row: dict):
    """A logged design's walker: ``base`` with the row's parameters (:data:`FREE`, and :data:`MORE`
    where the log has them)."""
    return base.replace(**{p: float(row[p]) for p in FREE + MORE if p in row})


def finalists(log: Path, n: int, mujoco: int, start: Path = START,
              min_clearance_mm: float = 0.0) -> list[dict]:
    """The ``n`` best designs of the log that cannot stand (and clear by ``min_clearance_mm``),
    measured in full; MuJoCo for the first ``mujoco`` of them."""
    from toywalk.model.mujoco_check import walk_in_mujoco

    base = load_params(start)
    rows = [r for r in read_rows(log) if r["feasible"] == 1 and r["clearance_mm"] >= min_clearance_mm]
    rows.sort(key=lambda r: -r["score"])
    free = [p for p in FREE + MORE if rows and p in rows[0]]
    out, seen = [], set()
    for r in rows:
        if len(out) >= n:
            break
        key = tuple(round(float(r[p]), 9) for p in free)
        if key in seen:
            continue
        seen.add(key)
        params = logged_params(base, r)
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


def write_finalists(found: list[dict], csv_path: Path = HERE / "launch_search_finalists.csv",
                    toml_path: Path = HERE / "launch_search_best.toml") -> None:
    keys = []
    for m in found:
        keys += [k for k in m if k not in keys and k not in ("params", "gait")]
    write_rows(csv_path, [{k: m[k] for k in keys if k in m} for m in found], keys)
    best = found[0]
    mj = "; ".join(f"{k[3:]} {v}" for k, v in best.items() if k.startswith("mj_"))
    header = (f"The best design of docs/make_launch_search.py (design {best['design']}, "
              f"score {best['score']:.4f}):\n"
              f"max |eigenvalue| {best['max_abs_eigenvalue']:.4f}, clearance {best['clearance_mm']:.2f} mm, "
              f"lean amplitude {best['lean_deg']:.3f} deg, can_stand False.\n"
              f"hand_launch (400 steps; tip x lean: steps, + converged): {best['hand_launch']}.\n"
              f"MuJoCo: {mj or 'not run'}.\n[gait] start is its fixed point.")
    start = tuple(float(v) for v in best["gait"].fixed_point)
    save_params(dataclasses.replace(best["params"], gait_start=start), toml_path,
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
    parser.add_argument("--start-from-log", type=Path, default=None,
                        help=f"seed the walk with the {SEEDS} best designs of this log that walk "
                             f"{SEED_STEPS}+ steps from both tips (instead of docs/launch_converging.toml)")
    parser.add_argument("--free-more", action="store_true", help=f"free {', '.join(MORE)} too")
    parser.add_argument("--margin-floor", default=None, metavar="START:END",
                        help="mm: designs whose fore-aft margin is below the floor are infeasible; the "
                             "floor rises linearly from START to END over --minutes")
    parser.add_argument("--soft-ceiling", default=None, metavar="START:END",
                        help="designs whose gait on soft feet of 1-4 ms has a max |eigenvalue| above the "
                             "ceiling are infeasible; it falls linearly from START to END over --minutes")
    parser.add_argument("--finalists-csv", type=Path, default=HERE / "launch_search_finalists.csv")
    parser.add_argument("--best-toml", type=Path, default=HERE / "launch_search_best.toml")
    parser.add_argument("--start", type=Path, default=START,
                        help="the walker the walk starts from (its [gait] start a fixed point)")
    parser.add_argument("--clearance-to", type=float, default=None, metavar="MM",
                        help="raise the clearance floor from --min-clearance to this over --minutes")
    parser.add_argument("--finalists-clearance", type=float, default=0.0, metavar="MM",
                        help="finalists only among designs clearing by at least this much")
    parser.add_argument("--feasible-only", action="store_true",
                        help="log the feasible designs alone (the others are only counted)")
    args = parser.parse_args()
    if args.start_from_log is not None and args.start_from_log.resolve() == args.log.resolve():
        parser.error("--start-from-log must differ from --log (the log is rewritten)")
    floor = parse_pair(parser, args.margin_floor, "--margin-floor", "START:END in mm", 1e-3)
    ceiling = parse_pair(parser, args.soft_ceiling, "--soft-ceiling")
    if args.minutes > 0:
        search = Search(args.log, np.random.default_rng(args.seed), args.max_eigenvalue,
                        1e-3 * args.min_clearance, free_more=args.free_more, margin_floor=floor,
                        feasible_only=args.feasible_only, start=args.start,
                        clearance_to=None if args.clearance_to is None else 1e-3 * args.clearance_to,
                        soft_ceiling=ceiling)
        try:
            walk(search, args.minutes, args.start_from_log)
        finally:
            search.close()
        logged = "; only the stable ones logged" if search.feasible_only else ""
        print(f"{search.n} designs: {search.counts} (parameters: not logged{logged}); best {search.best}",
              flush=True)
    if args.finalists > 0:
        found = finalists(args.log, args.finalists, args.mujoco, args.start, args.finalists_clearance)
        if found:
            write_finalists(found, args.finalists_csv, args.best_toml)


if __name__ == "__main__":
    main()
