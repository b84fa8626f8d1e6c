"""The transient fit of a long walk: the model's heel-strike times held as unknowns (the clock,
``measurement.Timing.clock_links``) against the naive way, each sample read through every step
duration before it, in one run.

Run: ``.venv/bin/python benchmarks/transient_speed.py`` (about 3 minutes). Writes
``benchmarks/results/transient_speed.json`` and prints a table. The walks: 10 to 60 simulated
steps of data/params/stable-toy.toml with a trailing-foot share of 0.1 and 0.002 rad of noise (the
walk of ``diagnose_speed.py``), fitted by the base model that lacks the share (foot radius and
lateral offset free), aligned on the measured strikes (the periodicity test's transient fit). For
each: the seconds IPOPT's solver took to build (``casadi.nlpsol``), the solve, the whole fit, the
Lagrangian Hessian's non-zeros, and the naive way's estimates against the clock's. The naive way
runs up to 20 steps only: at 60 its solver was still being built after 9.5 minutes.
"""

from __future__ import annotations

import datetime
import os
import sys
import time
from pathlib import Path

import casadi as ca
from toywalk.model.files import atomic_write_json
from toywalk.model.parameters import load_params
from toywalk.sysid import fit as fitting
from toywalk.sysid import problem as fit_problem

sys.path.insert(0, str(Path(__file__).parent))
import diagnose_speed  # noqa: E402  (the same walk)

HERE = Path(__file__).parent
FREE = ["foot_radius", "com_offset[1]"]
STEPS = (10, 20, 40, 60)
NAIVE_STEPS = (10, 20)


def one_fit(table, params) -> dict:
    """The transient fit of ``table`` timed: its IPOPT solver's build, the whole fit, the result."""
    builds = []  # (seconds, solver) of each IPOPT solver the fit builds
    nlpsol = ca.nlpsol

    def timed(name, *args, **kwargs):
        clock = time.perf_counter()
        solver = nlpsol(name, *args, **kwargs)
        if name == "fit":
            builds.append((time.perf_counter() - clock, solver))
        return solver

    ca.nlpsol = timed
    try:
        clock = time.perf_counter()
        result = fitting.fit(table, params, FREE, model="transient", strikes="measured",
                             check_jacobian=False)
        total = time.perf_counter() - clock
    finally:
        ca.nlpsol = nlpsol
    hessian = builds[-1][1].get_function("nlp_hess_l")
    return {"build_s": sum(s for s, _ in builds), "fit_s": total, "status": result.status,
            "iterations": result.iterations, "hessian_nonzeros": hessian.sparsity_out(0).nnz(),
            "chi2": result.chi2, "estimates": {n: result.estimates[n] for n in FREE}}


def main() -> None:
    toy = load_params(HERE.parent / "data" / "params" / "stable-toy.toml")
    truth = toy.replace(**{"effects.impact_trailing_share": 0.1})
    rows = []
    print(f"{'steps':>5s} {'way':<6s} {'build s':>8s} {'fit s':>7s} {'Hessian nnz':>12s} {'chi2':>10s}",
          flush=True)
    for steps in STEPS:
        diagnose_speed.STEPS = steps
        table = diagnose_speed.walk(truth)
        row = {"steps": steps}
        for way in ("clock", "naive") if steps in NAIVE_STEPS else ("clock",):
            fit_problem._CLOCK_LIFTED = way == "clock"
            try:
                got = one_fit(table, toy)
            finally:
                fit_problem._CLOCK_LIFTED = True
            row[way] = got
            print(f"{steps:5d} {way:<6s} {got['build_s']:8.2f} {got['fit_s']:7.1f} "
                  f"{got['hessian_nonzeros']:12d} {got['chi2']:10.2f}", flush=True)
        if "naive" in row:
            a, b = row["clock"], row["naive"]
            row["build_ratio"] = b["build_s"] / a["build_s"]
            row["fit_ratio"] = b["fit_s"] / a["fit_s"]
            row["estimates_max_rel_diff"] = max(abs(a["estimates"][n] / b["estimates"][n] - 1) for n in FREE)
            row["chi2_rel_diff"] = abs(a["chi2"] / b["chi2"] - 1)
        rows.append(row)
    data = {"benchmark": "transient_speed", "date": datetime.datetime.now().isoformat(timespec="seconds"),
            "cpus": os.cpu_count(), "python": sys.version.split()[0], "free": FREE, "rows": rows}
    out = HERE / "results" / "transient_speed.json"
    atomic_write_json(out, data)
    for row in rows:
        if "naive" in row:
            print(f"{row['steps']} steps: build {row['build_ratio']:.1f}x, fit {row['fit_ratio']:.1f}x "
                  f"faster with the clock; estimates agree to {row['estimates_max_rel_diff']:.1e}")
    print(f"-> {out}")


if __name__ == "__main__":
    main()
