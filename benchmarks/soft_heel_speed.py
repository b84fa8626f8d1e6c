"""The step map with the compliant heel strike (``effects.soft_heel``, docs/soft_feet.md section 5)
against the rigid one, side by side in one run.

Run: ``.venv/bin/python benchmarks/soft_heel_speed.py`` (under a minute once the kernels are
cached). Writes ``benchmarks/results/soft_heel_speed.json`` and prints a table. The walker: the
clearing toy (data/params/clearing-toy.toml) at its gait's fixed point; the soft strike at
tau = 1 ms (10 tau of phase, 200 RK4 steps of the free walker). Four ways: ``Walker.step`` value
only, with the state Jacobian, with the parameter Jacobian too, and the strike alone (the rigid
``collision`` kernel against the phase's kernel). Timing as ``run_all.py`` (median and minimum
of calibrated loops); compare the ratios, measured in the same run, not absolute times.
"""

from __future__ import annotations

import datetime
import os
import sys
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.walker import Walker

sys.path.insert(0, str(Path(__file__).parent))
from run_all import _ratio, measure  # noqa: E402  (one timing method for every benchmark)

HERE = Path(__file__).parent
TAU = 1e-3  # s, MuJoCo's default contact time constant in model/mujoco_check.py


def main() -> None:
    rigid_params = load_params(HERE.parent / "data" / "params" / "clearing-toy.toml")
    soft_params = rigid_params.replace(**{"effects.soft_heel": TAU})
    z = find_gait(rigid_params).fixed_point
    rigid, soft = Walker(rigid_params), Walker(soft_params)
    x_minus = rigid.full_state(rigid.step(z).z_minus)
    cases = {
        "step": lambda w: (lambda: w.step(z)),
        "step_jacobian": lambda w: (lambda: w.step(z, jacobian=True)),
        "step_params_jacobian": lambda w: (lambda: w.step(z, jacobian=True, params_jacobian=True)),
        "strike_only": lambda w: (lambda: w.collide(w.to_public(x_minus))),
    }
    load = os.getloadavg()
    rows = {}
    print(f"{'case':<22s} {'rigid ms':>9s} {'soft ms':>9s} {'ratio (median)':>15s}")
    for name, make in cases.items():
        fast, slow = measure(make(rigid)), measure(make(soft))
        rows[name] = {"rigid": fast, "soft": slow, **_ratio(slow, fast)}
        print(f"{name:<22s} {1e3 * fast['time_median_s']:9.3f} {1e3 * slow['time_median_s']:9.3f} "
              f"{rows[name]['ratio_median']:15.1f}", flush=True)
    step_rigid, step_soft = rigid.step(z), soft.step(z)
    out = {"walker": "data/params/clearing-toy.toml", "tau_s": TAU,
           "strike_phase_s": step_soft.strike_phase,
           "step_time_s": {"rigid": step_rigid.step_time, "soft": step_soft.step_time},
           "state_difference_after_one_step": float(np.max(np.abs(step_soft.z_plus - step_rigid.z_plus))),
           "cases": rows, "load_average_start": load, "load_average_end": os.getloadavg(),
           "date": datetime.datetime.now().isoformat(timespec="seconds")}
    atomic_write_json(HERE / "results" / "soft_heel_speed.json", out)
    print(f"-> {HERE / 'results' / 'soft_heel_speed.json'}")


if __name__ == "__main__":
    main()
