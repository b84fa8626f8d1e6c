"""A stable walker that cannot stand and clears its swing foot: the search behind
data/params/clearing-toy.toml (docs/gaits.md section 4).

Stages, each from the previous one's walker (warm-started gaits, toywalk.model.optimize), every
gait found logged (``--log``, about 7 MB for the run in docs/gaits.md):

1. the shipped stable walker (data/params/stable-toy.toml) widened, hip width w from 34.7 mm to
   160 mm in 26 steps: max |eigenvalue| and the swing foot's clearance over the whole swing;
2. ``--stage design``: two stages of Nelder-Mead (``minimise_max_eigenvalue``) over eleven
   parameters (FREE, within BOUNDS), each two rounds: (a) the highest clearance with max
   |eigenvalue| <= ``--max-eigenvalue`` (0.93), from the most stable walker of stage 1; (b) the
   lowest max |eigenvalue| with the clearance at least ``--clearance`` (1.5 mm). Both keep the
   centre of mass 5 mm above the feet's lateral centre of curvature (static_margin). The result
   goes to docs/clearance_best.toml; data/params/clearing-toy.toml is it rounded to four digits;
3. ``--stage toy`` (after design): towards the toy's stride time, advance and lean, keeping max
   |eigenvalue| <= 0.9 (``--max-eigenvalue 0.9``) and the clearance.

Every stage then summarises the log: docs/clearance_search.csv (stage 1's gaits and the stable
gaits no other beat on both clearance and max |eigenvalue|), docs/clearance_front.png (every gait
found) and, printed, how many gaits each stage found, how many were stable and cleared, and the
range each parameter spanned.

Run (about 20 min of one core for design, 11 min for toy, on a shared 2-core machine)::

    TOYWALK_CACHE=/tmp/twcache .venv/bin/python docs/make_clearance_design.py --maxiter 600 --log L.csv
    TOYWALK_CACHE=/tmp/twcache .venv/bin/python docs/make_clearance_design.py --stage toy \
        --maxiter 400 --max-eigenvalue 0.9 --log L.csv
    TOYWALK_CACHE=/tmp/twcache .venv/bin/python docs/make_clearance_design.py --stage summary --log L.csv
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, can_stand, load_params, save_params, solve_fixed_point, static_margin
from toywalk.model.optimize import GaitEvaluator, minimise_max_eigenvalue

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
# A fixed point of stable-toy's gait (public state order), from tests/model/documented.py.
Z_STABLE = [0.04661788900461893, -0.5141677402083711, -0.001876783030565294, 0.021718470946236697,
            -0.08694501480362028, 4.231073000769995, 0.08135087368205376, 2.3913296604495535]
# The shipped walker's fixed point (data/params/clearing-toy.toml), from tests/model/documented.py.
Z_CLEARING = [0.07050947332653978, -0.46650017313326736, -0.010489277599679167, -0.4243942466228133,
              -0.18659626122490666, 3.228258310166639, 0.13667971250468633, 1.1314428232345919]
# The design stage's result's fixed point (docs/clearance_best.toml), printed by that stage.
Z_DESIGN = [0.07051408377812535, -0.4664310852366725, -0.010490041087784313, -0.42444404878746045,
            -0.1865764779337875, 3.2282254446305685, 0.13666183121327982, 1.1321323979553932]
FREE = ["hip_width", "foot_radius", "foot_lateral_radius", "com_offset[0]", "com_offset[1]",
        "com_offset[2]", "inertia[0]", "inertia[1]", "inertia[2]", "inertia[5]", "slope"]
# Bounds: a toy-sized walker (15 cm legs, 50 g legs) that could be built: feet no larger than a
# spool, hips at most 16 cm apart, the balance masses within 25 cm of the leg, ramps up to 6 degrees.
BOUNDS = {
    "hip_width": (0.02, 0.16),
    "foot_radius": (0.002, 0.03),
    "foot_lateral_radius": (0.001, 0.03),
    "com_offset[0]": (-0.02, 0.02),
    "com_offset[1]": (0.05, 0.25),
    "com_offset[2]": (-0.145, -0.05),
    "inertia[0]": (2e-5, 1e-3),
    "inertia[1]": (2e-6, 1e-3),
    "inertia[2]": (2e-5, 1e-3),
    "inertia[5]": (-1e-4, 1e-4),
    "slope": (0.005, 0.105),
}
STATIC_MARGIN = 0.005  # m, the centre of mass above the feet's lateral centre of curvature
COLUMNS = ["stage", *FREE, "max_abs_eigenvalue", "clearance", "clearance_phase", "clearance_ahead",
           "at_passing", "step_time", "stride_length", "lean_amplitude", "static_margin"]


def _row(stage: str, params, gait) -> list:
    sw = gait.swing_clearance
    return [stage, *(params.get(n) for n in FREE), gait.max_abs_eigenvalue, sw.minimum, sw.phase,
            sw.ahead, sw.at_passing, gait.step_time, gait.stride_length, gait.lean_amplitude,
            static_margin(params)]


def front(base, gait0, rows: list) -> list:
    """Stage 1: widen the hips. Returns the gaits found along the way."""
    evaluator = GaitEvaluator(base, ["hip_width"], gait0)
    gaits = []
    for w in np.linspace(base.hip_width, 0.16, 26):
        g = evaluator([w])
        if g is None:
            print(f"w = {1e3 * w:.1f} mm: no gait")
            continue
        rows.append(_row("front", g.params, g))
        gaits.append(g)
        print(f"w = {1e3 * w:6.1f} mm: max|lambda| {g.max_abs_eigenvalue:.4f}, clearance "
              f"{1e3 * g.clearance:7.3f} mm at {g.swing_clearance.phase:.2f} of the step", flush=True)
    return gaits


def _search(stage: str, start, rows: list, rounds: int, maxiter: int, **kwargs):
    """Rounds of Nelder-Mead (each restarting the simplex at the last best), every gait logged."""

    def logged(objective):
        def f(gait):
            rows.append(_row(stage, gait.params, gait))
            return objective(gait)
        return f

    kwargs["objective"] = logged(kwargs.get("objective") or (lambda g: g.max_abs_eigenvalue))
    best, t0 = start, time.perf_counter()
    for k in range(rounds):
        result = minimise_max_eigenvalue(best, FREE, BOUNDS, maxiter=maxiter, **kwargs)
        print(f"{stage} round {k + 1}: objective {result.start_value:.5g} -> {result.value:.5g}, "
              f"{result.evaluations} evaluations, {result.failures} without a gait, "
              f"{result.jumps} branch jumps, {time.perf_counter() - t0:.0f} s", flush=True)
        if result.status == "improved":
            best = result.gait
    return best


def _write_log(path: Path, rows: list, mode: str) -> None:
    with open(path, mode, newline="") as f:
        writer = csv.writer(f)
        if mode == "w":
            writer.writerow(COLUMNS)
        writer.writerows(rows)


def main(maxiter: int, rounds: int, max_eigenvalue: float, clearance: float, log: Path) -> None:
    base = load_params(ROOT / "data" / "params" / "stable-toy.toml")
    gait0 = solve_fixed_point(Walker(base), np.array(Z_STABLE))
    rows: list = [_row("start", base, gait0)]
    gaits = front(base, gait0, rows)
    start = min(gaits, key=lambda g: g.max_abs_eigenvalue)

    def static(params, gait):
        return static_margin(params) - STATIC_MARGIN

    def stable(params, gait):
        return min(static(params, gait), (max_eigenvalue - gait.max_abs_eigenvalue) * params.leg_length)

    # Stage 2a: the highest clearance with max |eigenvalue| <= max_eigenvalue.
    lifted = _search("clearance", start, rows, rounds, maxiter, constraint=stable,
                     objective=lambda g: -g.clearance / g.params.leg_length)
    # Stage 2b: the most stable walker that keeps the clearance asked for.
    best = _search("stability", lifted, rows, rounds, maxiter, constraint=static,
                   min_clearance=clearance)
    _write_log(log, rows, "w")
    params = best.params
    report = can_stand(params)
    sw = best.swing_clearance
    print(f"best: max|lambda| {best.max_abs_eigenvalue:.4f}, clearance {1e3 * sw.minimum:.3f} mm at "
          f"{sw.phase:.2f} of the step ({1e3 * sw.ahead:.1f} mm ahead), step {best.step_time:.4f} s, "
          f"stride {1e3 * best.stride_length:.1f} mm, lean {math.degrees(best.lean_amplitude):.2f} deg, "
          f"can stand: {report.can_stand}")
    print("fixed point:", [float(v) for v in best.fixed_point])
    print({n: params.get(n) for n in FREE})
    save_params(params, HERE / "clearance_best.toml", header="search result (docs/make_clearance_design.py)")


# The toy's gait (Coleman & Ruina 1998, PRL 80:3658; docs/model.md section 7): stride time (s),
# advance per stride (m), side-to-side tilt (rad).
TOY = {"stride_time": 0.47, "stride_length": 0.013, "lean_amplitude": math.radians(4.0)}


def toy_stage(maxiter: int, rounds: int, max_eigenvalue: float, clearance: float, log: Path) -> None:
    """Stage 3: from the design (docs/clearance_best.toml), towards the toy's regime: the smallest
    misfit sum(log(feature / toy's)^2) over stride time, stride length and lean amplitude, with
    max |eigenvalue| <= max_eigenvalue, the clearance asked for and the static margin kept. Gaits
    appended to the log (stage "toy"); the best, if better than the start, to
    docs/clearance_toy.toml."""
    base = load_params(HERE / "clearance_best.toml")
    start = solve_fixed_point(Walker(base), np.array(Z_DESIGN))
    rows: list = []

    def feasible(params, gait):
        return min(static_margin(params) - STATIC_MARGIN,
                   (max_eigenvalue - gait.max_abs_eigenvalue) * params.leg_length)

    def misfit(gait):
        return sum(math.log(getattr(gait, k) / v) ** 2 for k, v in TOY.items())

    best = _search("toy", start, rows, rounds, maxiter, constraint=feasible, objective=misfit,
                   min_clearance=clearance)
    _write_log(log, rows, "a")
    sw = best.swing_clearance
    print(f"toy stage best: misfit {misfit(best):.4f}, max|lambda| {best.max_abs_eigenvalue:.4f}, "
          f"clearance {1e3 * sw.minimum:.3f} mm, stride {best.stride_time:.4f} s, "
          f"{1e3 * best.stride_length:.1f} mm, lean {math.degrees(best.lean_amplitude):.2f} deg, "
          f"can stand: {can_stand(best.params).can_stand}")
    print("fixed point:", [float(v) for v in best.fixed_point])
    if best is not start:
        save_params(best.params, HERE / "clearance_toy.toml",
                    header="toy-regime stage (docs/make_clearance_design.py)")


def pareto(clearance: np.ndarray, eigenvalue: np.ndarray) -> np.ndarray:
    """Indices of the gaits no other beats on both counts (higher clearance and lower max
    |eigenvalue|), in order of clearance."""
    order = np.argsort(-clearance)
    front, best = [], np.inf
    for i in order:
        if eigenvalue[i] < best:
            front.append(i)
            best = eigenvalue[i]
    return np.array(front[::-1], dtype=int)


def summarise(log: Path) -> None:
    """From the search log: docs/clearance_search.csv (the front of stage 1 and the stable gaits
    best on both counts, every column), the figure docs/clearance_front.png, and per stage the gaits
    found, how many are stable and clear by 1 mm, and the range each free parameter spanned."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(log) as f:
        rows = list(csv.DictReader(f))
    stage = np.array([r["stage"] for r in rows])
    clr = 1e3 * np.array([float(r["clearance"]) for r in rows])
    lam = np.array([float(r["max_abs_eigenvalue"]) for r in rows])
    margin = np.array([float(r["static_margin"]) for r in rows])
    ok = margin >= STATIC_MARGIN
    stable_ok = ok & (lam < 1)
    best = np.flatnonzero(stable_ok)[pareto(clr[stable_ok], lam[stable_ok])]
    keep = sorted(set(np.flatnonzero(stage == "front")) | set(best))
    with open(HERE / "clearance_search.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([*COLUMNS, "on_front"])
        for i in keep:
            writer.writerow([rows[i]["stage"], *(f"{float(rows[i][c]):.6g}" for c in COLUMNS[1:]),
                             int(i in set(best))])
    for name in dict.fromkeys(stage):
        sel = stage == name
        good = sel & ok & (lam < 1) & (clr >= 1.0)
        spans = ", ".join(f"{n} {min(float(rows[i][n]) for i in np.flatnonzero(sel)):.3g}.."
                          f"{max(float(rows[i][n]) for i in np.flatnonzero(sel)):.3g}" for n in FREE)
        print(f"{name}: {sel.sum()} gaits, {(sel & (lam < 1)).sum()} stable, of which {good.sum()} "
              f"clear by 1 mm with static margin >= 5 mm; parameters spanned {spans}")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    labels = {"front": "stable-toy, hips widened (stage 1)",
              "clearance": "highest clearance, max |lambda| <= 0.93 (stage 2a)",
              "stability": "lowest max |lambda|, clearance >= 1.5 mm (stage 2b)",
              "toy": "towards the toy's regime (stage 3)"}
    colours = {"front": "k", "clearance": "tab:blue", "stability": "tab:orange", "toy": "tab:green"}
    for name in labels:
        sel = stage == name
        if sel.any():
            ax.plot(clr[sel], lam[sel], ".", ms=5 if name == "front" else 2, color=colours[name],
                    alpha=0.5, label=labels[name])
    ax.plot(clr[best], lam[best], "-", color="tab:red", lw=1.5,
            label="stable gaits best found on both counts (static margin >= 5 mm)")
    gait = solve_fixed_point(Walker(load_params(ROOT / "data" / "params" / "clearing-toy.toml")),
                             np.array(Z_CLEARING))
    ax.plot(1e3 * gait.clearance, gait.max_abs_eigenvalue, "k*", ms=12, label="clearing-toy.toml")
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.axvline(1.0, color="0.5", lw=0.8, ls=":")
    ax.set_xlim(-0.5, 4.5)
    ax.set_ylim(0.8, 1.2)
    ax.set_xlabel("swing-foot clearance over the whole swing (mm)")
    ax.set_ylabel("step-map max |eigenvalue|")
    ax.set_title(f"{len(rows)} gaits found by docs/make_clearance_design.py", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(HERE / "clearance_front.png", dpi=120)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maxiter", type=int, default=400, help="Nelder-Mead iterations a round")
    parser.add_argument("--rounds", type=int, default=2, help="Nelder-Mead restarts a stage")
    parser.add_argument("--max-eigenvalue", type=float, default=0.93)
    parser.add_argument("--clearance", type=float, default=0.0015, help="m")
    parser.add_argument("--stage", choices=["design", "toy", "summary"], default="design",
                        help="design: stages 1-2; toy: stage 3 (after design); summary: the CSV, "
                             "the figure and the counts from the log only")
    parser.add_argument("--log", type=Path, default=Path("clearance_search_log.csv"),
                        help="every gait found (written by design, appended by toy; large)")
    args = parser.parse_args()
    if args.stage == "design":
        main(args.maxiter, args.rounds, args.max_eigenvalue, args.clearance, args.log)
    elif args.stage == "toy":
        toy_stage(args.maxiter, args.rounds, args.max_eigenvalue, args.clearance, args.log)
    summarise(args.log)
