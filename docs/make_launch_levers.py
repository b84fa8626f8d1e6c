"""One lever at a time on the launchable walker: does anything carry its hand launch from 2.5 x lean?

docs/launch_search_best.toml (docs/gaits.md section 7, "From 1.5 and 2.5 x lean") cannot stand, its
gait is stable, its hand launch converges from 1.2 and 1.5 x its lean amplitude and falls after 10
steps from 2.5 x. Its search moved eleven parameters together; this script moves one at a time,
each lever followed by natural continuation (Newton from the previous gait, in :data:`SUBSTEPS`
substeps between the values listed), and at every value walks the hand launches at
:data:`MULTIPLES` x the gait's lean amplitude as the search scores them (``launch_walk`` of
docs/make_robust_design.py, up to :data:`STEPS` steps):

- **foot_lateral_radius** from 4 mm to the fore-aft radius (the torus's limit, 41.5 mm): the
  sideways curvature of the foot sets whether the walker rocks on it like a pendulum or tips like a
  block, the rocking being what lifts the swing foot at the launch;
- **hinge_stiffness** (a spring between the legs, an elastic band; N m/rad) from -0.02 to 0.08: a
  swing leg that swings faster (or slower) than the rocking;
- **hip_damping** (N m s/rad) from 1e-6 to 2e-5: friction in the hinge, which takes energy out of
  the alternation of long and short steps that the launches from large tips show;
- **rolling_resistance** (N m s/rad) from 1e-6 to 2e-5: a viscous loss in the rolling contact, for the same;
- **hip_coulomb** (N m) from 1e-6 to 3e-5: dry friction in the hinge, which would stop the swing
  leg's swinging back at the stutter step that ends those launches (docs/gaits.md section 7);
- **roll_damping** (N m s/rad) from 1e-6 to 1e-4: a viscous loss of the foot's roll on the ramp,
  which would take the excess rocking of a large tip.

The effects are the model's library (docs/effects.md); MuJoCo's walker has none of them
(``build_mjcf`` refuses effects), so a lever that worked would be checked there by building it in.

Output: docs/launch_levers.csv (a row per lever and value: the gait's max |eigenvalue|, clearance,
lean amplitude and step time, and steps and reason of each launch).

``--releases``: other ways to let go, on the shipped robust walker and two others
(:data:`RELEASE_WALKERS`): ``hand_launch`` with the legs open by :data:`SPLITS` x the gait's own
opening at heel strike and pushed forward at :data:`RATES` x its stance leg's rate just after heel
strike (``launch_state``'s ``split`` and ``rate``: the walker rolling forward on its stance foot
as one body), at the tips of :data:`MULTIPLES` x lean, :data:`STEPS` steps; output
docs/launch_releases.csv. Run (one core, kernels cached; about 3 and 2 minutes)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_levers.py
    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_levers.py --releases

``--slope``: the one lever the searches moved only in tiny steps. Design :data:`DESIGN` of
docs/launch_push.csv (the margin homotopy's best that cannot stand: fore-aft margin +0.59 mm;
from 1.5 x lean its launch converges, from 2.5 x it walks 12 steps) followed down in slope from
its own, 0.0172 rad, to :data:`SLOPE_LOW` in steps of :data:`SLOPE_STEP` (Newton from the last
gait), and at every slope ``hand_launch`` at :data:`SLOPE_MULTIPLES` x lean (``recovers``'
defaults: converged within 1e-4 of the fixed point, 600 steps at most) and ``can_stand``. The
longest run of slopes where the launches from 1.5 and 2.5 x lean both converge is the window; its
middle, to 1e-4 rad, is docs/launch_toy.toml (its fixed point the ``[gait] start``), which is
data/params/launch-toy.toml with its header written by hand. Output docs/launch_toy_slope.csv.
Run (about 3 minutes)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_levers.py --slope

``--slope-of P.toml`` follows another walker instead (its ``[gait] start`` near its fixed point),
``--slope-range LOW:HIGH`` over those slopes (reached from its own slope by Newton in steps of
:data:`SLOPE_STEP`), writing ``--slope-csv`` and ``--slope-toml``. docs/launch_clear_toy.toml,
data/params/launch-clear-toy.toml with its header written by hand, is (1 minute)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_levers.py --slope \
        --slope-of docs/launch_clear_1mm_best.toml --slope-range 0.0072:0.0090 \
        --slope-csv docs/launch_clear_slope.csv --slope-toml docs/launch_clear_toy.toml

``--soft-slope P.toml``: where on the ramp is the walker's gait stable on soft feet? The gait
followed (rigid, by Newton in steps of :data:`SOFT_SLOPE_STEP`) from the walker's slope up to
:data:`SOFT_SLOPE_HIGH`; there, for each tau of :data:`SOFT_TAUS`, onto soft feet (``soft_heel``,
tau raised in steps of :data:`SOFT_TAU_STEP`, :data:`SOFT_STEPS` RK4 steps per tau); then down in
slope in steps of :data:`SOFT_SLOPE_STEP` to :data:`SOFT_SLOPE_LOW` or until Newton loses the gait.
Output (``--soft-slope-csv``, default docs/launch_clear_soft_slope.csv): per tau and slope the max
|eigenvalue| and the largest real eigenvalue (a real eigenvalue reaching +1 is a fold, where the
gait ends), and per tau a row ``lost`` at the first slope where Newton lost it. Run (4 minutes)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_levers.py \
        --soft-slope data/params/launch-clear-toy.toml
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
from toywalk.model import (
    Walker,
    can_stand,
    find_gait,
    hand_launch,
    load_params,
    save_params,
    solve_fixed_point,
)
from toywalk.model.gait import GaitNotFound
from toywalk.model.walker import StepFailure

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_launch_margin import parse_pair, read_rows, write_rows  # noqa: E402
from make_launch_search import logged_params  # noqa: E402
from make_robust_design import launch_walk  # noqa: E402
from make_soft_robust_design import STEPS_PER_TAU  # noqa: E402

HERE = Path(__file__).resolve().parent
START = HERE / "launch_search_best.toml"
MULTIPLES = (1.0, 1.5, 2.0, 2.5, 3.0)
STEPS = 200
SUBSTEPS = 5
LEVERS = {
    "foot_lateral_radius": (0.004, 0.0075, 0.015, 0.025, 0.035, 0.0415),
    "effects.hinge_stiffness": (-0.02, -0.01, -0.005, 0.005, 0.01, 0.02, 0.04, 0.08),
    "effects.hip_damping": (1e-6, 3e-6, 1e-5, 2e-5),
    "effects.rolling_resistance": (1e-6, 3e-6, 1e-5, 2e-5),
    "effects.hip_coulomb": (1e-6, 3e-6, 1e-5, 3e-5),
    "effects.roll_damping": (1e-6, 1e-5, 1e-4),
}
RELEASE_WALKERS = {"robust-toy": HERE.parent / "data" / "params" / "robust-toy.toml",
                   "clearing-toy": HERE.parent / "data" / "params" / "clearing-toy.toml",
                   "launch_search_best": START}
SPLITS = (0.0, 0.5, 1.0)
RATES = (0.0, 0.25, 0.5, 0.75, 1.0)
RELEASE_COLUMNS = ["walker", "split", "split_rad", "rate", "rate_rad_s", *(f"steps_{m:g}" for m in MULTIPLES),
                   *(f"reason_{m:g}" for m in MULTIPLES)]
DESIGN = 35044
SLOPE_LOW = 0.0068
SLOPE_STEP = 1e-4
SLOPE_MULTIPLES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
SLOPE_COLUMNS = ["slope", "max_abs_eigenvalue", "clearance_mm", "lean_deg", "step_time", "can_stand",
                 *(f"{k}_{m:g}" for m in SLOPE_MULTIPLES for k in ("steps", "reason"))]
SOFT_TAUS = (0.0, 1e-3, 2e-3, 4e-3)  # s: rigid and issue 44's soft contacts
SOFT_TAU_STEP = 2.5e-4  # s
SOFT_STEPS = STEPS_PER_TAU  # RK4 steps per tau (80: docs/make_soft_robust_design.py)
SOFT_SLOPE_HIGH = 0.016  # rad: launch-clear-toy's 1.5 x launch converges up to here, its 2.5 x does not
SOFT_SLOPE_LOW = 0.006  # rad
SOFT_SLOPE_STEP = 2e-4  # rad
SOFT_SLOPE_COLUMNS = ["tau_ms", "slope", "status", "max_abs_eigenvalue", "largest_real_eigenvalue",
                      "step_time"]
COLUMNS = ["lever", "value", "max_abs_eigenvalue", "clearance_mm", "lean_deg", "step_time",
           *(f"{k}_{m:g}" for m in MULTIPLES for k in ("steps", "reason"))]


def lever_rows(name: str, values, start) -> list[dict]:
    """The lever ``name`` followed out from the start's value through ``values`` in each direction
    (values below the start's first, descending, then those above, ascending)."""
    base_value = start.get(name) if not name.startswith("effects.") else 0.0
    below = sorted((v for v in values if v < base_value), reverse=True)
    above = sorted(v for v in values if v > base_value)
    rows = []
    for side in (below, above):
        z, previous = np.array(start.gait_start), base_value
        for value in side:
            row = {"lever": name, "value": value}
            try:
                for s in np.linspace(previous, value, SUBSTEPS + 1)[1:]:
                    params = start.replace(**{name: float(s)})
                    gait = solve_fixed_point(Walker(params), z)
                    z = gait.fixed_point
            except (GaitNotFound, StepFailure) as err:
                row["reason_1"] = f"gait lost at {s:.4g}: {str(err)[:60]}"
                rows.append(row)
                print(f"{name} {value:g}: gait lost at {s:.4g}", flush=True)
                break
            previous = value
            walker = Walker(params)
            row.update(max_abs_eigenvalue=gait.max_abs_eigenvalue, clearance_mm=1e3 * gait.clearance,
                       lean_deg=math.degrees(gait.lean_amplitude), step_time=gait.step_time)
            for m in MULTIPLES:
                walk = launch_walk(walker, gait, m * gait.lean_amplitude, steps=STEPS)
                row[f"steps_{m:g}"], row[f"reason_{m:g}"] = walk["steps"], walk["reason"]
            rows.append(row)
            print(f"{name} {value:g}: |lambda| {gait.max_abs_eigenvalue:.4f}, "
                  f"clear {1e3 * gait.clearance:.2f} mm, "
                  f"lean {math.degrees(gait.lean_amplitude):.3f} deg; launches "
                  + " ".join(f"{m:g}:{row[f'steps_{m:g}']}{row[f'reason_{m:g}'][:4]}" for m in MULTIPLES),
                  flush=True)
    return rows


def release_rows() -> list[dict]:
    """:data:`RELEASE_WALKERS`' releases over :data:`SPLITS` x :data:`RATES` (the module's docstring)."""
    rows = []
    for name, path in RELEASE_WALKERS.items():
        gait = find_gait(load_params(path))
        split = float(gait.fixed_point[6] - gait.fixed_point[4])  # trailing minus leading leg's pitch
        rate = float(gait.fixed_point[5])
        tips = [m * gait.lean_amplitude for m in MULTIPLES]
        for a in SPLITS:
            for b in RATES:
                launch = hand_launch(gait.params, tips, gait=gait, split=a * split, rate=b * rate,
                                     steps=STEPS)
                row = {"walker": name, "split": a, "split_rad": a * split, "rate": b, "rate_rad_s": b * rate}
                for m, r in zip(MULTIPLES, launch.results[0], strict=True):
                    row[f"steps_{m:g}"], row[f"reason_{m:g}"] = r.steps, r.reason
                rows.append(row)
                print(f"{name} split {a:g} x {split:.3f} rad, rate {b:g} x {rate:.3f} rad/s: "
                      + " ".join(f"{m:g}:{row[f'steps_{m:g}']}{row[f'reason_{m:g}'][:4]}" for m in MULTIPLES),
                      flush=True)
    return rows


def design_35044():
    """:data:`DESIGN` of docs/launch_push.csv: its walker and logged fixed point."""
    base = load_params(HERE / "launch_converging.toml")
    row = next(r for r in read_rows(HERE / "launch_push.csv") if int(r["design"]) == DESIGN)
    return logged_params(base, row), np.array([float(row[f"z{i}"]) for i in range(8)])


def slope_rows(params, z: np.ndarray, low: float = SLOPE_LOW,
               high: float | None = None) -> tuple[list[dict], list]:
    """A walker (``z`` near its fixed point) followed in slope (the module's docstring) on the grid
    of :data:`SLOPE_STEP` from ``high`` (default: the grid point at or below its own slope) down to
    ``low``, reached from its own slope by Newton in grid steps: the rows, and the gaits."""
    rows, gaits = [], []
    n = int(round(((params.slope if high is None else high) - low) / SLOPE_STEP))
    top = low + n * SLOPE_STEP
    up = int(np.ceil((top - params.slope) / SLOPE_STEP - 1e-9))  # grid steps up to ``top`` first
    path = [params.slope, *(params.slope + (top - params.slope) * i / up for i in range(1, up))]
    recorded = [top - i * SLOPE_STEP for i in range(n + 1)]
    for k, slope in enumerate([*path, *recorded]):
        here = params.replace(slope=float(round(slope, 10)))
        gait = solve_fixed_point(Walker(here), z)
        z = gait.fixed_point
        if k < len(path):
            continue  # the design itself and the way up: only the start of the path
        tips = [m * gait.lean_amplitude for m in SLOPE_MULTIPLES]
        launch = hand_launch(here, tips, gait=gait)
        out = {"slope": here.slope, "max_abs_eigenvalue": gait.max_abs_eigenvalue,
               "clearance_mm": 1e3 * gait.clearance, "lean_deg": math.degrees(gait.lean_amplitude),
               "step_time": gait.step_time, "can_stand": int(can_stand(here).can_stand)}
        for m, r in zip(SLOPE_MULTIPLES, launch.results[0], strict=True):
            out[f"steps_{m:g}"], out[f"reason_{m:g}"] = r.steps, r.reason
        rows.append(out)
        gaits.append(gait)
        print(f"slope {here.slope:.4f}: |lambda| {gait.max_abs_eigenvalue:.4f}, stands {out['can_stand']}; "
              + " ".join(f"{m:g}:{out[f'steps_{m:g}']}{out[f'reason_{m:g}'][:4]}" for m in SLOPE_MULTIPLES),
              flush=True)
    return rows, gaits


def soft_slope_rows(params) -> list[dict]:
    """The walker's gait on soft feet along the slope (the module's docstring, ``--soft-slope``)."""
    z = np.array(params.gait_start)
    grid = np.arange(params.slope, SOFT_SLOPE_HIGH + 0.5 * SOFT_SLOPE_STEP, SOFT_SLOPE_STEP)
    for slope in [*grid[1:], SOFT_SLOPE_HIGH]:
        z = solve_fixed_point(Walker(params.replace(slope=float(slope))), z).fixed_point
    top, rows = z, []
    slopes = np.arange(SOFT_SLOPE_HIGH, SOFT_SLOPE_LOW - 0.5 * SOFT_SLOPE_STEP, -SOFT_SLOPE_STEP)
    for tau in SOFT_TAUS:
        def walker(slope, t=tau):
            return Walker(params.replace(slope=float(slope), **{"effects.soft_heel": float(t)}),
                          soft_steps_per_tau=SOFT_STEPS)
        z = top
        for t in np.arange(SOFT_TAU_STEP, tau + 0.5 * SOFT_TAU_STEP, SOFT_TAU_STEP):
            z = solve_fixed_point(walker(SOFT_SLOPE_HIGH, t), z).fixed_point
        for slope in slopes:
            row = {"tau_ms": 1e3 * tau, "slope": round(float(slope), 10)}
            try:
                gait = solve_fixed_point(walker(slope), z)
            except (GaitNotFound, StepFailure):
                rows.append({**row, "status": "lost"})
                print(f"tau {1e3 * tau:g} ms: lost at slope {slope:.4f}", flush=True)
                break
            z = gait.fixed_point
            rows.append({**row, "status": "found", "max_abs_eigenvalue": gait.max_abs_eigenvalue,
                         "largest_real_eigenvalue": float(np.max(gait.eigenvalues.real)),
                         "step_time": gait.step_time})
        stable = [r["slope"] for r in rows if r["tau_ms"] == 1e3 * tau and r["status"] == "found"
                  and r["max_abs_eigenvalue"] < 1]
        print(f"tau {1e3 * tau:g} ms: stable on "
              + (f"{min(stable):.4f}-{max(stable):.4f} rad" if stable else "no slope followed"), flush=True)
    return rows


def launch_window(rows: list[dict]) -> tuple[int, int]:
    """(first, last) index of the longest run of rows where the launches from 1.5 and 2.5 x lean
    both converge (the first such run of that length)."""
    ok = [r["reason_1.5"] == "recovered" and r["reason_2.5"] == "recovered" and not r["can_stand"]
          for r in rows]
    best, start = (0, -1), None
    for i, good in enumerate([*ok, False]):
        if good and start is None:
            start = i
        elif not good and start is not None:
            if i - 1 - start > best[1] - best[0]:
                best = (start, i - 1)
            start = None
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--releases", action="store_true", help="the releases instead of the levers")
    parser.add_argument("--slope", action="store_true", help="design 35044 in slope instead of the levers")
    parser.add_argument("--slope-of", type=Path, default=None, metavar="P.toml",
                        help="with --slope: this walker (its [gait] start near its fixed point) instead")
    parser.add_argument("--slope-range", default=None, metavar="LOW:HIGH",
                        help=f"with --slope: the slopes scanned (rad; default {SLOPE_LOW:g} to its own)")
    parser.add_argument("--soft-slope", type=Path, default=None, metavar="P.toml",
                        help="this walker's gait on soft feet of 1-4 ms along the slope instead")
    parser.add_argument("--soft-slope-csv", type=Path, default=HERE / "launch_clear_soft_slope.csv")
    parser.add_argument("--slope-csv", type=Path, default=HERE / "launch_toy_slope.csv")
    parser.add_argument("--slope-toml", type=Path, default=HERE / "launch_toy.toml")
    args = parser.parse_args()
    if args.soft_slope is not None:
        write_rows(args.soft_slope_csv, soft_slope_rows(load_params(args.soft_slope)), SOFT_SLOPE_COLUMNS)
        return
    if args.slope:
        low, high = (parse_pair(parser, args.slope_range, "--slope-range", "LOW:HIGH in rad")
                     or (SLOPE_LOW, None))
        if args.slope_of is None:
            params, z = design_35044()
            what = f"Design {DESIGN} of docs/launch_push.csv"
        else:
            params = load_params(args.slope_of)
            z, what = np.array(params.gait_start), f"{args.slope_of.name}"
        rows, gaits = slope_rows(params, z, low, high)
        write_rows(args.slope_csv, rows, SLOPE_COLUMNS)
        first, last = launch_window(rows)
        if last < first:
            print("no slope where both launches converge")
            return
        middle = (first + last) // 2
        gait = gaits[middle]
        header = (f"{what} at the middle of the slopes "
                  f"{rows[last]['slope']:.4f}-{rows[first]['slope']:.4f} rad where its hand launch "
                  f"converges from 1.5 and 2.5 x lean (docs/make_launch_levers.py --slope).\n"
                  "[gait] start is its fixed point.")
        save_params(dataclasses.replace(gait.params, gait_start=tuple(float(v) for v in gait.fixed_point)),
                    args.slope_toml, header=header)
        print(f"window {rows[last]['slope']:.4f}-{rows[first]['slope']:.4f} rad; wrote {args.slope_toml} "
              f"(slope {gait.params.slope:.4f})")
        return
    if args.releases:
        rows = release_rows()
        write_rows(HERE / "launch_releases.csv", rows, RELEASE_COLUMNS)
        return
    start = load_params(START)
    rows = []
    for name, values in LEVERS.items():
        rows += lever_rows(name, values, start)
    write_rows(HERE / "launch_levers.csv", rows, COLUMNS)


if __name__ == "__main__":
    main()
