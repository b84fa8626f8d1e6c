"""The basin in MuJoCo against the model's: hand launches, kicks and recovery curves (docs/gaits.md
section 8).

    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_basin_mujoco.py   # about 3.5 minutes
    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_basin_mujoco.py --curves
    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_basin_mujoco.py --plot-only
    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_basin_mujoco.py --long       # 2 minutes
    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_basin_mujoco.py \
        --launches docs/launch_converging.toml                                      # about 5 minutes

**Hand launches** (``--launches P.toml``): the walker's hand launch at 0.5 to 2.5 times its lean
amplitude in the model (``hand_launch``, up to 200 steps) and in MuJoCo (200 heel strikes) at the
six contact settings below; docs/launch_mujoco_P.csv, one row per tip and engine setting
(``steps``, ``outcome``, ``scuffs``, ``bounces``, ``last10_step_time_ms``).

**Long walks** (``--long``): robust-toy, launch-toy and launch-clear-toy from their gaits' fixed
points, 300 heel strikes at 1, 2 and 4 ms (friction 1): does MuJoCo's soft contact keep the gait?
docs/basin_mujoco_long.csv (steps, outcome, and the step times' mean and standard deviation over
the first and the last 40 steps).

**Starts** (the default). For data/params/robust-toy.toml (the shipped robust walker, section 7),
data/params/launch-toy.toml and data/params/launch-clear-toy.toml (the walkers started by hand),
docs/robust_best.toml (the rigid design search's best, which robust-toy was made from) and
data/params/clearing-toy.toml, from three kinds of start, each walked at most 60 steps:

- the gait's fixed point (the reference: does the engine walk the gait at all?);
- the hand launch at 1.5 and 2.5 times the gait's lean amplitude (``launch_state``: at rest, legs
  parallel and normal to the ramp, tipped onto the left foot, the right leg 1e-5 rad back);
- the fixed point with its four rates kicked by 0.02 rad/s with random signs, seeds 0-7
  (``np.random.default_rng(seed)``, as docs/make_basin.py kicks them; seeds 2 and 3 draw the
  same signs, and so do 4 and 7, so there are six distinct kicks).

The model walks with the step map (``Walker.step``) until a step fails (fell, no heel strike) or
its swing foot scuffs (a failure for these two gaits, which clear, as in ``recovers``). MuJoCo
walks with ``walk_in_mujoco`` at six contact settings (time constant, friction): the checked
build (1 ms, 2) and (1 ms, 1), (2 ms, 1), (2 ms, 0.6), (4 ms, 2), (4 ms, 0.6) from issue 44's
range (1 to 4 ms, friction 0.6 to 2), 1e-4 s steps, giving up after twice the gait's time for 60
steps. Writes docs/basin_mujoco.csv, one row per walker, engine setting and start: ``steps``
walked (MuJoCo's alternating heel strikes), ``outcome`` (model: ``walked``, ``fell``,
``no_heel_strike``, ``scuffed``; MuJoCo: ``walked``, ``fell`` (a hip down to half the leg length),
``same foot twice`` (a foot's second heel strike running, too late to be a bounce; ``..., walked
on`` when 60 heel strikes came all the same), ``timed out``), ``heel_strikes`` (all of them,
alternating or not), ``scuffs``, ``bounces`` (MuJoCo: the landing foot leaving the ramp and
landing again, ``MujocoWalk.bounces``), ``last_strike_s`` (the last alternating heel strike's
time, 0 for the start's), ``end_time_s`` (model: its last heel strike; MuJoCo: the end of the
walk, the fall's time), ``end_distance`` (model: from the fixed point at its last heel
strike, state_scale units), ``last10_step_time_ms`` (MuJoCo: mean of its last ten steps), and
the seconds each walk took.

**Recovery curves** (``--curves``; about 20 minutes). For robust-toy, pushes of 9 sizes (0.005
to 0.135 state_scale units) along 20 random directions (``random_directions``, seed 0; the same
at every size), each start ``perturbed`` onto the post-strike surface (section 5) and given to
both engines: the model's step map and ``walk_in_mujoco`` at (1 ms, friction 1), (2 ms, 0.6) and
(4 ms, 0.6).
The criterion is the same in both: 60 alternating heel strikes without a fall (the model's scuff
a fall, as above). For the model it also says whether the walk ``recovers`` onto the gait
(section 5's rule: within 1e-4 and 100 times closer, at most 600 steps). Writes
docs/basin_mujoco_curves.csv (one row per size, direction and engine setting: ``walked``,
``steps``, ``outcome``, ``recovered`` (model), ``bounces``, ``scuffs``, ``seconds``) and
docs/basin_mujoco_curves.png (the fraction that walks against size, binomial standard errors,
the series drawn 2 % apart along the size axis so that equal ones stay visible);
``--plot-only`` redraws it from the CSV.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, find_gait, load_params
from toywalk.model.basin import hand_launch, launch_state, perturbed, random_directions, recovers
from toywalk.model.gait import state_scale
from toywalk.model.mujoco_check import walk_in_mujoco
from toywalk.model.walker import StepFailure

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_basin import _write  # noqa: E402  (the same CSV writer as the model's basin tables)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
WALKERS = {"robust-toy": ROOT / "data" / "params" / "robust-toy.toml",
           "launch-toy": ROOT / "data" / "params" / "launch-toy.toml",
           "launch-clear-toy": ROOT / "data" / "params" / "launch-clear-toy.toml",
           "robust_best": HERE / "robust_best.toml",
           "clearing-toy": ROOT / "data" / "params" / "clearing-toy.toml"}
CAP = 60  # steps walked at most
LAUNCH_MULTIPLES = (1.5, 2.5)  # tip angles, times the gait's lean amplitude (issue 44)
KICK = 0.02  # rad/s on each of the four rates, random signs (issue 44)
SEEDS = range(8)
# MuJoCo's contacts: (time constant (s), friction coefficient); the first is the checked build, the
# others span issue 44's range (1 to 4 ms, friction 0.6 to 2).
SETTINGS = ((1e-3, 2.0), (1e-3, 1.0), (2e-3, 1.0), (2e-3, 0.6), (4e-3, 2.0), (4e-3, 0.6))
TIMESTEP = 1e-4  # s, walk_in_mujoco's default
# Recovery curves (--curves): robust-toy, push sizes (state_scale units) from where every random
# direction walks in the model (0.005; its median random radius is 0.032, docs/gaits.md section
# 7) to where none does (0.135), 20 directions, three contact settings from issue 44's range
# (the softest, 4 ms and friction 0.6, its far corner).
CURVE_WALKER = "robust-toy"
CURVE_SIZES = (0.005, 0.008, 0.012, 0.018, 0.027, 0.04, 0.06, 0.09, 0.135)
CURVE_DIRECTIONS = 20
CURVE_SEED = 0
CURVE_SETTINGS = ((1e-3, 1.0), (2e-3, 0.6), (4e-3, 0.6))
# Hand launches (--launches P.toml): tips as multiples of the lean amplitude, around the range in
# which docs/launch_converging.toml's converges in the model (1-1.2) and out to the 2.5;
# heel strikes walked at most (a converging launch takes 100-150 steps in the model).
LAUNCH_TIPS = (0.5, 0.8, 1.0, 1.1, 1.2, 1.5, 2.0, 2.5)
LAUNCH_CAP = 200
# Long walks (--long): the shipped walkers of issue 44 from their fixed points, this many heel strikes,
# at three contact times with friction 1; the spread of the step times over the first and the last
# LONG_WINDOW steps says whether the walk settles (a gait stable in that engine) or drifts.
LONG_WALKERS = ("robust-toy", "launch-toy", "launch-clear-toy")
LONG_CAP = 300
LONG_SETTINGS = ((1e-3, 1.0), (2e-3, 1.0), (4e-3, 1.0))
LONG_WINDOW = 40


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


def _mujoco_walk(gait, z0: np.ndarray, contact_time: float, friction: float, cap: int = CAP):
    """(MujocoWalk, how it ended) of at most ``cap`` steps from ``z0``."""
    walk = walk_in_mujoco(gait.params, z0, steps=cap, timestep=TIMESTEP, friction=friction,
                          contact_time=contact_time, max_time=2.0 * cap * gait.step_time)
    if walk.status == "completed":
        outcome = "walked"
    elif walk.message.startswith("no "):
        outcome = "timed out"
    elif "same foot" in walk.message and len(walk.feet) >= cap:
        outcome = "same foot twice, walked on"
    elif "same foot" in walk.message:
        outcome = "same foot twice"
    else:
        outcome = "fell"
    return walk, outcome


def measure() -> list[dict]:
    rows = []
    for name, path in WALKERS.items():
        gait = find_gait(load_params(path))
        walker = Walker(gait.params)
        stable = bool(np.max(np.abs(gait.eigenvalues)) < 1.0)
        print(f"{name}: max |eigenvalue| {np.max(np.abs(gait.eigenvalues)):.4f} (stable: {stable}), "
              f"step time {gait.step_time:.4f} s, lean amplitude {math.degrees(gait.lean_amplitude):.3f} deg",
              flush=True)
        for label, tip, z0 in _starts(gait):
            t = time.perf_counter()
            steps, reason, scuffs, distance, elapsed = _model_walk(gait, walker, z0)
            rows.append(dict(walker=name, engine="model", contact_time_ms="", friction="", start=label,
                             tip_deg=tip, steps=steps, outcome=reason, heel_strikes=steps, scuffs=scuffs,
                             bounces=0, last_strike_s=elapsed, end_time_s=elapsed, end_distance=distance,
                             last10_step_time_ms=math.nan, seconds=time.perf_counter() - t))
            for contact_time, friction in SETTINGS:
                t = time.perf_counter()
                walk, outcome = _mujoco_walk(gait, z0, contact_time, friction)
                last = walk.step_times[-10:]
                last_ms = round(1e3 * float(np.mean(last)), 3) if len(last) else math.nan
                rows.append(dict(walker=name, engine="mujoco", contact_time_ms=1e3 * contact_time,
                                 friction=friction, start=label, tip_deg=tip, steps=walk.steps,
                                 outcome=outcome, heel_strikes=len(walk.feet), scuffs=walk.scuffs,
                                 bounces=walk.bounces,
                                 last_strike_s=float(walk.strikes[walk.steps - 1, 0]) if walk.steps else 0.0,
                                 end_time_s=walk.duration, end_distance=math.nan,
                                 last10_step_time_ms=last_ms, seconds=time.perf_counter() - t))
            print(f"  {label:18s} model {steps:2d} {reason:15s} | MuJoCo "
                  + "  ".join(f"{r['steps']:2d} {r['outcome']}" for r in rows[-len(SETTINGS):]), flush=True)
    return rows


def measure_long() -> list[dict]:
    """Each of :data:`LONG_WALKERS` walked from its fixed point for :data:`LONG_CAP` heel strikes
    at :data:`LONG_SETTINGS`: the steps, how it ended, and the standard deviation of the step times
    over the first and the last :data:`LONG_WINDOW` steps (ms; the model's step time beside)."""
    rows = []
    for name in LONG_WALKERS:
        gait = find_gait(load_params(WALKERS[name]))
        for contact_time, friction in LONG_SETTINGS:
            t = time.perf_counter()
            walk, outcome = _mujoco_walk(gait, gait.fixed_point, contact_time, friction, cap=LONG_CAP)
            times = np.asarray(walk.step_times)
            rows.append(dict(walker=name, contact_time_ms=1e3 * contact_time, friction=friction,
                             steps=walk.steps, outcome=outcome, model_step_ms=round(1e3 * gait.step_time, 3),
                             first_mean_ms=round(1e3 * float(np.mean(times[:LONG_WINDOW])), 3),
                             first_std_ms=round(1e3 * float(np.std(times[:LONG_WINDOW])), 3),
                             last_mean_ms=round(1e3 * float(np.mean(times[-LONG_WINDOW:])), 3),
                             last_std_ms=round(1e3 * float(np.std(times[-LONG_WINDOW:])), 3),
                             seconds=time.perf_counter() - t))
            r = rows[-1]
            print(f"{name} ({r['contact_time_ms']:g} ms, {friction:g}): {walk.steps} steps, {outcome}; step "
                  f"time spread {r['first_std_ms']} -> {r['last_std_ms']} ms", flush=True)
    return rows


def measure_launches(path: Path) -> list[dict]:
    """The hand launch of the walker in ``path`` at :data:`LAUNCH_TIPS` times its lean amplitude:
    ``hand_launch`` in the model (up to :data:`LAUNCH_CAP` steps; converged or not) and
    ``walk_in_mujoco`` from the same ``launch_state`` (:data:`LAUNCH_CAP` heel strikes) at every
    contact setting of :data:`SETTINGS`."""
    gait = find_gait(load_params(path))
    tips = [m * gait.lean_amplitude for m in LAUNCH_TIPS]
    model = hand_launch(gait.params, tips, gait=gait, steps=LAUNCH_CAP).results[0]
    print(f"{path.name}: max |eigenvalue| {gait.max_abs_eigenvalue:.4f}, step {1e3 * gait.step_time:.1f} ms, "
          f"lean amplitude {math.degrees(gait.lean_amplitude):.3f} deg", flush=True)
    rows = []
    for m, tip, launch in zip(LAUNCH_TIPS, tips, model, strict=True):
        rows.append(dict(walker=path.stem, multiple=m, tip_deg=math.degrees(tip), engine="model",
                         contact_time_ms="", friction="", steps=launch.steps, outcome=launch.reason,
                         scuffs=launch.scuffs, bounces=0, last10_step_time_ms=math.nan))
        for contact_time, friction in SETTINGS:
            walk, outcome = _mujoco_walk(gait, launch_state(tip), contact_time, friction, LAUNCH_CAP)
            last = walk.step_times[-10:]
            last_ms = round(1e3 * float(np.mean(last)), 3) if len(last) else math.nan
            rows.append(dict(walker=path.stem, multiple=m, tip_deg=math.degrees(tip), engine="mujoco",
                             contact_time_ms=1e3 * contact_time, friction=friction, steps=walk.steps,
                             outcome=outcome, scuffs=walk.scuffs, bounces=walk.bounces,
                             last10_step_time_ms=last_ms))
        print(f"  {m:g} x lean: model {launch.steps} {launch.reason} | MuJoCo "
              + "  ".join(f"{r['steps']} {r['outcome']}" for r in rows[-len(SETTINGS):]), flush=True)
    return rows


def curves_path(walker: str, suffix: str) -> Path:
    """docs/basin_mujoco_curves.SUFFIX for :data:`CURVE_WALKER`, docs/basin_mujoco_curves_WALKER.SUFFIX
    for another (``--walker``)."""
    return HERE / (f"basin_mujoco_curves.{suffix}" if walker == CURVE_WALKER
                   else f"basin_mujoco_curves_{walker}.{suffix}")


def measure_curves(name: str = CURVE_WALKER) -> list[dict]:
    """One row per push size, direction and engine setting (the module's docstring), for the
    walker :data:`WALKERS` calls ``name``."""
    gait = find_gait(load_params(WALKERS[name]))
    params, walker = gait.params, Walker(gait.params)
    directions = random_directions(params, gait, CURVE_DIRECTIONS, CURVE_SEED)
    rows = []
    start = time.perf_counter()
    for size in CURVE_SIZES:
        for k, direction in enumerate(directions):
            z0 = perturbed(params, gait, direction, size, walker)
            t = time.perf_counter()
            steps, reason, scuffs, _, _ = _model_walk(gait, walker, z0)
            recovery = recovers(params, z0, gait, walker=walker)
            rows.append(dict(walker=name, size=size, direction=k, engine="model", contact_time_ms="",
                             friction="", walked=steps == CAP, steps=steps, outcome=reason,
                             recovered=recovery.recovered, bounces=0, scuffs=scuffs,
                             seconds=round(time.perf_counter() - t, 4)))
            for contact_time, friction in CURVE_SETTINGS:
                t = time.perf_counter()
                walk, outcome = _mujoco_walk(gait, z0, contact_time, friction)
                rows.append(dict(walker=name, size=size, direction=k, engine="mujoco",
                                 contact_time_ms=1e3 * contact_time, friction=friction,
                                 walked=walk.status == "completed", steps=walk.steps, outcome=outcome,
                                 recovered="", bounces=walk.bounces, scuffs=walk.scuffs,
                                 seconds=round(time.perf_counter() - t, 4)))
        at = [r for r in rows if r["size"] == size]
        counts = [sum(r["walked"] for r in at if r["engine"] == "model"),
                  sum(r["recovered"] for r in at if r["engine"] == "model")]
        counts += [sum(r["walked"] for r in at if r["contact_time_ms"] == 1e3 * c and r["friction"] == f)
                   for c, f in CURVE_SETTINGS]
        print(f"size {size:.4g}: walked 60 of {CURVE_DIRECTIONS}: model {counts[0]} (recovered {counts[1]}), "
              + ", ".join(f"MuJoCo {1e3 * c:g} ms, friction {f:g}: {n}"
                          for (c, f), n in zip(CURVE_SETTINGS, counts[2:], strict=True))
              + f"  [{time.perf_counter() - start:.0f} s]", flush=True)
    return rows


def _read_curves(walker: str = CURVE_WALKER) -> list[dict]:
    with open(curves_path(walker, "csv"), newline="") as f:
        return list(csv.DictReader(f))


def curve_summary(rows: list[dict]) -> list[tuple[str, np.ndarray, np.ndarray, int]]:
    """(label, sizes, walking counts, directions) for the model's 60-step walks, its recoveries
    and each MuJoCo setting; ``rows`` as read from the CSV (strings)."""
    sizes = np.array(sorted({float(r["size"]) for r in rows}))
    series = [("model: walks 60 steps", lambda r: r["engine"] == "model", "walked"),
              ("model: recovers onto the gait", lambda r: r["engine"] == "model", "recovered")]
    settings = sorted({(float(r["contact_time_ms"]), float(r["friction"]))
                       for r in rows if r["engine"] == "mujoco"})
    for c, f in settings:
        series.append((f"MuJoCo {c:g} ms, friction {f:g}: walks 60 steps",
                       lambda r, c=c, f=f: r["engine"] == "mujoco" and float(r["contact_time_ms"]) == c
                       and float(r["friction"]) == f, "walked"))
    out = []
    for label, pick, column in series:
        chosen = [r for r in rows if pick(r)]
        n = len(chosen) // len(sizes)
        counts = np.array([sum(r[column] == "True" for r in chosen if float(r["size"]) == s) for s in sizes])
        out.append((label, sizes, counts, n))
    return out


def plot_curves(walker: str = CURVE_WALKER) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.3))
    series = curve_summary(_read_curves(walker))
    styles = ("o-", "s--", "^-", "v-", "d-", "x-")
    for k, ((label, sizes, counts, n), style) in enumerate(zip(series, styles, strict=False)):
        p = counts / n
        apart = 1.02 ** (k - (len(series) - 1) / 2)  # equal series side by side, not on top
        ax.errorbar(sizes * apart, p, yerr=np.sqrt(p * (1 - p) / n), fmt=style, capsize=3, label=label,
                    mfc="none" if "--" in style else None)
    ax.set_xscale("log")
    ax.set_xlabel("push size (state_scale units)")
    ax.set_ylabel(f"fraction of {n} random directions")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title(f"{walker}: pushes just after a heel strike, model and MuJoCo")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(curves_path(walker, "png"), dpi=110)
    print(f"wrote {curves_path(walker, 'png').relative_to(ROOT)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--curves", action="store_true", help="the recovery curves instead of the starts")
    parser.add_argument("--plot-only", action="store_true", help="redraw the curves' figure from the CSV")
    parser.add_argument("--walker", choices=sorted(WALKERS), default=CURVE_WALKER,
                        help=f"with --curves, --plot-only: whose curves (default {CURVE_WALKER}; "
                             "another's go to docs/basin_mujoco_curves_WALKER.csv/png)")
    parser.add_argument("--long", action="store_true",
                        help=f"walk {', '.join(LONG_WALKERS)} {LONG_CAP} steps from their gaits "
                             "(docs/basin_mujoco_long.csv)")
    parser.add_argument("--launches", type=Path, metavar="P.toml",
                        help="this walker's hand launches in both engines instead (docs/launch_mujoco_P.csv)")
    args = parser.parse_args()
    start = time.perf_counter()
    if args.long:
        rows = measure_long()
        _write(HERE / "basin_mujoco_long.csv", rows)
        print(f"wrote docs/basin_mujoco_long.csv ({len(rows)} rows) in {time.perf_counter() - start:.0f} s")
        return
    if args.launches:
        rows = measure_launches(args.launches)
        out = HERE / f"launch_mujoco_{args.launches.stem}.csv"
        _write(out, rows)
        print(f"wrote {out.relative_to(ROOT)} ({len(rows)} rows) in {time.perf_counter() - start:.0f} s")
        return
    if args.plot_only:
        plot_curves(args.walker)
        return
    if args.curves:
        rows = measure_curves(args.walker)
        out = curves_path(args.walker, "csv")
        _write(out, rows)
        print(f"wrote {out.relative_to(ROOT)} ({len(rows)} rows) in {time.perf_counter() - start:.0f} s")
        plot_curves(args.walker)
        return
    rows = measure()
    _write(HERE / "basin_mujoco.csv", rows)
    print(f"wrote docs/basin_mujoco.csv ({len(rows)} rows) in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
