"""The clearing toy's gait on soft feet: its stability against the contact time constant
(docs/soft_feet.md section 5).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_soft_heel.py      # about 40 s
    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_soft_heel.py \
        --params data/params/robust-toy.toml --slope-to 0.09           # another walker

The gait of data/params/clearing-toy.toml is followed by pseudo-arclength continuation in
``effects.soft_heel`` (the compliant heel strike's time constant tau, model/effects/soft.py) from
the rigid strike (tau = 0) to 4 ms, then solved by Newton at tau = 0, 0.25, 0.5, 1, 2 and 4 ms
from the nearest branch point. For each: the step map's eigenvalues, the step time and the lean
amplitude; at 1 ms and 4 ms also the largest eigenvalue with the phase integrated at twice the
steps (the integrator's share of the numbers: check it on another walker, where the default 20
steps per tau can be far from converged, docs/gaits.md section 7). Then the slope at which the
gait loses stability, rigid and at tau = 1, 2 and 4 ms (continuation in ``slope`` up to
``--slope-to``). Prints Markdown tables and writes docs/soft_heel.png and docs/soft_heel.csv;
with ``--params P.toml``, docs/soft_heel_P.png and docs/soft_heel_P.csv.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, load_params
from toywalk.model.continuation import continue_branch
from toywalk.model.gait import solve_fixed_point

HERE = Path(__file__).resolve().parent
PARAMS = HERE.parent / "data" / "params" / "clearing-toy.toml"
TAUS = (0.0, 2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3)
SOFT = "effects.soft_heel"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--params", type=Path, default=PARAMS)
    parser.add_argument("--slope-to", type=float, default=0.0625,
                        help="the slope continuation's end (rad), above the rigid gait's edge")
    args = parser.parse_args()
    params = load_params(args.params)
    suffix = "" if args.params.resolve() == PARAMS else f"_{args.params.stem}"
    start = time.perf_counter()
    branch = continue_branch(params, SOFT, 0.0, 0.004, max_points=400)
    print(f"continuation: {branch.status} ({branch.message}), {len(branch.points)} points, "
          f"{time.perf_counter() - start:.1f} s; events: {[(e.kind, e.value) for e in branch.events]}")
    values = np.array([p.value for p in branch.points])
    rows = []
    for tau in TAUS:
        near = branch.points[int(np.argmin(np.abs(values - tau)))]
        walker = Walker(params.replace(**{SOFT: tau}))
        gait = solve_fixed_point(walker, near.fixed_point)
        residual = np.abs(walker.step(gait.fixed_point).z_plus - gait.fixed_point).max()
        moduli = np.sort(np.abs(gait.eigenvalues))[::-1]
        row = dict(tau_ms=1e3 * tau, max_abs_eig=moduli[0], second=moduli[2] if len(moduli) > 2 else np.nan,
                   step_time_ms=1e3 * gait.step_time, lean_deg=np.degrees(gait.lean_amplitude),
                   stride_mm=1e3 * gait.stride_length, residual=residual, finer=np.nan,
                   dominant=gait.eigenvalues[np.argmax(np.abs(gait.eigenvalues))])
        if tau in (1e-3, 4e-3):
            fine = solve_fixed_point(Walker(params.replace(**{SOFT: tau}), soft_steps_per_tau=40),
                                     gait.fixed_point)
            row["finer"] = fine.max_abs_eigenvalue
        rows.append(row)
    print("\n| tau (ms) | max abs eigenvalue | dominant eigenvalue | same at 40 steps per tau "
          "| step time (ms) | lean amplitude (deg) | stride (mm) | fixed-point residual |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        finer = "" if np.isnan(r["finer"]) else f"{r['finer']:.4f}"
        print(f"| {r['tau_ms']:g} | {r['max_abs_eig']:.4f} | {r['dominant']:.4f} | {finer} "
              f"| {r['step_time_ms']:.2f} | {r['lean_deg']:.3f} | {r['stride_mm']:.2f} "
              f"| {r['residual']:.1e} |")
    with open(HERE / f"soft_heel{suffix}.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["tau_s", "max_abs_eigenvalue", "step_time_s", "lean_amplitude_rad",
                         "stride_length_m"])
        for p in branch.points:
            writer.writerow([f"{p.value:.6e}", f"{p.max_abs_eigenvalue:.6f}", f"{p.step_time:.6f}",
                             f"{p.lean_amplitude:.6f}", f"{p.stride_length:.6f}"])
    # The upper edge of the stable slopes: where the gait loses stability, rigid and on soft feet.
    edges = {}
    for tau in (0.0, 1e-3, 2e-3, 4e-3):
        walker_params = params.replace(**{SOFT: tau})
        slope_branch = continue_branch(walker_params, "slope", params.slope, args.slope_to, max_points=200,
                                       z_start=None if tau == 0.0 else _gait_start(branch, tau))
        lost = [e for e in slope_branch.events if e.kind == "loses stability"]
        edges[tau] = lost[0].value if lost else np.nan
        print(f"tau = {1e3 * tau:g} ms: slope branch {slope_branch.status}; loses stability at "
              f"{edges[tau]:.6f} rad" + (f" ({lost[0].detail})" if lost else ""))
    title = f"{args.params.stem} on soft feet ({args.params.name}, slope {params.slope:.4g} rad)"
    _figure(branch, rows, title, HERE / f"soft_heel{suffix}.png")


def _gait_start(branch, tau: float) -> np.ndarray:
    values = np.array([p.value for p in branch.points])
    return branch.points[int(np.argmin(np.abs(values - tau)))].fixed_point


def _figure(branch, rows, title: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tau = np.array([1e3 * p.value for p in branch.points])
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.3), constrained_layout=True)
    axes[0].plot(tau, [p.max_abs_eigenvalue for p in branch.points], ".-", ms=3)
    axes[0].plot([r["tau_ms"] for r in rows], [r["max_abs_eig"] for r in rows], "o", mfc="none")
    axes[0].axhline(1.0, color="k", lw=0.8)
    axes[0].set(xlabel="contact time constant tau (ms)", ylabel="max |eigenvalue| of the step map",
                ylim=(0.8, 1.05))
    axes[1].plot(tau, [1e3 * p.step_time for p in branch.points], ".-", ms=3, label="step")
    axes[1].plot(tau, [1e3 * p.step_time - 10 * t for p, t in zip(branch.points, tau, strict=True)],
                 ".-", ms=3, label="flow (step less the phase)")
    axes[1].set(xlabel="tau (ms)", ylabel="time (ms)")
    axes[1].legend(fontsize=8)
    axes[2].plot(tau, [np.degrees(p.lean_amplitude) for p in branch.points], ".-", ms=3)
    axes[2].set(xlabel="tau (ms)", ylabel="lean amplitude (deg)")
    fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
