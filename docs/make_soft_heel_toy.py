"""The paper's question on the Tinkertoy model: does a heel strike that takes time (the brass
strips' compliance, docs/soft_feet.md) change its gait and stability?

The Tinkertoy fit (data/params/tinkertoy.toml) sits at the fold that ends its branch on the
measured 4.5 degree ramp (docs/effects_study.md), where continuation in ``effects.soft_heel``
cannot start (its parameter column is the rigid path's 0 at tau = 0, docs/soft_feet.md section 5).
So, as the effects study does, the gait is followed in slope to 6 degrees, then in the contact
time constant tau from 0 to 3 ms there (the brass strip's estimates: 0.23-2.6 ms loose over a
span, microseconds backed by the spool; docs/soft_feet.md section 4); and at tau = 1 and 2.5 ms
the soft gait is followed back down in slope to find where its branch turns back near 4.5
degrees.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_soft_heel_toy.py

writes docs/soft_heel_toy.csv and prints the table and the folds (about 3 minutes).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from toywalk.model.continuation import continue_branch
from toywalk.model.parameters import load_params

HERE = Path(__file__).resolve().parent
SIX = math.radians(6.0)


def main() -> None:
    toy = load_params(HERE.parent / "data" / "params" / "tinkertoy.toml")
    up = continue_branch(toy, "slope", toy.slope, SIX, max_points=80)
    z = up.points[-1].fixed_point
    soft = continue_branch(toy.replace(slope=SIX), "effects.soft_heel", 0.0, 3e-3, max_points=80, z_start=z)
    rows = [{"tau_ms": 1e3 * p.value, "max_abs_eigenvalue": p.max_abs_eigenvalue, "step_time_s": p.step_time,
             "stride_m": p.stride_length, "lean_deg": math.degrees(p.lean_amplitude),
             "steer_deg": math.degrees(p.steer_amplitude)} for p in soft.points]
    with open(HERE / "soft_heel_toy.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"6 degrees, tau 0 to 3 ms: {soft.status} ({soft.message}); events: "
          f"{[e.detail for e in soft.events] or 'none'}")
    for r in rows[:: max(1, len(rows) // 8)] + [rows[-1]]:
        print(f"tau {r['tau_ms']:6.3f} ms  max|eig| {r['max_abs_eigenvalue']:.4f}  "
              f"step {r['step_time_s']:.5f} s  stride {100 * r['stride_m']:.3f} cm  "
              f"lean {r['lean_deg']:.3f} deg  steer {r['steer_deg']:.3f} deg")
    for tau in (1e-3, 2.5e-3):
        down = continue_branch(toy.replace(slope=SIX, **{"effects.soft_heel": tau}), "slope", SIX,
                               math.radians(4.0), max_points=120, z_start=z)
        folds = [e.value for e in down.events if e.kind == "fold"]
        first = f"{folds[0]:.7f} rad ({math.degrees(folds[0]):.4f} deg)" if folds else "none"
        print(f"tau {1e3 * tau:g} ms, followed down from 6 degrees: first fold at {first}; "
              f"{down.status}; all folds {[round(math.degrees(f), 3) for f in folds]} deg")
    print(f"rigid: the fit's gait ends at its fold at {toy.slope:.7f} rad "
          f"({math.degrees(toy.slope):.4f} deg)")


if __name__ == "__main__":
    main()
