"""Stability map of the stable statically-unstable walker (data/params/stable-toy.toml) over foot
radius r (rho tied to it at the file's ratio rho/r) and lateral mass offset d_y.

Writes docs/stability_map.csv and docs/stability_map.png. Computed by warm-started continuation:
the gait of the file is followed in r (at the file's d_y) to each row, then along the row in d_y
both ways from there (toywalk.model.optimize.GaitEvaluator: Newton from the neighbour, continuation
on failure). A cell with no gait is a failure (marked x). The static-instability boundary is drawn
where static_margin = 0 (rho = COM height); can_stand() is evaluated at every cell (False = cannot
stand) and its boundary drawn as well.

Run: ``TOYWALK_CACHE=/tmp/twcache .venv/bin/python docs/make_stability_map.py [--n 12]``
"""

import argparse
import csv
import math
from pathlib import Path

import numpy as np
from toywalk.model import Walker, can_stand, load_params, solve_fixed_point, static_margin
from toywalk.model.optimize import GaitEvaluator

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
# A fixed point of the file's gait (public state order), from tests/model/documented.py.
Z_STABLE = [0.04661788900461893, -0.5141677402083711, -0.001876783030565294, 0.021718470946236697,
            -0.08694501480362028, 4.231073000769995, 0.08135087368205376, 2.3913296604495535]


def main(n: int) -> None:
    base = load_params(ROOT / "data" / "params" / "stable-toy.toml")
    ratio = base.foot_lateral_radius / base.foot_radius
    gait0 = solve_fixed_point(Walker(base), np.array(Z_STABLE))
    radii = np.linspace(0.002, 0.04, n)
    offsets = np.linspace(0.02, 0.26, n)
    j0 = int(np.argmin(np.abs(offsets - base.com_offset[1])))
    rows = []
    col_eval = GaitEvaluator(base, ["foot_radius", "foot_lateral_radius", "com_offset[1]"], gait0)
    # Visit rows outward from the file's r, so that each row starts from a neighbouring row's gait.
    i0 = int(np.argmin(np.abs(radii - base.foot_radius)))
    order = [i0] + [i for k in range(1, n) for i in (i0 + k, i0 - k) if 0 <= i < n]
    anchors = {}
    for i in order:
        r = radii[i]
        near = min(anchors, key=lambda k: abs(k - i)) if anchors else None
        if near is not None:
            col_eval.last = anchors[near]
        else:
            col_eval.last = gait0
        g_anchor = col_eval([r, ratio * r, offsets[j0]])
        if g_anchor is not None:
            anchors[i] = g_anchor
        for direction in (range(j0, n), range(j0 - 1, -1, -1)):
            row_eval = GaitEvaluator(base, ["foot_radius", "foot_lateral_radius", "com_offset[1]"],
                                     g_anchor if g_anchor is not None else gait0)
            alive = g_anchor is not None
            for j in direction:
                params = base.replace(**{"foot_radius": r, "foot_lateral_radius": ratio * r,
                                         "com_offset[1]": offsets[j]})
                g = row_eval([r, ratio * r, offsets[j]]) if alive else None
                alive = g is not None
                rows.append({
                    "foot_radius": r, "foot_lateral_radius": ratio * r, "com_offset_y": offsets[j],
                    "max_abs_eigenvalue": g.max_abs_eigenvalue if g else math.nan,
                    "step_time": g.step_time if g else math.nan,
                    "static_margin": static_margin(params),
                    "can_stand": int(can_stand(params).can_stand),
                    "status": "ok" if g else "no_gait",
                })
            print(f"row r = {r * 1e3:.1f} mm done", flush=True)
    rows.sort(key=lambda d: (d["foot_radius"], d["com_offset_y"]))
    with open(HERE / "stability_map.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, radii, offsets, base)


def replot() -> None:
    with open(HERE / "stability_map.csv") as fh:
        rows = [{k: (v if k == "status" else float(v)) for k, v in d.items()} for d in csv.DictReader(fh)]
    radii = np.array(sorted({d["foot_radius"] for d in rows}))
    offsets = np.array(sorted({d["com_offset_y"] for d in rows}))
    plot(rows, radii, offsets, load_params(ROOT / "data" / "params" / "stable-toy.toml"))


def plot(rows, radii, offsets, base) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_r, n_y = len(radii), len(offsets)
    lam = np.array([d["max_abs_eigenvalue"] for d in rows]).reshape(n_r, n_y)
    margin = np.array([d["static_margin"] for d in rows]).reshape(n_r, n_y)
    stands = np.array([d["can_stand"] for d in rows]).reshape(n_r, n_y)
    fig, ax = plt.subplots(figsize=(7, 5))
    ext = [offsets[0] * 1e3, offsets[-1] * 1e3, radii[0] * 1e3, radii[-1] * 1e3]
    from matplotlib.colors import TwoSlopeNorm

    norm = TwoSlopeNorm(vmin=-0.03, vcenter=0.0, vmax=0.5)
    im = ax.imshow(np.log10(lam), origin="lower", aspect="auto", extent=ext, cmap="coolwarm",
                   norm=norm, interpolation="nearest")
    cb = fig.colorbar(im, ax=ax)
    cb.set_label("log10 step-map max |eigenvalue|  (< 0: stable)")
    yy, rr = np.meshgrid(offsets * 1e3, radii * 1e3)
    if np.nanmin(lam) < 1 < np.nanmax(lam):
        ax.contour(yy, rr, lam, levels=[1.0], colors="k", linewidths=1.5)
    if margin.min() < 0 < margin.max():
        ax.contour(yy, rr, margin, levels=[0.0], colors="g", linestyles="--")
        ax.plot([], [], "g--", label="static margin 0 (above: COM below rho)")
    if stands.min() < 0.5 < stands.max():
        ax.contour(yy, rr, stands, levels=[0.5], colors="m", linestyles=":")
        ax.plot([], [], "m:", label="can_stand boundary (above: can stand)")
    ax.plot([], [], "k-", label="|lambda| = 1 (between: stable)")
    fail = np.isnan(lam)
    ax.plot(yy[fail], rr[fail], "kx", ms=6, label="no gait")
    ax.plot(base.com_offset[1] * 1e3, base.foot_radius * 1e3, "k*", ms=12, label="stable-toy.toml")
    ax.set_xlabel("lateral COM offset d_y (mm)")
    ax.set_ylabel(f"foot radius r (mm), rho = {base.foot_lateral_radius / base.foot_radius:.3f} r")
    ax.set_title("stable-toy walker: step-map max |eigenvalue|", fontsize=10)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(HERE / "stability_map.png", dpi=120)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12, help="grid points per axis")
    ap.add_argument("--plot-only", action="store_true", help="redraw the figure from the CSV")
    args = ap.parse_args()
    if args.plot_only:
        replot()
    else:
        main(args.n)
