"""Posterior sampling speed: the log-posterior warm against cold, 1 against 2 workers, and effective
samples per minute for a 5-parameter posterior.

Run ``.venv/bin/python benchmarks/sample_speed.py`` (``make bench`` runs it too). It writes
``benchmarks/results/sample_speed.json`` and prints a table. The walk: 10 simulated steps of
data/params/stable-toy.toml with a trailing-foot share of 0.1 and 0.002 rad of noise; the fit
frees foot radius, hip width, lateral and vertical mass offset and the share.

- ``log_posterior``: one evaluation at draws from the fit's covariance. ``warm`` is
  :class:`toywalk.sysid.likelihood.LogPosterior` (chord steps from the nearest solved gait with
  its map Jacobian held); ``newton`` is Newton from the same gait (derivatives at every
  iteration, the way before the chord steps); ``cold``
  is the naive way, ``find_gait`` from nothing, then the same residuals. Alternating draws, median.
- ``workers``: the same emcee run (1 ensemble, 20 walkers, 60 steps) with 1 and with 2 local
  processes; the time per log-posterior evaluation and the speed-up, start-up of the processes
  (spawn, imports, compiled functions loaded from the cache) included, and that start-up alone.
- ``effective_samples``: 2 ensembles on 2 workers; bulk ESS (ArviZ, across ensembles) of the
  worst-mixed parameter per minute of wall time, and whether 1000 effective samples take under
  10 minutes at that rate.
The machine may be shared: compare ratios within one run.
"""

from __future__ import annotations

import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json
from toywalk.model.gait import find_gait, solve_fixed_point
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.model.walker import Walker
from toywalk.sysid.fit import fit
from toywalk.sysid.sample import posterior_from_fit, sample

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "sample_speed.json"
FREE = ["foot_radius", "hip_width", "com_offset[1]", "com_offset[2]", "effects.impact_trailing_share"]


def _walk():
    truth = load_params(ROOT / "data" / "params" / "stable-toy.toml").replace(
        **{"effects.impact_trailing_share": 0.1})
    gait = find_gait(truth)
    traj = simulate(truth, gait.fixed_point, 10)
    rng = np.random.default_rng(0)
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right}
    signals = {k: v + rng.normal(0.0, 0.002, v.shape) for k, v in signals.items()}
    events = [{"time": 0.0, "foot": "L"}] + [{"time": e.time, "foot": e.foot} for e in traj.events]
    return truth, TrajectoryTable(traj.times, signals, traj.stance, events, {})


def bench_log_posterior(report, table, draws: int = 20) -> dict:
    post, estimates, cov = posterior_from_fit(report, table)
    rng = np.random.default_rng(1)
    thetas = rng.multivariate_normal(estimates, cov, size=draws)
    warm, newton, cold = [], [], []
    post(estimates)  # the first solve (from the fit's gait) fills the warm-start cache
    for theta in thetas:
        params = post.params.replace(**dict(zip(post.free, map(float, theta), strict=True)))
        walker = Walker(params, planar=post.planar, period=post.period)
        # Newton (derivatives at every iteration) from the nearest solved gait, as before the chord
        t = time.perf_counter()
        z_near, _ = post._start(theta)
        gait = solve_fixed_point(walker, z_near)
        c = -0.5 * post.chi2(gait, walker)
        newton.append(time.perf_counter() - t)
        t = time.perf_counter()
        a = post(theta)  # chord steps from the same gait, with its Jacobian
        warm.append(time.perf_counter() - t)
        t = time.perf_counter()
        gait = find_gait(params)
        b = -0.5 * post.chi2(gait, Walker(params, planar=gait.planar, period=gait.period))
        cold.append(time.perf_counter() - t)
        for other in (b, c):
            if not abs(a[0] - other) <= 1e-6 * max(1.0, abs(other)):
                raise RuntimeError(f"the log-posteriors differ: {a[0]} vs {other}")
    return {"draws": draws, "warm_median_s": float(np.median(warm)),
            "newton_median_s": float(np.median(newton)), "cold_median_s": float(np.median(cold)),
            "speedup_warm_vs_newton": float(np.median(newton) / np.median(warm)),
            "speedup_warm_vs_cold": float(np.median(cold) / np.median(warm))}


def bench_workers(report, table, folder: Path) -> dict:
    out = {}
    walkers, steps = 20, 60
    for k in (1, 2):
        t = time.perf_counter()
        sample(report, table, folder / f"workers{k}.h5", walkers=walkers, steps=steps, ensembles=1,
               workers=k, seed=2)
        elapsed = time.perf_counter() - t
        out[f"workers_{k}"] = {"time_s": elapsed, "per_evaluation_s": elapsed / (walkers * (steps + 1))}
    out["speedup_2_vs_1"] = out["workers_1"]["time_s"] / out["workers_2"]["time_s"]
    from toywalk.sysid.sample import worker_pool

    t = time.perf_counter()
    with worker_pool(2, None) as pool:
        pool.map(abs, [1, 2])  # the first task waits for both processes to start
    out["pool_start_s"] = time.perf_counter() - t
    return out


def bench_ess(report, table, folder: Path, steps: int = 250) -> dict:
    t = time.perf_counter()
    summary = sample(report, table, folder / "ess.h5", walkers=20, steps=steps, ensembles=2,
                     workers=2, seed=3).to_json()
    minutes = (time.perf_counter() - t) / 60
    ess = min(summary["ess_bulk"].values())
    return {"walkers": 20, "steps": steps, "ensembles": 2, "workers": 2, "minutes": minutes,
            "ess_bulk_worst": ess, "ess_per_minute": ess / minutes,
            "minutes_for_1000": 1000 / (ess / minutes),
            "aim_1000_in_10_minutes_met": bool(1000 / (ess / minutes) <= 10),
            "autocorrelation_time": summary["autocorrelation_time"], "rhat": summary["rhat"],
            "long_enough": summary["long_enough"]}


def main() -> dict:
    t0 = time.perf_counter()
    truth, table = _walk()
    start = truth.replace(**{n: truth.get(n) * 1.03 for n in FREE})
    result = fit(table, start, FREE)
    report = result.to_json()
    res = {"timestamp_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
           "cpu_count": os.cpu_count(), "free": FREE, "fit_status": result.status,
           "load_average_1min_start": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory() as tmp:
        res["log_posterior"] = bench_log_posterior(report, table)
        res["workers"] = bench_workers(report, table, Path(tmp))
        res["effective_samples"] = bench_ess(report, table, Path(tmp))
    res["total_run_time_s"] = time.perf_counter() - t0
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(RESULTS, res)
    lp, wk, es = res["log_posterior"], res["workers"], res["effective_samples"]
    print(f"log-posterior, warm {1e3 * lp['warm_median_s']:.1f} ms vs Newton from the same gait "
          f"{1e3 * lp['newton_median_s']:.1f} ms ({lp['speedup_warm_vs_newton']:.1f}x) vs cold "
          f"{1e3 * lp['cold_median_s']:.1f} ms ({lp['speedup_warm_vs_cold']:.1f}x)")
    print(f"workers: 1 -> {1e3 * wk['workers_1']['per_evaluation_s']:.1f} ms per evaluation, 2 -> "
          f"{1e3 * wk['workers_2']['per_evaluation_s']:.1f} ms: {wk['speedup_2_vs_1']:.2f}x "
          f"(starting 2 processes: {wk['pool_start_s']:.1f} s)")
    print(f"5-parameter posterior on 2 workers: {es['ess_per_minute']:.0f} effective samples per "
          f"minute (worst parameter); 1000 in {es['minutes_for_1000']:.1f} min")
    print(json.dumps({"rhat": es["rhat"], "tau": es["autocorrelation_time"]}))
    print(f"wrote {RESULTS.relative_to(ROOT)} in {res['total_run_time_s']:.0f} s")
    return res


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
