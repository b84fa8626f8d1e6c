"""How often the diagnosis from summary statistics (toywalk.sysid.summary) names the wrong cause,
measured.

The stable toy's four numbers (stride time, stride length, lean and steer amplitudes) with one
candidate hidden in them at its typical magnitude (the library's ``typical``, a few SDs of the
numbers or more), Gaussian noise of their SDs and the slope measured with its SD (the SDs of
tests/sysid/test_summary.py and docs/make_summary_null.py), analysed with the base model and the
same three candidates, one seed at a time. Counts, per hidden effect, how often the analysis
names it, names another, says `unexplained` or `adequate`. Writes
docs/summary_wrong_cause.csv and prints the rates with binomial 95 % intervals.

Run: ``TOYWALK_CACHE=/tmp/twcache .venv/bin/python docs/make_summary_wrong_cause.py [N]`` (N
seeds per hidden effect, default 30; 2 processes).
"""

import csv
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from make_summary_null import CANDIDATES, PARAMS, SD, SLOPE_SD  # the same toy, numbers and SDs
from scipy import stats
from toywalk.model import find_gait, load_params
from toywalk.model.effects import EFFECTS
from toywalk.model.gait import solve_fixed_point
from toywalk.model.optimize import gait_features
from toywalk.model.walker import Walker
from toywalk.sysid.summary import SummaryData, diagnose_summary

HERE = Path(__file__).resolve().parent

_state = {}


def _setup():
    gait = find_gait(load_params(PARAMS))
    truths = {}
    for name in CANDIDATES:
        value = EFFECTS[name].typical
        params = gait.params.replace(**{f"effects.{name}": value})
        hidden = solve_fixed_point(Walker(params), gait.fixed_point)
        truths[name] = (value, gait_features(hidden))
    _state.update(gait=gait, truths=truths)


def _case(job):
    name, seed = job
    if not _state:
        _setup()
    gait, (value, feats) = _state["gait"], _state["truths"][name]
    rng = np.random.default_rng(seed)
    targets = {k: (float(feats[k] + rng.normal() * s), s) for k, s in SD.items()}
    slope = float(gait.params.slope + rng.normal() * SLOPE_SD)
    data = SummaryData(targets, {"slope": (slope, SLOPE_SD)})
    d = diagnose_summary(gait.params, data, effects=CANDIDATES, parameters=[], gait=gait)
    key = f"effects.{name}"
    held = ""
    if d.cause == key:
        low, high = d.fits[key].interval[key]
        held = bool(low <= value <= high)
    outcome = ("adequate" if d.verdict == "adequate" else "named" if d.cause == key
               else "unexplained" if d.cause == "unexplained" else "wrong")
    return {"hidden": name, "truth": value, "seed": seed, "outcome": outcome, "verdict": d.verdict,
            "cause": d.cause, "interval_holds_truth": held, "base_chi2": d.base.chi2,
            "seconds": d.seconds["total"]}


def main(n: int) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    jobs = [(name, seed) for name in CANDIDATES for seed in range(n)]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(_case, jobs))
    with open(HERE / "summary_wrong_cause.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    for name in CANDIDATES:
        mine = [r for r in rows if r["hidden"] == name]
        counts = {o: sum(r["outcome"] == o for r in mine) for o in ("named", "wrong", "unexplained",
                                                                     "adequate")}
        wrong = counts["wrong"]
        low, high = stats.binomtest(wrong, len(mine)).proportion_ci(0.95)
        held = [r["interval_holds_truth"] for r in mine if r["outcome"] == "named"]
        print(f"{name} = {mine[0]['truth']:g}: " + ", ".join(f"{k} {v}" for k, v in counts.items())
              + f" of {len(mine)}; wrong cause {100 * wrong / len(mine):.0f} % (95 % [{100 * low:.0f}, "
              f"{100 * high:.0f}] %); interval holds the truth in {sum(held)} of {len(held)} named; "
              f"median {np.median([r['seconds'] for r in mine]):.1f} s a case")
    wrong = sum(r["outcome"] == "wrong" for r in rows)
    low, high = stats.binomtest(wrong, len(rows)).proportion_ci(0.95)
    print(f"all: wrong cause {wrong}/{len(rows)} ({100 * wrong / len(rows):.1f} %, 95 % "
          f"[{100 * low:.1f}, {100 * high:.1f}] %)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 30)
