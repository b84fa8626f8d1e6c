"""PySINDy beside toywalk's search for the missing force, on the same walks (benchmarks/README.md,
"Beside PySINDy").

Run ``OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/sindy_comparison.py`` (about 13 minutes,
one process; ``make bench`` runs it so).
It writes ``benchmarks/results/sindy_comparison.json`` and prints a table.

The walks are those of docs/make_missing_force_validation.py: the stable toy and the clearing toy
with a hinge spring hidden (``tau = -k (theta_sw - theta_st)``, k = 5e-3 N m/rad, which no library
effect is), 12 steps from the gait's fixed point, 2 mrad of white noise, seeds 0 and 1. The
observations' complete steps (:func:`toywalk.sysid.measurement.observations`: 11 of the 12, about
17 samples each) are the stance phases of both methods.

- toywalk: ``diagnose(table, walker, free=["foot_radius", "com_offset[1]"], tie_design=False)``, as
  the validation runs it; the terms its search selects, with their intervals, and its held-out
  chi-square (two folds of alternate strides, :func:`toywalk.sysid.heldout.strides`). The two fold
  fits of the selected model and of the base are then repeated (the search keeps their chi-square,
  not their residuals), and their angle residuals on the held-out steps give an RMS in degrees,
  against the measured angles and against the noise-free walk (the same walk simulated without
  the noise: ``gait_walk`` draws the noise after the simulation). The repeat's chi-square is
  recorded beside the search's, to show it is the same computation.
- PySINDy, as a user would: each stance phase a trajectory in the stance/swing description (lean
  and steer mirrored on right-stance steps, the stance leg's pitch and the swing leg's, as
  ``sysid/residuals.py``'s ``_components``), the state the four angles and their rates from
  ``ps.SmoothedFiniteDifference`` (its defaults: Savitzky-Golay window 11, order 3), a
  ``ps.PolynomialLibrary`` of the eight, ``ps.STLSQ``, derivatives again by smoothed finite
  differences. Held out: the same folds of alternate strides, the model fitted on one fold's
  phases, each phase of the other simulated (``model.simulate``) from its measured angles and
  their smoothed rates at its first sample. A simulation that leaves five times the data's range
  in any state is stopped and counted as diverged (:func:`_diverged`); the RMS is over the phases
  that did not. Sweep: degree 1 and 2 at thresholds 0.001, 0.01, 0.1, degree 3 at 0.001 (degree 3
  has 165 candidate terms an equation against about 100 samples a fold: the regression is
  underdetermined, and its simulations take 0.8-1.6 s a step); a threshold of 1 or more would
  remove the kinematic rows' coefficient 1 (angle' = rate). The same sweep on the noise-free walk
  (one per walker: the seeds differ only in the noise) is PySINDy's ceiling here.
- Terms: each PySINDy model fitted on all 11 phases, and on the same walk without the spring
  (the control, same seed); the coefficients of theta_st and theta_sw in the two pitch
  accelerations, their change from the control, and the change the spring makes in the model's
  own equations (:func:`spring_in_accelerations`: the right-hand side with and without it, along
  the noise-free walk, per radian of hip angle).

Wall time of each side is recorded (``seconds``); the machine may be shared.

Measured (2026-11-28, 12 min 45 s; benchmarks/README.md, "Beside PySINDy"): toywalk selects the
hinge's angle form alone on all four walks, its interval holding 5e-3, held-out RMS 0.113-0.117
deg against the measured angles (the noise 0.115) and 0.005-0.012 against the noise-free walk,
65-114 s a walk; PySINDy's simulations of held-out steps diverge on 4 to all 11 of 11 steps in
every setting, at best 1.95 deg RMS over 7 steps (stable toy) or 0.22-0.42 deg over 1 or 2
(clearing toy), 50-76 s a walk, and no coefficient of its equations reads as the spring.
"""

from __future__ import annotations

import datetime
import math
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json

HERE = Path(__file__).parent
ROOT = HERE.parent
WALKERS = ("stable-toy", "clearing-toy")
SEEDS = (0, 1)
#: The hidden spring (N m/rad; docs/make_missing_force_validation.py): 8 % of the stable toy's
#: swing-leg gravity stiffness (model/effects/hip.py).
STIFFNESS = 5e-3
STEPS = 12
NOISE = 0.002
FREE = ["foot_radius", "com_offset[1]"]
#: PySINDy's sweep: (library degree, STLSQ threshold).
SWEEP = ((1, 0.001), (1, 0.01), (1, 0.1), (2, 0.001), (2, 0.01), (2, 0.1), (3, 0.001))
#: A simulated phase is stopped as diverged when a state leaves this many times the largest
#: magnitude that state takes in the noise-free walk.
DIVERGED = 5.0
#: ``model.simulate``'s integrator: LSODA as its default, at a tolerance far below the noise (its
#: default 1e-12 only makes the diverging simulations slower).
INTEGRATOR = {"method": "LSODA", "rtol": 1e-6, "atol": 1e-8}
NAMES = ["lean", "steer", "theta_st", "theta_sw"]
STATE = NAMES + [f"{n}_dot" for n in NAMES]


def walks(walker_name: str, seed: int) -> dict:
    """The measured walk, the same walk without noise, and the control without the spring."""
    from toywalk.model.parameters import load_params
    from toywalk.model.simulate import gait_walk

    walker = load_params(ROOT / "data" / "params" / f"{walker_name}.toml")
    hidden = walker.replace(**{"effects.hinge_stiffness": STIFFNESS})
    return {"walker": walker, "hidden": hidden,
            "table": gait_walk(hidden, STEPS, noise=NOISE, seed=seed),
            "truth": gait_walk(hidden, STEPS, noise=0.0, seed=seed),
            "control": gait_walk(walker, STEPS, noise=NOISE, seed=seed)}


def stance_phases(table, obs) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each complete step of ``obs`` as (times (n,), angles (n, 4)) in the stance/swing
    description: lean and steer mirrored on right-stance steps, the stance leg's pitch, the swing
    leg's."""
    out = []
    for k in range(obs.n_steps):
        rows = (table.time >= obs.step_start[k]) & (table.time < obs.step_end[k])
        side = 1.0 if obs.stance[k] == "L" else -1.0
        legs = ("pitch_left", "pitch_right")
        stance, swing = legs if obs.stance[k] == "L" else legs[::-1]
        s = table.signals
        out.append((table.time[rows], np.column_stack([side * s["lean"][rows], side * s["steer"][rows],
                                                       s[stance][rows], s[swing][rows]])))
    return out


def _state(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The angles and their rates by PySINDy's smoothed finite differences, shape (n, 8)."""
    import pysindy as ps

    return np.hstack([q, ps.SmoothedFiniteDifference()(q, t)])


def _sindy(phases: list, degree: int, threshold: float):
    """A PySINDy model of the phases (a list of trajectories), as a user fits it."""
    import pysindy as ps

    model = ps.SINDy(optimizer=ps.STLSQ(threshold=threshold),
                     feature_library=ps.PolynomialLibrary(degree=degree),
                     differentiation_method=ps.SmoothedFiniteDifference())
    with warnings.catch_warnings():  # STLSQ warns where a threshold removes every term
        warnings.simplefilter("ignore")
        model.fit([_state(t, q) for t, q in phases], t=[t for t, _ in phases], feature_names=STATE)
    return model


def _diverged(bound: np.ndarray):
    """A terminal event of ``solve_ivp``: a state beyond ``bound`` (8,)."""
    def event(_t, x):
        return 1.0 - float(np.max(np.abs(x) / bound))
    event.terminal = True
    return event


def sindy_held_out(phases: list, truth: list, folds: np.ndarray, degree: int, threshold: float,
                   bound: np.ndarray) -> dict:
    """Fit on one fold's phases, simulate the other's from their first sample, both ways round:
    RMS (deg) of the angles against the measured and the noise-free ones over the phases that
    did not diverge, and how many did."""
    clock = time.perf_counter()
    squares = {"measured": 0.0, "truth": 0.0}
    n, diverged, terms = 0, 0, []
    for fold in (0, 1):
        model = _sindy([p for p, f in zip(phases, folds, strict=True) if f != fold], degree, threshold)
        terms.append(int(np.count_nonzero(model.coefficients())))
        for (t, q), (_, q_true), f in zip(phases, truth, folds, strict=True):
            if f != fold:
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sim = model.simulate(_state(t, q)[0], t,
                                     integrator_kws={**INTEGRATOR, "events": _diverged(bound)})
            if sim.shape[0] != len(t) or not np.all(np.isfinite(sim)):
                diverged += 1
                continue
            squares["measured"] += float(np.sum((sim[:, :4] - q) ** 2))
            squares["truth"] += float(np.sum((sim[:, :4] - q_true) ** 2))
            n += q.size
    rms = {k: math.degrees(math.sqrt(v / n)) if n else math.nan for k, v in squares.items()}
    return {"degree": degree, "threshold": threshold, "phases": len(phases), "diverged": diverged,
            "terms_by_fold": terms, "rms_deg": rms, "samples": n, "seconds": time.perf_counter() - clock}


def _pitch_terms(model) -> dict:
    """The coefficients of theta_st and theta_sw in the two pitch accelerations, and each
    equation's count of terms."""
    names = model.get_feature_names()
    coef = model.coefficients()
    out = {}
    for row, target in ((6, "theta_st_ddot"), (7, "theta_sw_ddot")):
        out[target] = {"theta_st": float(coef[row, names.index("theta_st")]),
                       "theta_sw": float(coef[row, names.index("theta_sw")]),
                       "terms": int(np.count_nonzero(coef[row]))}
    out["kinematic_rows_identity"] = bool(all(
        abs(coef[k, names.index(f"{NAMES[k]}_dot")] - 1.0) < 0.1
        and np.count_nonzero(coef[k]) == 1 for k in range(4)))
    return out


def spring_in_accelerations(params, stiffness: float) -> dict:
    """What the hinge spring adds to the pitch accelerations in the model's own equations, per
    radian of hip angle (1/s^2): the right-hand side with and without it at every sample of the
    noise-free walk with a hip angle over 0.02 rad, the difference over the hip angle (median and
    range). A polynomial model's coefficients of theta_sw and theta_st in an acceleration would
    change by +c and -c."""
    from toywalk.model.gait import find_gait
    from toywalk.model.simulate import simulate
    from toywalk.model.walker import Walker

    hidden = params.replace(**{"effects.hinge_stiffness": stiffness})
    gait = find_gait(hidden)
    traj = simulate(hidden, gait.fixed_point, STEPS, planar=gait.planar)
    with_spring, without = Walker(hidden), Walker(params)
    per_rad = []
    for z, stance in zip(traj.states, traj.stance, strict=True):
        side = 1 if stance == "L" else -1
        mirrored = z.copy()
        mirrored[:4] *= side  # steer, lean and their rates in the stance-left description
        hip = mirrored[6] - mirrored[4]
        if abs(hip) < 0.02:
            continue
        x = with_spring.full_state(mirrored)
        delta = with_spring.rhs(x, side)[4:8] - without.rhs(x, side)[4:8]  # steer, lean, theta_st, theta_sw
        per_rad.append(delta[2:] / hip)
    per_rad = np.array(per_rad)
    return {f"{name}_ddot": {"median": float(np.median(per_rad[:, i])), "min": float(per_rad[:, i].min()),
                             "max": float(per_rad[:, i].max())}
            for i, name in enumerate(("theta_st", "theta_sw"))} | {"samples": len(per_rad)}


def toywalk_side(data: dict) -> dict:
    """toywalk's diagnosis of the walk, its search's terms and held-out chi-square, and the
    repeated fold fits' held-out RMS (deg) against the measured and the noise-free angles."""
    from toywalk.sysid.discrepancy import diagnose
    from toywalk.sysid.heldout import held_out_fits, held_out_score, held_out_tasks, strides
    from toywalk.sysid.measurement import observations

    table, truth = data["table"], data["truth"]
    clock = time.perf_counter()
    d = diagnose(table, data["walker"], free=FREE, tie_design=False)
    seconds = time.perf_counter() - clock
    found = d.missing_force
    out = {"verdict": d.verdict, "cause": d.cause, "seconds": seconds,
           "seconds_by_stage": {k: float(v) for k, v in d.seconds.items() if isinstance(v, (int, float))},
           "terms": [], "stop": found.stop if found else "not searched", "gain": found.gain if found else {}}
    if found:
        out["terms"] = [{k: t[k] for k in ("parameter", "port", "form", "coefficient", "interval")}
                        for t in found.terms]
    obs = observations(table)
    rows = np.searchsorted(table.time, obs.time)
    if not np.allclose(table.time[rows], obs.time, rtol=0, atol=1e-12):
        raise RuntimeError("observation times are not the table's sample times")
    columns = ["lean", "steer", "pitch_left", "pitch_right"]
    true_value = np.array([truth.signals[columns[s]][r] for s, r in zip(obs.signal, rows, strict=True)])
    folds = strides(obs.n_steps)
    noise = dict(d.base.noise_sd)
    selected = found.fit if found and found.fit is not None else None
    models = {"base": (d.base, FREE)}
    if selected is not None:
        models["selected"] = (selected, FREE + [t["parameter"] for t in found.terms])
    options = dict((selected or d.base).options)
    out["held_out"] = {}
    for name, (result, free) in models.items():
        lap = time.perf_counter()
        fits = held_out_fits(held_out_tasks(table, result.params, free, noise, result, **options))
        score = held_out_score(table, fits, noise)
        squares, n = {"measured": 0.0, "truth": 0.0}, 0
        for fold, f in zip((0, 1), fits, strict=True):
            if isinstance(f, str) or not f.success:
                continue
            held = np.isin(obs.step, np.flatnonzero(folds == fold))
            model_value = obs.value[held] + f.residuals[held]
            squares["measured"] += float(np.sum(f.residuals[held] ** 2))
            squares["truth"] += float(np.sum((model_value - true_value[held]) ** 2))
            n += int(held.sum())
        out["held_out"][name] = {
            "chi2": score["chi2"], "success": score["success"], "samples": n,
            "rms_deg": {k: math.degrees(math.sqrt(v / n)) if n else math.nan for k, v in squares.items()},
            "seconds": time.perf_counter() - lap}
    return out


def sindy_side(data: dict, clean_sweep: dict | None) -> dict:
    """PySINDy's sweep on the walk (held-out prediction; terms on the whole walk and on the
    control), and on the noise-free walk unless ``clean_sweep`` already holds it."""
    from toywalk.sysid.heldout import strides
    from toywalk.sysid.measurement import observations

    clock = time.perf_counter()
    obs = observations(data["table"])
    phases = stance_phases(data["table"], obs)
    truth = stance_phases(data["truth"], obs)
    control = stance_phases(data["control"], observations(data["control"]))
    folds = strides(obs.n_steps)
    bound = DIVERGED * np.abs(np.vstack([_state(t, q) for t, q in truth])).max(axis=0)
    sweep = []
    for degree, threshold in SWEEP:
        row = sindy_held_out(phases, truth, folds, degree, threshold, bound)
        row["walk"] = _pitch_terms(_sindy(phases, degree, threshold))
        row["control"] = _pitch_terms(_sindy(control, degree, threshold))
        sweep.append(row)
        print(f"    PySINDy degree {degree} threshold {threshold:g}: {row['diverged']}/{row['phases']} "
              f"diverged, held-out RMS {row['rms_deg']['measured']:.3f} deg ({row['seconds']:.1f} s)",
              flush=True)
    seconds = time.perf_counter() - clock
    if clean_sweep is None:
        lap = time.perf_counter()
        clean_sweep = {"rows": [sindy_held_out(truth, truth, folds, d, th, bound) for d, th in SWEEP]}
        clean_sweep["seconds"] = time.perf_counter() - lap
    return {"sweep": sweep, "seconds": seconds, "noise_free": clean_sweep,
            "samples_per_phase": [len(t) for t, _ in phases]}


def main() -> None:
    import pysindy

    started = time.perf_counter()
    runs, clean, springs = [], {}, {}
    for walker_name in WALKERS:
        for seed in SEEDS:
            print(f"{walker_name}, seed {seed}", flush=True)
            data = walks(walker_name, seed)
            if walker_name not in springs:
                springs[walker_name] = spring_in_accelerations(data["walker"], STIFFNESS)
            sindy = sindy_side(data, clean.get(walker_name))
            clean[walker_name] = sindy["noise_free"]
            toy = toywalk_side(data)
            runs.append({"walker": walker_name, "seed": seed, "toywalk": toy, "pysindy": sindy})
            held = toy["held_out"].get("selected", toy["held_out"]["base"])
            print(f"  toywalk: {', '.join(t['parameter'] for t in toy['terms']) or 'no term'} "
                  f"({toy['stop']}); held-out RMS {held['rms_deg']['measured']:.3f} deg measured, "
                  f"{held['rms_deg']['truth']:.3f} deg truth; {toy['seconds']:.1f} s", flush=True)
    data = {"benchmark": "sindy_comparison", "date": datetime.datetime.now().isoformat(timespec="seconds"),
            "cpus": os.cpu_count(), "python": sys.version.split()[0], "pysindy": pysindy.__version__,
            "load_average": os.getloadavg(), "walkers": list(WALKERS), "seeds": list(SEEDS),
            "hinge_stiffness": STIFFNESS, "steps": STEPS, "noise_rad": NOISE, "free": FREE,
            "sweep": [list(s) for s in SWEEP], "diverged_factor": DIVERGED, "integrator": INTEGRATOR,
            "spring_in_accelerations": springs, "runs": runs,
            "total_run_time_s": time.perf_counter() - started}
    out = HERE / "results" / "sindy_comparison.json"
    atomic_write_json(out, data)
    print(table(data))
    print(f"-> {out}")


def table(data: dict) -> str:
    """The measured comparison, one line a walk and method."""
    lines = [f"{'walk':<18s} {'method':<28s} {'terms':<34s} {'held-out RMS (deg) meas/truth':>30s} "
             f"{'diverged':>9s} {'s':>7s}"]
    for run in data["runs"]:
        walk = f"{run['walker']} {run['seed']}"
        toy = run["toywalk"]
        terms = ", ".join(f"{t['parameter'].split('.')[-1]} {t['coefficient']:.4g}"
                          for t in toy["terms"]) or "none"
        for name, held in toy["held_out"].items():
            label = "toywalk " + ("(selected)" if name == "selected" else "(base)")
            seconds = f"{toy['seconds']:7.1f}" if name == "selected" else ""
            lines.append(f"{walk:<18s} {label:<28s} {terms if name == 'selected' else '':<34s} "
                         f"{held['rms_deg']['measured']:>14.3f} /{held['rms_deg']['truth']:>7.3f}        "
                         f"{'':>9s} {seconds:>7s}")
        for row in run["pysindy"]["sweep"]:
            label = f"PySINDy deg {row['degree']} thr {row['threshold']:g}"
            pitch = row["walk"]["theta_sw_ddot"]
            terms = f"{sum(row['terms_by_fold']) // 2} terms; sw'': {pitch['theta_sw']:+.3g} th_sw"
            lines.append(f"{walk:<18s} {label:<28s} {terms:<34s} {row['rms_deg']['measured']:>14.3f} /"
                         f"{row['rms_deg']['truth']:>7.3f}        {row['diverged']:>3d}/{row['phases']:<5d}"
                         f"{row['seconds']:>7.1f}")
    done = set()
    for run in data["runs"]:  # PySINDy on the noise-free walk, once a walker
        if run["walker"] in done:
            continue
        done.add(run["walker"])
        for row in run["pysindy"]["noise_free"]["rows"]:
            label = f"PySINDy deg {row['degree']} thr {row['threshold']:g}"
            lines.append(f"{run['walker'] + ' no noise':<18s} {label:<28s} {'':<34s} "
                         f"{row['rms_deg']['measured']:>14.3f} /{row['rms_deg']['truth']:>7.3f}        "
                         f"{row['diverged']:>3d}/{row['phases']:<5d}{row['seconds']:>7.1f}")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
