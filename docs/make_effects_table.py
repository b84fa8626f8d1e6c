"""The stable toy's gait with each effect of the library at its typical strength (docs/effects.md).

Run from the repository root: ``.venv/bin/python docs/make_effects_table.py``. Writes
``docs/effects_typical.csv`` and prints the Markdown table of docs/effects.md.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from toywalk.model.effects import EFFECTS
from toywalk.model.gait import GaitNotFound, find_gait
from toywalk.model.parameters import load_params

ROOT = Path(__file__).resolve().parents[1]
COLUMNS = ("effect", "value", "unit", "map", "step_time_s", "stride_cm", "lean_deg", "steer_deg",
           "heading_deg", "max_abs_eigenvalue_per_step", "collision_loss_mJ")


def features(name: str, value: float, unit: str, gait) -> dict:
    return {
        "effect": name, "value": value, "unit": unit, "map": "step" if gait.period == 1 else "stride",
        "step_time_s": gait.step_time, "stride_cm": 100 * gait.stride_length,
        "lean_deg": math.degrees(gait.lean_amplitude), "steer_deg": math.degrees(gait.steer_amplitude),
        "heading_deg": math.degrees(gait.heading),
        # A stride map's eigenvalues are two steps' worth: the per-step growth is their square root.
        "max_abs_eigenvalue_per_step": gait.max_abs_eigenvalue ** (1 / gait.period),
        "collision_loss_mJ": 1e3 * gait.step.collision_loss,
    }


def main() -> list[dict]:
    params = load_params(ROOT / "data" / "params" / "stable-toy.toml")
    base = find_gait(params)
    rows = [features("(none: the seed's model)", 0.0, "", base)]
    for name, effect in EFFECTS.items():
        changed = params.replace(**{f"effects.{name}": effect.typical})
        try:
            gait = find_gait(changed) if changed.breaks_symmetry else find_gait(changed, base.fixed_point)
        except GaitNotFound as err:
            print(f"{name}: no gait ({err})")
            continue
        rows.append(features(name, effect.typical, effect.unit, gait))
    with (ROOT / "docs" / "effects_typical.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    print("| effect | typical | step time (s) | stride (cm) | lean (deg) | steer (deg) | heading (deg) "
          "| max abs eigenvalue per step | collision loss (mJ) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        value = f"{r['value']:g} {r['unit']}".strip() if r["unit"] else "-"
        print(f"| {r['effect']} | {value} | {r['step_time_s']:.4f} | {r['stride_cm']:.2f} | "
              f"{r['lean_deg']:.2f} | {r['steer_deg']:.2f} | {r['heading_deg']:.1f} | "
              f"{r['max_abs_eigenvalue_per_step']:.4f} | {r['collision_loss_mJ']:.3f} |")
    return rows


if __name__ == "__main__":
    main()
