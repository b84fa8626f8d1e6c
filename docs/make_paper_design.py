"""The paper's toy by inverse design: is there a rigid, frictionless walker with the toy's build
that walks like the toy (Coleman & Ruina, PRL 80:3658, 1998), and is its gait stable? Writes
docs/paper_design.csv (a row a start), docs/paper_design.png and docs/paper_design.json (the
summary docs/paper_toy.md quotes).

**Constraints** (the paper's numbers, :data:`TARGETS`): stride time 0.47 +- 0.03 s (a stride is
two steps), stride 1.3 +- 0.3 cm, lean amplitude 4 +- 1.5 deg, steer amplitude at most 1.5 deg,
slope 4.5 +- 0.5 deg, total mass 120 +- 30 g; the walker within the box a Tinkertoy build allows
(:data:`BOX`, a reason per bound) and the paper's description of the build (:func:`build_margins`:
the legs' centres of mass low, about one leg length out, above the feet's centre of curvature,
just behind the leg axes, legs about normal to the ramp when standing); and unable to stand
(``can_stand``; ``static_margin`` > 0 as its cheap necessary condition inside the optimisers).

**Formulation**: least squares to the centres of the intervals, each residual scaled by its
half-width (``fit_gait_targets``, the box as bounds; slope and masses are bounds of the box), then
every interval and build relation checked: a design is *feasible* when every number lies in its
interval (|residual| <= 1), the build relations hold and it cannot stand. A fit that meets every
number but misses a build relation (or stands) is *repaired*: Nelder-Mead
(``minimise_max_eigenvalue`` with the smallest constraint margin, :func:`margin`, as its objective).
On the feasible set the step map's max |eigenvalue| is minimised (``minimise_max_eigenvalue``)
with that margin as its penalised constraint (*polished*; data/params/paper-toy.toml is the best).
When that gait is unstable, each screened, mirror-symmetric effect of the library is freed alone
within 20 times its typical magnitude (the physical range of docs/paper_toy.md's diagnosis): the
eigenvalue minimised keeping every constraint, and the effect stepped through its range with the
numbers free (``GaitEvaluator``: warm-started Newton, then continuation).

**Starts** (each a gait that the least squares starts from):

1. ``shipped``: every gait of the global search (``all_gaits``) of each shipped walker
   (data/params/*.toml but this search's own result), continued (``continue_gait``) into the box:
   its parameters clipped to the box, the ramp at 4.5 deg (else 4.9 or 4.1 deg: the Tinkertoy
   fit's gait sits on a fold at 4.5);
2. ``box``: Latin-hypercube designs over the box; the first ``--global-designs`` searched by
   ``all_gaits`` (its pitch-paced and rocking-paced starts) plus the :data:`TOY_PACED`
   rocking-paced starts at the toy's pace (steps of 0.2-0.27 s, stance angles covering 4-12 mm a
   step, leans of 0.05-0.11 rad), the others by Newton from the toy-paced starts alone;
3. every distinct gait found is fitted, the closest to the numbers first, until ``--budget``
   seconds of fitting are spent.

Run (19 min on one core of a shared 2-core machine with the defaults)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_paper_design.py [--designs 300] [--budget 300]

``--effects-only`` runs the effect stages again on data/params/paper-toy.toml (about a minute);
``--tally-only`` recounts the CSV into the JSON and redraws the figure.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import scipy.optimize
from toywalk.model import (
    EFFECTS,
    Walker,
    all_gaits,
    can_stand,
    load_params,
    save_params,
    solve_fixed_point,
    static_margin,
)
from toywalk.model.gait import GaitNotFound, continue_gait, find_gait
from toywalk.model.gait_search import SAME_GAIT
from toywalk.model.optimize import GaitEvaluator, fit_gait_targets, gait_features, minimise_max_eigenvalue
from toywalk.model.parameters import ParameterError

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DEG = math.pi / 180

#: The paper's numbers (Coleman & Ruina 1998; docs/model.md section 7) as (centre, half-width) of
#: the interval a design must meet. The steer's "no visible variation" is at most 1.5 deg.
TARGETS = {
    "stride_time": (0.47, 0.03),          # s, two steps
    "stride_length": (0.013, 0.003),      # m, advance per stride
    "lean_amplitude": (4.0 * DEG, 1.5 * DEG),
    "steer_amplitude": (0.0, 1.5 * DEG),
}
SLOPE = (4.5 * DEG, 0.5 * DEG)            # rad, the ramp: a bound of the box
TOTAL_MASS = (0.120, 0.030)               # kg: checked

#: The box a Tinkertoy build allows (SI units), with the reason for each bound.
BOX = {
    # Hip to foot bottom: a yellow spool (about 5 cm across), a light green rod and a hinge; no
    # rod of the set makes a leg shorter than 8 cm with a spool at its end, and none longer than
    # about 22 cm fits the paper's photograph of legs a few spools long.
    "leg_length": (0.08, 0.22),
    # The foot is the spool's rim: a Tinkertoy spool is about 5.4 cm across (2 1/8 in); 1.5-4 cm
    # allows for the plastic set's spool and the brass strip over the flat.
    "foot_radius": (0.015, 0.04),
    # The sideways radius of the rim under a 0.5 cm brass strip: from a rounded edge (2 mm) to
    # about the rim's width (2 cm); the model also needs it at most the fore-aft radius.
    "foot_lateral_radius": (0.002, 0.02),
    # Hip points = the two hinges' centres on the axle: a hinge about 1 cm thick plus three orange
    # washers between them; at most 4 cm.
    "hip_width": (0.01, 0.04),
    # One leg: a 50 g nut assembly plus spool, rods, hinge and tape (5-20 g).
    "leg_mass": (0.05, 0.07),
    # The red axle rod and its washers.
    "axle_mass": (0.002, 0.015),
    # "Just behind the leg axes": 0 to 2 cm back (the balance mass assembly tilted behind the leg).
    "com_offset[0]": (-0.02, 0.0),
    # "Laterally at a distance comparable to the leg length" (checked as d_y / l in 0.5-1.5,
    # build_margins): 6 to 25 cm absolute.
    "com_offset[1]": (0.06, 0.25),
    # "Low": below the hip by 4 cm (the shortest leg's half) to 20 cm (checked against the leg).
    "com_offset[2]": (-0.2, -0.04),
    # The leg's inertia about its centre of mass: the 5-20 g spool and rods a leg length from the
    # 50 g mass that sets the centre, m d^2 = 2e-5 .. 1e-3 kg m^2 (docs/make_tinkertoy.py's box).
    "inertia[0]": (2e-5, 1e-3),
    "inertia[1]": (2e-5, 1e-3),
    "inertia[2]": (2e-5, 1e-3),
    "slope": (SLOPE[0] - SLOPE[1], SLOPE[0] + SLOPE[1]),
}
FREE = list(BOX)
#: The build relations of :func:`build_margins`: d_y / l, and how far from normal to the ramp the
#: legs may stand (rad: "nominally-vertical legs ... approximately orthogonal to the ramp").
LATERAL_REACH = (0.5, 1.5)
STANDING_PITCH = 0.1
#: Rocking-paced starts at the toy's pace (gait_search's rocking starts use the leg's pendulum
#: period; the toy steps every 0.235 s whatever its legs): lean at heel strike (rad), step time
#: (s), and the step advance (m) the stance angle covers.
TOY_PACED = {"lean": (0.05, 0.08, 0.11), "step_time": (0.2, 0.235, 0.27), "advance": (0.004, 0.0065, 0.012)}
#: Ramps at which the shipped walkers' gaits are continued into the box, tried in turn (rad).
SHIPPED_SLOPES = (4.5 * DEG, 4.9 * DEG, 4.1 * DEG)
#: Effects freed one at a time on the best design, within [null, EFFECT_RANGE x typical].
EFFECT_RANGE = 20.0
COLUMNS = ["kind", "label", "converged", "fit_status", "stride_time", "stride_length",
           "lean_amplitude_deg", "steer_amplitude_deg", "slope_deg", "total_mass",
           *(f"z_{k}" for k in TARGETS), "numbers_met", "build_met", "worst_build", "feasible",
           "max_abs_eigenvalue", "can_stand", "start_stride_time", "start_stride_length",
           "start_lean_deg", *FREE, "seconds"]


def standing_pitch(params) -> float:
    """The stance pitch (rad, + hip ahead) at which the walker balances on both feet, legs
    parallel, in the ramp's pitching plane: the whole centre of mass over the contact point along
    gravity. Rolling on the fore-aft radius r moves the contact with the pitch; the centre of mass
    sits at (x_c, h) from the contact with the legs normal to the ramp."""
    m, mh, (dx, _, dz) = params.leg_mass, params.axle_mass, params.com_offset
    total = 2 * m + mh
    x_c = 2 * m * dx / total
    h = (2 * m * (params.leg_length + dz) + mh * params.leg_length) / total
    r, tan_a = params.foot_radius, math.tan(params.slope)

    def uphill_gap(theta):  # (x + z tan alpha) of the centre of mass from the contact
        x = x_c * math.cos(theta) + (h - r) * math.sin(theta)
        z = r + (h - r) * math.cos(theta) - x_c * math.sin(theta)
        return x + z * tan_a

    try:
        return float(scipy.optimize.brentq(uphill_gap, -1.2, 1.2))
    except ValueError:
        return math.nan


def build_margins(params) -> dict[str, float]:
    """The paper's description of the build as margins, each >= 0 when it holds (dimensionless):
    total mass within 120 +- 30 g; d_y / l within :data:`LATERAL_REACH`; the leg's centre of mass
    low (at most half a leg above the foot bottom) and above the feet's fore-aft centre of
    curvature; the standing pitch within :data:`STANDING_PITCH`; the static margin (the centre of
    mass above the feet's lateral centre of curvature, necessary for not standing) positive."""
    l, (_, dy, dz) = params.leg_length, params.com_offset
    height = l + dz
    reach = dy / l
    pitch = standing_pitch(params)
    return {
        "total_mass": 1 - abs(params.total_mass - TOTAL_MASS[0]) / TOTAL_MASS[1],
        "lateral_reach": min(reach - LATERAL_REACH[0], LATERAL_REACH[1] - reach),
        "com_low": (0.5 * l - height) / l,
        "com_above_feet": (height - params.foot_radius) / l,
        "standing_pitch": 1 - abs(pitch) / STANDING_PITCH if math.isfinite(pitch) else -1.0,
        "static_margin": static_margin(params) / l,
    }


def number_residuals(features: dict) -> dict[str, float]:
    """(value - centre) / half-width of every target: |z| <= 1 inside its interval."""
    return {k: (features[k] - c) / s for k, (c, s) in TARGETS.items()}


def margin(params, gait) -> float:
    """The smallest of every constraint's margin (>= 0: every number in its interval and the build
    relations held), scaled by the leg length as minimise_max_eigenvalue's constraints are (m)."""
    z = number_residuals(gait_features(gait))
    return params.leg_length * min(min(1 - abs(v) for v in z.values()), min(build_margins(params).values()))


def latin_hypercube(n: int, rng: np.random.Generator) -> np.ndarray:
    """n points in [0, 1]^len(FREE), one in each of n strata of every coordinate."""
    u = (rng.permuted(np.tile(np.arange(n), (len(FREE), 1)), axis=1).T + rng.random((n, len(FREE)))) / n
    return u


def into_box(params, u: np.ndarray | None = None):
    """``params`` with every box parameter set from ``u`` in [0, 1] (or, without it, clipped into
    the box); the lateral radius kept at most the fore-aft one."""
    values = {}
    for i, name in enumerate(FREE):
        lo, hi = BOX[name]
        values[name] = lo + u[i] * (hi - lo) if u is not None else min(hi, max(lo, params.get(name)))
    values["foot_lateral_radius"] = min(values["foot_lateral_radius"], values["foot_radius"])
    return params.replace(**values)


def toy_paced_starts(params) -> list[tuple[str, np.ndarray]]:
    """Rocking-paced starts at the toy's pace: stance angle a covering the advance in a step,
    covered in the step time, lean psi at heel strike turning back through zero over the step."""
    out = []
    for psi in TOY_PACED["lean"]:
        for step in TOY_PACED["step_time"]:
            for advance in TOY_PACED["advance"]:
                a = advance / (2 * params.leg_length)
                rate = 2 * a / step
                z = np.array([0.0, 0.0, psi, -2 * psi / step, -a, rate, a, rate * math.cos(2 * a)])
                out.append((f"toy-paced psi={psi:g} T={step:g} s dx={1e3 * advance:g} mm", z))
    return out


def row(kind, label, start, fit, seconds) -> dict:
    """A row of docs/paper_design.csv: the start's gait (None: no gait) and the design it led to
    (a fit, or a repair's result: anything with ``params``, ``gait`` and ``status``)."""
    out = {"kind": kind, "label": label, "converged": start is not None, "seconds": f"{seconds:.2f}"}
    if start is not None:
        out.update(start_stride_time=f"{start.stride_time:.5g}",
                   start_stride_length=f"{start.stride_length:.5g}",
                   start_lean_deg=f"{start.lean_amplitude / DEG:.4g}")
    if fit is None:
        return out
    p, g = fit.params, fit.gait
    z = number_residuals(gait_features(g))
    build = build_margins(p)
    worst = min(build, key=build.get)
    out.update(
        fit_status=fit.status, stride_time=f"{g.stride_time:.5g}",
        stride_length=f"{g.stride_length:.5g}", lean_amplitude_deg=f"{g.lean_amplitude / DEG:.4g}",
        steer_amplitude_deg=f"{g.steer_amplitude / DEG:.4g}",
        slope_deg=f"{p.slope / DEG:.4g}", total_mass=f"{p.total_mass:.4g}",
        **{f"z_{k}": f"{v:+.3f}" for k, v in z.items()},
        numbers_met=all(abs(v) <= 1 for v in z.values()), build_met=build[worst] >= 0,
        worst_build=f"{worst} {build[worst]:+.3f}", max_abs_eigenvalue=f"{g.max_abs_eigenvalue:.5g}",
        **{n: f"{p.get(n):.6g}" for n in FREE})
    return out


def shipped_starts(log) -> list:
    """Every shipped walker's gaits (global search) continued into the box at 4.5 deg."""
    out = []
    for path in sorted((ROOT / "data" / "params").glob("*.toml")):
        if path.stem == "paper-toy":  # this search's own result
            continue
        params = load_params(path)
        t0 = time.perf_counter()
        search = all_gaits(params)
        for k, found in enumerate(search.gaits):
            label = f"{path.stem} gait {k} ({found.how})"
            gait = None
            for slope in SHIPPED_SLOPES:  # the Tinkertoy fit's gait sits at a fold at 4.5 deg
                try:
                    gait = continue_gait(params, into_box(params).replace(slope=slope),
                                         found.gait.fixed_point)
                    break
                except (GaitNotFound, ParameterError):
                    continue
            out.append(("shipped", label, gait, time.perf_counter() - t0))
            log(f"{label}: " + (f"continued into the box at {gait.params.slope / DEG:.2f} deg"
                                if gait else "lost on the way into the box"))
    return out


def box_starts(n: int, n_global: int, seed: int, log) -> tuple[list, int]:
    """Latin-hypercube designs over the box: the first ``n_global`` searched by all_gaits (its
    built-in starts and the toy-paced ones), the others by Newton from the toy-paced starts only
    (the global search's planar branches cost 5-20 s a design)."""
    rng = np.random.default_rng(seed)
    base = load_params(ROOT / "data" / "params" / "tinkertoy.toml")
    out, newton = [], 0
    for i, u in enumerate(latin_hypercube(n, rng)):
        t0 = time.perf_counter()
        kind = "box (global search)" if i < n_global else "box (toy-paced)"
        try:
            params = into_box(base, u)
        except ParameterError:
            out.append((kind, f"design {i} (not a rigid body)", None, 0.0))
            continue
        if i < n_global:
            search = all_gaits(params, starts=toy_paced_starts(params))
            newton += search.starts
            found = [(f.how, f.gait) for f in search.gaits]
        else:
            found = []
            walker = Walker(params)
            for how, z in toy_paced_starts(params):
                newton += 1
                try:
                    gait = solve_fixed_point(walker, z)
                except GaitNotFound:
                    continue
                if not any(_same(gait, other) for _, other in found):
                    found.append((how, gait))
        if not found:
            out.append((kind, f"design {i}", None, time.perf_counter() - t0))
        for k, (how, gait) in enumerate(found):
            out.append((kind, f"design {i} gait {k} ({how})", gait, time.perf_counter() - t0))
        log(f"design {i} ({kind}): {len(found)} gaits, {time.perf_counter() - t0:.1f} s")
    return out, newton


def _same(a, b) -> bool:
    """One gait twice: fixed points within SAME_GAIT (rad, rad/s) and step times alike."""
    return bool(np.max(np.abs(a.fixed_point - b.fixed_point)) <= SAME_GAIT
                and abs(a.step_time - b.step_time) <= SAME_GAIT * a.step_time)


def fit(gait, max_nfev: int):
    """Least squares to the intervals' centres from ``gait``, the box as bounds. A start that
    continuation left a rounding error outside the box is first solved again inside it."""
    inside = into_box(gait.params)
    if inside != gait.params:
        gait = solve_fixed_point(Walker(inside), gait.fixed_point)
    return fit_gait_targets(gait, FREE, BOX, TARGETS, max_nfev=max_nfev, continuation=False)


def main(args) -> None:
    t_start = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t_start:6.0f} s] {msg}", flush=True)

    starts = shipped_starts(log)
    box, newton = box_starts(args.designs, args.global_designs, args.seed, log)
    starts += box
    log(f"{len(starts)} starts, {sum(s[2] is not None for s in starts)} with a gait "
        f"({newton} Newton starts over {args.designs} box designs)")
    rows, fits = [], []
    fit_start = time.perf_counter()
    # The closest starts first, so that the budget goes where the numbers are nearest.
    def distance(start):
        gait = start[2]
        if gait is None:
            return math.inf
        return sum(v * v for v in number_residuals(gait_features(gait)).values())

    for kind, label, gait, seconds in sorted(starts, key=distance):
        if gait is None or time.perf_counter() - fit_start > args.budget:
            rows.append(row(kind, label, gait, None, seconds))
            continue
        t0 = time.perf_counter()
        try:
            result = fit(gait, args.nfev)
        except (GaitNotFound, ParameterError, ValueError) as err:
            log(f"{label}: fit failed ({err})")
            result = None
        rows.append(row(kind, label, gait, result, seconds + time.perf_counter() - t0))
        if result is not None:
            fits.append((rows[-1], result))
            z = number_residuals(result.features)
            log(f"{label}: {', '.join(f'{k} {v:+.2f}' for k, v in z.items())}, max|eig| "
                f"{result.gait.max_abs_eigenvalue:.3f}, least build margin {rows[-1]['worst_build']}")
    for r, result in fits:
        r["can_stand"] = can_stand(result.params).can_stand
        r["feasible"] = margin(result.params, result.gait) >= 0 and not r["can_stand"]
    repaired = repair(fits, args, log)
    fits += repaired
    rows += [r for r, _ in repaired]
    feasible = [result for r, result in fits if r["feasible"]]
    log(f"{len(fits)} fits and repairs, {len(feasible)} feasible")
    summary = {"starts": len(starts), "with_gait": sum(s[2] is not None for s in starts),
               "newton_starts": newton, "designs": args.designs, "fits": len(fits),
               "feasible": len(feasible)}
    best = None
    for result in sorted(feasible, key=lambda f: f.gait.max_abs_eigenvalue)[: args.polish]:
        opt = minimise_max_eigenvalue(result.gait, FREE, BOX, constraint=margin, maxiter=args.maxiter,
                                      continuation=False)
        stand = can_stand(opt.params).can_stand
        rows.append(polished_row(opt.gait, stand))
        log(f"polished: max|eig| {opt.start_value:.4f} -> {opt.value:.4f}, can stand {stand}")
        if not stand and (best is None or opt.value < best.value):
            best = opt
    closest = min(fits, key=lambda f: f[1].cost) if fits else None
    summary["closest"] = describe(closest[1]) if closest else None
    built = [f for f in fits if min(build_margins(f[1].params).values()) >= 0]
    summary["closest_built"] = describe(min(built, key=lambda f: f[1].cost)[1]) if built else None
    summary["best"] = describe_gait(best.gait) if best else None
    # Effects: on the most stable feasible design, keeping every constraint; else on the closest
    # design that meets the build relations, with no constraint (the numbers are missed anyway).
    if best is not None and best.gait.max_abs_eigenvalue >= 1:
        summary["effects_on"] = "best"
        summary["effects"] = effect_stage(best.gait, margin, args.effect_iter, log)
        summary["effect_scan"] = effect_scan(best.gait, args.scan_points, log)
    elif best is None and built:
        summary["effects_on"] = "closest_built"
        closest_built = min(built, key=lambda f: f[1].cost)[1]
        summary["effects"] = effect_stage(closest_built.gait, None, args.effect_iter, log)
    summary["seconds"] = time.perf_counter() - t_start
    write(rows, summary)
    figure(HERE / "paper_design.csv")
    write_design(summary)
    summary["tally"] = tally(HERE / "paper_design.csv")
    (HERE / "paper_design.json").write_text(json.dumps(summary, indent=1) + "\n")
    log("written docs/paper_design.csv, docs/paper_design.json, docs/paper_design.png")


@dataclasses.dataclass
class Repair:
    """A design moved into the build relations: what :func:`repair` returns in a fit's place."""

    params: object
    gait: object
    status: str
    cost: float


def repair(fits: list, args, log) -> list:
    """The fits that meet every number but miss a build relation (or stand), the nearest first
    (at most ``args.repair``): the smallest constraint margin maximised by Nelder-Mead
    (``minimise_max_eigenvalue`` with that as its objective) from each. Returns (row, Repair)
    pairs for the designs it reached."""
    near = [(r, f) for r, f in fits if not r["feasible"] and r["numbers_met"]]
    near.sort(key=lambda rf: -margin(rf[1].params, rf[1].gait))
    out = []
    for r, result in near[: args.repair]:
        t0 = time.perf_counter()
        opt = minimise_max_eigenvalue(result.gait, FREE, BOX, maxiter=args.repair_iter, continuation=False,
                                      objective=lambda g: -margin(g.params, g) / g.params.leg_length)
        gait = opt.gait
        fixed = Repair(gait.params, gait, "repaired", sum(v * v for v in number_residuals(
            gait_features(gait)).values()) / 2)
        new = row("repair", f"repair of {r['label']}", result.gait, fixed, time.perf_counter() - t0)
        new["can_stand"] = can_stand(gait.params).can_stand
        new["feasible"] = margin(gait.params, gait) >= 0 and not new["can_stand"]
        out.append((new, fixed))
        log(f"repair of {r['label']}: least margin {margin(result.params, result.gait):+.4f} -> "
            f"{margin(gait.params, gait):+.4f} m, {new['worst_build']}, max|eig| "
            f"{gait.max_abs_eigenvalue:.3f}, can stand {new['can_stand']}, "
            f"{time.perf_counter() - t0:.0f} s")
    return out


def effect_ranges():
    """The effects the effect stages free, each ``(name, effect, key, high)``: the screened,
    mirror-symmetric effects of the library, freed within [null, high], high EFFECT_RANGE x typical
    (within the effect's bounds)."""
    for name, effect in EFFECTS.items():
        if effect.port_only or not effect.screened or effect.breaks_symmetry:
            continue
        high = min(effect.bounds[1], effect.null + EFFECT_RANGE * effect.typical)
        yield name, effect, f"effects.{name}", high


def effect_stage(gait, constraint, maxiter: int, log) -> list[dict]:
    """Each screened, mirror-symmetric effect of the library freed alone on ``gait``'s walker,
    within [null, EFFECT_RANGE x typical]: the least max |eigenvalue| it reaches (Nelder-Mead,
    the gait followed by the evaluator's warm starts and continuation), ``constraint`` kept."""
    out = []
    for name, effect, key, high in effect_ranges():
        t0 = time.perf_counter()
        opt = minimise_max_eigenvalue(gait, [key], {key: (effect.null, high)}, constraint=constraint,
                                      maxiter=maxiter, initial_step=0.05)
        value = opt.params.effects.get(name, effect.null)
        z = number_residuals(gait_features(opt.gait))
        out.append({"effect": name, "range": [effect.null, high], "unit": effect.unit,
                    "value": value, "max_abs_eigenvalue": opt.value, "start": opt.start_value,
                    "z": z, "evaluations": opt.evaluations, "failures": opt.failures,
                    "fixed_point": [float(v) for v in opt.gait.fixed_point]})
        log(f"{key} in [{effect.null:g}, {high:g}] {effect.unit}: max|eig| {opt.start_value:.4f} -> "
            f"{opt.value:.4f} at {value:.4g} ({opt.evaluations} gaits, {opt.failures} lost, "
            f"{time.perf_counter() - t0:.0f} s)")
    return out


def effect_scan(gait, points: int, log) -> list[dict]:
    """Each effect of :func:`effect_stage` stepped from its null value to EFFECT_RANGE x typical in
    ``points`` strengths, the gait followed by warm-started Newton and continuation
    (``GaitEvaluator``): max |eigenvalue| and the numbers (in half-widths) along the way, to the
    last strength with a gait."""
    out = []
    for name, effect, key, high in effect_ranges():
        evaluator = GaitEvaluator(gait.params, [key], gait)
        steps = []
        for value in np.linspace(effect.null, high, points):
            g = evaluator([value])
            if g is None:
                break
            steps.append({"value": float(value), "max_abs_eigenvalue": g.max_abs_eigenvalue,
                          "z": number_residuals(gait_features(g))})
        least = min(steps, key=lambda s: s["max_abs_eigenvalue"])
        out.append({"effect": name, "unit": effect.unit, "range": [effect.null, high], "steps": steps,
                    "reached": steps[-1]["value"], "least": least})
        log(f"{key} scanned to {steps[-1]['value']:.4g} of {high:g} {effect.unit}: least max|eig| "
            f"{least['max_abs_eigenvalue']:.4f} at {least['value']:.4g}, numbers there "
            + ", ".join(f"{k} {v:+.2f}" for k, v in least["z"].items()))
    return out


def polished_row(gait, stands: bool) -> dict:
    """The CSV row of a feasible design after the eigenvalue minimisation."""
    cost = sum(v * v for v in number_residuals(gait_features(gait)).values()) / 2
    result = Repair(gait.params, gait, "polished", cost)
    out = row("polished", "polish of a feasible design", None, result, 0.0)
    out.update(converged=True, can_stand=stands, feasible=margin(gait.params, gait) >= 0 and not stands)
    return out


def effects_only(args) -> None:
    """The effect stages again on data/params/paper-toy.toml's gait, into docs/paper_design.json."""
    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.0f} s] {msg}", flush=True)

    gait = find_gait(load_params(ROOT / "data" / "params" / "paper-toy.toml"))
    # Its row in docs/paper_design.csv (runs before the polished rows were written lack it).
    with open(HERE / "paper_design.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["kind"] != "polished"]
    rows.append(polished_row(gait, can_stand(gait.params).can_stand))
    with open(HERE / "paper_design.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    figure(HERE / "paper_design.csv")
    path = HERE / "paper_design.json"
    summary = json.loads(path.read_text())
    summary["effects_on"] = "best"
    summary["effects"] = effect_stage(gait, margin, args.effect_iter, log)
    summary["effect_scan"] = effect_scan(gait, args.scan_points, log)
    path.write_text(json.dumps(summary, indent=1) + "\n")


def describe(result) -> dict:
    out = describe_gait(result.gait)
    out["cost"] = result.cost
    return out


def describe_gait(gait) -> dict:
    p = gait.params
    return {"numbers": gait_features(gait), "z": number_residuals(gait_features(gait)),
            "build": build_margins(p), "standing_pitch": standing_pitch(p),
            "params": {n: p.get(n) for n in FREE}, "max_abs_eigenvalue": gait.max_abs_eigenvalue,
            "fixed_point": [float(v) for v in gait.fixed_point]}


def write(rows, summary) -> None:
    with open(HERE / "paper_design.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    (HERE / "paper_design.json").write_text(json.dumps(summary, indent=1) + "\n")


def tally(path: Path) -> dict:
    """From docs/paper_design.csv: of the fits and repairs, how many meet each number's interval,
    each pair of them, all of them, the build relations, and the least |z| (half-widths) each number
    reached."""
    with open(path) as f:
        fitted = [r for r in csv.DictReader(f) if r["fit_status"] and r["kind"] != "polished"]
    z = {k: np.array([float(r[f"z_{k}"]) for r in fitted]) for k in TARGETS}
    met = {k: np.abs(v) <= 1 for k, v in z.items()}
    built = np.array([r["build_met"] == "True" for r in fitted])
    keys = list(TARGETS)
    missed = [r["worst_build"].split()[0] for r in fitted if r["build_met"] == "False"]
    return {
        "fits": len(fitted),
        "meets": {k: int(v.sum()) for k, v in met.items()},
        "meets_with_build": {k: int((v & built).sum()) for k, v in met.items()},
        "pairs": {f"{a}+{b}": int((met[a] & met[b]).sum()) for i, a in enumerate(keys) for b in keys[i + 1:]},
        "all_numbers": int(np.logical_and.reduce(list(met.values())).sum()),
        "build": int(built.sum()),
        "least_abs_z": {k: float(np.min(np.abs(v))) for k, v in z.items()},
        "worst_build": {name: missed.count(name) for name in sorted(set(missed))},
    }


def write_design(summary: dict) -> None:
    """The most stable feasible design to data/params/paper-toy.toml, or, when there is none, the
    closest design that meets the build relations to docs/paper_design_closest.toml (the closest
    of all when none does); each with its fixed point as ``[gait] start``."""
    if summary["best"] is not None:
        design, path, what = summary["best"], ROOT / "data" / "params" / "paper-toy.toml", (
            "The most stable walker of docs/make_paper_design.py that meets the paper's numbers")
    else:
        key = "closest_built" if summary["closest_built"] else "closest"
        design, path, what = summary[key], HERE / "paper_design_closest.toml", (
            "The closest design of docs/make_paper_design.py to the paper's numbers "
            + ("that meets the build relations" if key == "closest_built" else "(build relations missed)"))
    base = load_params(ROOT / "data" / "params" / "tinkertoy.toml")
    params = dataclasses.replace(base.replace(**design["params"]), gait_start=tuple(design["fixed_point"]))
    z = ", ".join(f"{k} {v:+.2f}" for k, v in design["z"].items())
    save_params(params, path, header=f"{what} (docs/paper_toy.md).\nNumbers in half-widths of the "
                f"paper's intervals: {z}; max |eigenvalue| {design['max_abs_eigenvalue']:.4g}.\n"
                "[gait] start is its fixed point.")


def figure(path: Path) -> None:
    """docs/paper_design.png from docs/paper_design.csv: every fit and repair, stride time against
    stride and lean against max |eigenvalue|, the paper's intervals shaded, feasible designs
    starred."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(path) as f:
        fitted = [r for r in csv.DictReader(f) if r["fit_status"]]
    colours = {"box": "tab:blue", "shipped": "tab:orange", "repair": "tab:green", "polished": "tab:red"}
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for r in fitted:
        colour = colours[r["kind"].split()[0]]
        marker, size = ("*", 12) if r["feasible"] == "True" else ("o", 4)
        axes[0].plot(float(r["stride_time"]), 100 * float(r["stride_length"]), marker, ms=size,
                     color=colour, alpha=0.7)
        axes[1].plot(float(r["lean_amplitude_deg"]), float(r["max_abs_eigenvalue"]), marker, ms=size,
                     color=colour, alpha=0.7)
    (c, s), (cl, sl) = TARGETS["stride_time"], TARGETS["stride_length"]
    axes[0].add_patch(plt.Rectangle((c - s, 100 * (cl - sl)), 2 * s, 200 * sl, fill=False, color="k"))
    axes[0].set_xlabel("stride time (s)")
    axes[0].set_ylabel("stride (cm)")
    axes[0].set_xscale("log")
    axes[0].set_yscale("log")
    c, s = TARGETS["lean_amplitude"]
    axes[1].axvspan((c - s) / DEG, (c + s) / DEG, color="0.9")
    axes[1].axhline(1.0, color="0.5", lw=0.8)
    axes[1].set_xlabel("lean amplitude (deg)")
    axes[1].set_ylabel("step-map max |eigenvalue|")
    axes[1].set_yscale("log")
    fig.suptitle(f"{len(fitted)} designs (blue: fits from box designs, orange: from shipped walkers, "
                 "green: repairs, red: polished; star: feasible; box and band: the paper's intervals)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(HERE / "paper_design.png", dpi=120)


def retally() -> None:
    """Rewrite the tally of docs/paper_design.json and the figure from docs/paper_design.csv (no
    search)."""
    path = HERE / "paper_design.json"
    summary = json.loads(path.read_text())
    summary["tally"] = tally(HERE / "paper_design.csv")
    path.write_text(json.dumps(summary, indent=1) + "\n")
    figure(HERE / "paper_design.csv")
    print(json.dumps(summary["tally"], indent=1))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", type=int, default=300, help="Latin-hypercube box designs")
    parser.add_argument("--global-designs", type=int, default=8,
                        help="box designs searched by all_gaits (the others: toy-paced starts only)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--budget", type=float, default=300.0,
                        help="s of fitting after which no fit starts")
    parser.add_argument("--nfev", type=int, default=60, help="least-squares evaluations a fit")
    parser.add_argument("--maxiter", type=int, default=300, help="Nelder-Mead iterations a polish")
    parser.add_argument("--effect-iter", type=int, default=30, help="Nelder-Mead iterations an effect")
    parser.add_argument("--repair", type=int, default=4, help="near-feasible fits repaired")
    parser.add_argument("--repair-iter", type=int, default=100, help="Nelder-Mead iterations a repair")
    parser.add_argument("--polish", type=int, default=3, help="feasible designs polished")
    parser.add_argument("--scan-points", type=int, default=41, help="strengths an effect scan")
    parser.add_argument("--effects-only", action="store_true",
                        help="only the effect stages on data/params/paper-toy.toml's gait")
    parser.add_argument("--tally-only", action="store_true",
                        help="only recount docs/paper_design.csv into docs/paper_design.json and redraw "
                             "the figure")
    arguments = parser.parse_args()
    if arguments.tally_only:
        retally()
    elif arguments.effects_only:
        effects_only(arguments)
    else:
        main(arguments)
