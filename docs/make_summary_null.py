"""False-alarm rate of the diagnosis from summary statistics (toywalk.sysid.summary), measured.

The stable toy's own four numbers (stride time, stride length, lean and steer amplitudes) with
Gaussian noise of their SDs, and the slope measured with its SD (tests/sysid/test_summary.py's
SDs), analysed with the base model and three candidates, one seed at a time. The rule says
`adequate` when the base fit's chi-square has p >= alpha (0.01); this counts how often it does
not. Writes docs/summary_null.csv and prints the rate with its binomial 95 % interval.

Run: ``TOYWALK_CACHE=/tmp/twcache .venv/bin/python docs/make_summary_null.py [N]`` (N seeds,
default 200; about 1.5 s each).
"""

import csv
import math
import sys
from pathlib import Path

import numpy as np
from scipy import stats
from toywalk.model import find_gait, load_params
from toywalk.model.optimize import gait_features
from toywalk.sysid.summary import SummaryData, diagnose_summary

HERE = Path(__file__).resolve().parent
PARAMS = HERE.parent / "data" / "params" / "stable-toy.toml"
SD = {"stride_time": 5e-4, "stride_length": 2e-4, "lean_amplitude": math.radians(0.1),
      "steer_amplitude": math.radians(0.1)}
SLOPE_SD = math.radians(0.1)
CANDIDATES = ["impact_trailing_share", "hip_damping", "rolling_resistance"]


def main(n: int) -> None:
    gait = find_gait(load_params(PARAMS))
    feats = gait_features(gait)
    rows = []
    for seed in range(n):
        rng = np.random.default_rng(seed)
        targets = {k: (float(feats[k] + rng.normal() * s), s) for k, s in SD.items()}
        slope = float(gait.params.slope + rng.normal() * SLOPE_SD)
        data = SummaryData(targets, {"slope": (slope, SLOPE_SD)})
        d = diagnose_summary(gait.params, data, effects=CANDIDATES, parameters=[], gait=gait)
        rows.append({"seed": seed, "verdict": d.verdict, "cause": d.cause, "chi2": d.base.chi2,
                     "dof": d.base.dof, "p": d.base.p_value})
    with open(HERE / "summary_null.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    alarms = sum(r["verdict"] != "adequate" for r in rows)
    named = sum(r["cause"] not in (None, "unexplained") for r in rows)
    low, high = stats.binomtest(alarms, n).proportion_ci(0.95)
    chi2 = np.array([r["chi2"] for r in rows])
    print(f"{alarms}/{n} not adequate ({100 * alarms / n:.1f} %, 95 % [{100 * low:.1f}, "
          f"{100 * high:.1f}] %), {named} named a cause; base chi-square mean {chi2.mean():.2f} "
          f"(4 expected on 4 degrees of freedom)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
