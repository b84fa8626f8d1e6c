"""The basins and hand launches of the shipped stable walkers (docs/gaits.md section 5).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_basin.py            # about 2 minutes
    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_basin.py --plot-only

Writes docs/basin_radii.csv (one row per direction), docs/basin_curves.csv (recovery against size),
docs/basin_launch.csv (hand launches), docs/basin_kicks.csv (the four rates kicked by +-0.02 rad/s,
eight seeds, as issue 44 kicked the clearing toy in MuJoCo), docs/basin_cost.csv (seconds per
call) and docs/basin.png.
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, find_gait, load_params
from toywalk.model.basin import (
    basin_radius,
    eigen_directions,
    hand_launch,
    perturbed,
    random_directions,
    recovers,
    recovery_curve,
)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
WALKERS = ("stable-toy", "clearing-toy")
SIZES = np.geomspace(1e-3, 0.3, 11)
TRIALS = 50
N_RANDOM = 20
SEED = 0
KICK = 0.02  # rad/s on each of the four rates, with random signs (issue 44's MuJoCo kicks)
TIPS_DEG = (0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 2.9, 4.0, 4.8, 6.0, 8.0, 10.0)
HEADINGS_DEG = (0.0, 2.0, -2.0, 5.0)


def _gait(name: str):
    """The file's gait: from its stored start (clearing-toy) or the search (stable-toy)."""
    return find_gait(load_params(ROOT / "data" / "params" / f"{name}.toml"))


def _write(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def measure() -> None:
    radii, curves, launches, cost, kicks = [], [], [], [], []
    for name in WALKERS:
        gait = _gait(name)
        params, walker = gait.params, Walker(gait.params)
        t = time.perf_counter()
        for label, unit in eigen_directions(gait):
            r = basin_radius(params, unit, gait, label=label, walker=walker)
            radii.append(dict(walker=name, direction=label, radius=r.radius, upper=r.upper,
                              evaluations=r.evaluations))
        n_eig = len(eigen_directions(gait))
        cost.append(dict(walker=name, call="basin_radius (eigenvector)",
                         seconds=(time.perf_counter() - t) / n_eig))
        t = time.perf_counter()
        for i, unit in enumerate(random_directions(params, gait, N_RANDOM, SEED)):
            r = basin_radius(params, unit, gait, label=f"random {i}", walker=walker)
            radii.append(dict(walker=name, direction=f"random {i}", radius=r.radius, upper=r.upper,
                              evaluations=r.evaluations))
        cost.append(dict(walker=name, call="basin_radius (random)",
                         seconds=(time.perf_counter() - t) / N_RANDOM))
        u = random_directions(params, gait, 1, SEED)[0]
        t = time.perf_counter()
        for _ in range(10):
            recovers(params, perturbed(params, gait, u, 1e-3, walker), gait, walker=walker)
        cost.append(dict(walker=name, call="recovers (size 1e-3)", seconds=(time.perf_counter() - t) / 10))
        t = time.perf_counter()
        curve = recovery_curve(params, SIZES, TRIALS, SEED, gait=gait)
        cost.append(dict(walker=name, call=f"recovery_curve ({len(SIZES)} sizes x {TRIALS})",
                         seconds=time.perf_counter() - t))
        for s, k, p, se in zip(curve.sizes, curve.recovered, curve.probability, curve.se, strict=True):
            curves.append(dict(walker=name, size=s, trials=TRIALS, recovered=k, probability=p, se=se))
        t = time.perf_counter()
        launch = hand_launch(params, np.radians(TIPS_DEG), np.radians(HEADINGS_DEG), gait=gait)
        cost.append(dict(walker=name, call="hand_launch (per launch)",
                         seconds=(time.perf_counter() - t) / (len(TIPS_DEG) * len(HEADINGS_DEG))))
        for heading, row in zip(HEADINGS_DEG, launch.results, strict=True):
            for tip, res in zip(TIPS_DEG, row, strict=True):
                launches.append(dict(walker=name, heading_deg=heading, tip_deg=tip, recovered=res.recovered,
                                     reason=res.reason, steps=res.steps, scuffs=res.scuffs,
                                     lean_amplitude_deg=math.degrees(gait.lean_amplitude)))
        for seed in range(8):
            signs = np.random.default_rng(seed).choice([-1.0, 1.0], 4)
            z = gait.fixed_point.copy()
            z[[1, 3, 5, 7]] += KICK * signs
            res = recovers(params, z, gait, walker=walker)
            kicks.append(dict(walker=name, seed=seed, kick_rad_s=KICK, recovered=res.recovered,
                              reason=res.reason, steps=res.steps))
    _write(HERE / "basin_kicks.csv", kicks)
    _write(HERE / "basin_radii.csv", radii)
    _write(HERE / "basin_curves.csv", curves)
    _write(HERE / "basin_launch.csv", launches)
    _write(HERE / "basin_cost.csv", cost)


def plot() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(HERE / "basin_curves.csv") as f:
        curves = list(csv.DictReader(f))
    with open(HERE / "basin_radii.csv") as f:
        radii = list(csv.DictReader(f))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for name, colour in zip(WALKERS, ("C0", "C1"), strict=True):
        rows = [r for r in curves if r["walker"] == name]
        s = np.array([float(r["size"]) for r in rows])
        p = np.array([float(r["probability"]) for r in rows])
        se = np.array([float(r["se"]) for r in rows])
        ax1.errorbar(s, p, yerr=se, marker="o", color=colour, capsize=2,
                     label=f"{name} ({rows[0]['trials']} directions)")
        mine = [r for r in radii if r["walker"] == name]
        eig = [float(r["radius"]) for r in mine if r["direction"].startswith("eig")]
        rnd = [float(r["radius"]) for r in mine if r["direction"].startswith("random")]
        ax2.scatter(eig, np.full(len(eig), WALKERS.index(name) + 0.1), color=colour, marker="|", s=200,
                    label=f"{name}: eigenvectors")
        ax2.scatter(rnd, np.full(len(rnd), WALKERS.index(name) - 0.1), color=colour, marker="x",
                    label=f"{name}: random")
    ax1.set_xscale("log")
    ax1.set_xlabel("perturbation size (rad; rates in 1/sqrt(l/g))")
    ax1.set_ylabel("fraction that recovers")
    ax1.legend(fontsize=8)
    ax2.set_xscale("log")
    ax2.set_yticks([0, 1], WALKERS)
    ax2.set_xlabel("basin radius along a direction")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(HERE / "basin.png", dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot-only", action="store_true")
    args = parser.parse_args()
    if not args.plot_only:
        measure()
    plot()


if __name__ == "__main__":
    main()
