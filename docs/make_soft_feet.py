"""The compliant heel strike's convergence table and the toy's strip stiffness (docs/soft_feet.md).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_soft_feet.py      # about 10 s

For three walkers at their gait's heel strike (a planar point-foot compass, the 3D clearing toy and
the 3D toy-sized walker), the compliant strike (model/compliant.py) at contact time constants
4 ms to 0.125 ms, critically damped, friction 1: its distance to the rigid collision's state
after the strike, the observed order, the trailing foot's share of the normal impulse and the
energy balance. Prints a Markdown table and writes docs/soft_feet.csv.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
from toywalk.model import Walker, find_gait, load_params
from toywalk.model.compliant import SoftContact, compliant_strike
from toywalk.model.equations import build_functions

HERE = Path(__file__).resolve().parent
PARAMS = HERE.parent / "data" / "params"
TAUS = (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4)


def _walkers():
    """(name, params, planar) of the three cases."""
    compass = dataclasses.replace(load_params(PARAMS / "compass-3d.toml"), com_offset=(0.0, 0.0, -0.3),
                                  hip_width=0.0, foot_radius=0.0, foot_lateral_radius=0.0)
    return [("planar point-foot compass", compass, True),
            ("clearing-toy", load_params(PARAMS / "clearing-toy.toml"), False),
            ("toy-sized", load_params(PARAMS / "toy-sized.toml"), False)]


def convergence() -> list[dict]:
    """One row per walker and time constant."""
    rows = []
    for name, params, planar in _walkers():
        walker = Walker(params, planar=planar)
        x = walker.full_state(walker.step(find_gait(params, planar=planar).fixed_point).z_minus)
        p = params.input_vector(1.0)
        fns = build_functions(planar)
        rigid = fns["collision"](x, p).full().ravel()
        rigid_loss = -fns["impact"](x, p)[0].full()[0, 0]
        n_dyn = walker.lay.n_dyn
        previous = None
        for tau in TAUS:
            out = compliant_strike(params, x, SoftContact(tau), planar=planar)
            error = float(np.abs(out.x_plus - rigid)[:n_dyn].max())
            e = out.energy
            rows.append(dict(
                walker=name, tau_ms=tau * 1e3, error=error,
                order=math.log2(previous / error) if previous else math.nan,
                trailing_share=float(out.impulses[0] / out.impulses.sum()),
                trailing_lift_off_ms=out.trailing_lift_off * 1e3, trailing_left=out.trailing_left,
                landing_rebounds=out.landing_rebounds, peak_landing_N=float(out.peak_normal[1]),
                friction_used=out.friction_used, rigid_loss_mJ=rigid_loss * 1e3,
                damping_mJ=e["damping"] * 1e3, tangential_mJ=e["tangential"] * 1e3,
                projection_mJ=e["projection"] * 1e3, mechanical_mJ=e["mechanical"] * 1e3,
                balance_rel=abs(e["balance"] / e["mechanical"])))
            previous = error
    return rows


def strip_stiffness() -> dict:
    """The brass strip's normal stiffness and the toy's contact time (docs/soft_feet.md)."""
    e_brass, width, thickness = 100e9, 0.50e-2, 0.013e-2  # Pa, m, m
    mass, g = 0.120, 9.81  # kg: the toy; m/s^2
    # Axial (through-thickness) stiffness of a 1 mm long patch of the strip pressed flat on wood:
    # k = E A / t, A = width * 1 mm; the strip on its spool is backed, so this bounds the strip's
    # own compliance from above (it is stiffer than the wood under it).
    patch = 1e-3
    k_through = e_brass * width * patch / thickness
    # Plate bending: the strip lifted off the spool over a free span L (a loose shim), as a
    # beam clamped at both ends with a central load: k = 192 E I / L^3, I = width t^3 / 12.
    inertia = width * thickness**3 / 12
    rows = {}
    for span in (2e-3, 5e-3, 10e-3):
        k_bend = 192 * e_brass * inertia / span**3
        rows[span] = dict(k=k_bend, tau=math.sqrt(mass / k_bend), sag=mass * g / k_bend)
    return dict(k_through=k_through, tau_through=math.sqrt(mass / k_through), bending=rows,
                inertia=inertia)


def main():
    rows = convergence()
    with open(HERE / "soft_feet.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print("| walker | tau (ms) | max abs x_plus - rigid | order | trailing share | lift-off (ms) "
          "| rebound | peak N landing (N) | balance (rel) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['walker']} | {r['tau_ms']:g} | {r['error']:.3e} | {r['order']:.3f} | "
              f"{r['trailing_share']:.1e} | {r['trailing_lift_off_ms']:.3g} | {r['landing_rebounds']} | "
              f"{r['peak_landing_N']:.3g} | {r['balance_rel']:.1e} |")
    print()
    print("| walker | tau (ms) | rigid loss (mJ) | phase mechanical change (mJ) | damping (mJ) "
          "| tangential (mJ) | projection (mJ) | friction used |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['walker']} | {r['tau_ms']:g} | {r['rigid_loss_mJ']:.4g} | {r['mechanical_mJ']:.4g} | "
              f"{r['damping_mJ']:.4g} | {r['tangential_mJ']:.4g} | {r['projection_mJ']:.3g} | "
              f"{r['friction_used']:.3f} |")
    s = strip_stiffness()
    print()
    print(f"through-thickness, 1 mm patch: k = {s['k_through']:.3g} N/m, "
          f"sqrt(m/k) = {s['tau_through']:.3g} s")
    print(f"I = {s['inertia']:.3g} m^4")
    for span, b in s["bending"].items():
        print(f"bending, free span {span * 1e3:g} mm: k = {b['k']:.3g} N/m, sqrt(m/k) = {b['tau']:.3g} s, "
              f"static sag {b['sag'] * 1e6:.3g} um")


if __name__ == "__main__":
    main()
