"""The shape of the missing force, recovered (docs/diagnosis.md, "The shape of the missing force").

Kinds of walk, each 12 steps (``hinge-stable-24``: 24) from the gait's fixed point with 2 mrad of
white noise (seeds 0, 1, ...), analysed by ``diagnose`` (its default model choice; the
further-walk weighing off, which does not change the verdict or the search):

- ``hinge-stable``, ``hinge-clearing``: a hinge spring (the port term ``hinge_stiffness``,
  5e-3 N m/rad: the pitches move by 0.4 and 0.3 degrees over two steps, 2 to 4 noise SDs) in the
  stable toy and the clearing toy, which no library effect is; ``hinge-stable-24`` the stable
  toy's over 24 steps, where 12 leave the linear and the cubic spring within the search's
  separation of each other in some walks;
- ``damping``: hip damping of the library (2e-4 N m s/rad, its typical strength) in the stable
  toy with the library withheld from the causes (``effects=[]``, ``parameters=[]``: what
  ``diagnose --effects none --parameters none`` does), so that the analysis goes straight to the
  port dictionary: the search should find the hinge's rate form, which is hip_damping, at the
  estimate a fit with it free gives. (Withholding only the hinge's own effects is not enough:
  the stance foot's pivot friction, which the damping's signature resembles, was then named.)

    python docs/make_missing_force_validation.py hinge-stable 0 1 2 3 4 5 6 7 8 9

writes ``docs/missing_force_KIND.csv``: per seed the verdict, the terms selected, the hidden
term's coefficient and 95 % interval, whether it holds the truth, whether it is the only term,
and (``damping``) the direct fit's estimate.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FREE = ["foot_radius", "com_offset[1]"]
KINDS = {"hinge-stable": ("stable-toy", "hinge_stiffness", 5e-3),
         "hinge-clearing": ("clearing-toy", "hinge_stiffness", 5e-3),
         "damping": ("stable-toy", "hip_damping", 2e-4),
         "hinge-stable-24": ("stable-toy", "hinge_stiffness", 5e-3),
         "hinge-toy-sized": ("toy-sized", "hinge_stiffness", 5e-3)}
#: Steps of each kind's walk (12 unless said).
STEPS = {"hinge-stable-24": 24}
FIELDS = ["kind", "seed", "truth", "verdict", "cause", "terms", "coefficient", "low", "high", "covers",
          "only", "direct", "direct_se", "stop", "seconds"]


def one(kind: str, seed: int) -> dict:
    from toywalk.model.parameters import load_params
    from toywalk.model.simulate import gait_walk
    from toywalk.sysid.discrepancy import diagnose
    from toywalk.sysid.fit import fit

    walker_name, effect, strength = KINDS[kind]
    walker = load_params(ROOT / "data" / "params" / f"{walker_name}.toml")
    name = f"effects.{effect}"
    table = gait_walk(walker.replace(**{name: strength}), STEPS.get(kind, 12), noise=0.002, seed=seed)
    withheld = {"effects": [], "parameters": []} if kind == "damping" else {}
    d = diagnose(table, walker, free=FREE, tie_design=False, **withheld)
    found = d.missing_force
    terms = [t["parameter"] for t in found.terms] if found else []
    term = next((t for t in found.terms if t["parameter"] == name), None) if found else None
    row = {"kind": kind, "seed": seed, "truth": strength, "verdict": d.verdict, "cause": d.cause,
           "terms": " ".join(terms), "stop": found.stop if found else "not searched",
           "seconds": round(d.seconds["total"], 1)}
    if term:
        lo, hi = term["interval"]
        row.update(coefficient=term["coefficient"], low=lo, high=hi, covers=lo <= strength <= hi,
                   only=terms == [name])
    if kind == "damping":
        direct = fit(table, d.base.params, FREE + [name], model=d.base.model, check_jacobian=False)
        row.update(direct=direct.estimates[name], direct_se=direct.std[name])
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=sorted(KINDS))
    parser.add_argument("seeds", nargs="+", type=int)
    args = parser.parse_args()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    out = ROOT / "docs" / f"missing_force_{args.kind}.csv"
    kept = []
    if out.exists():
        with open(out, newline="") as fh:
            kept = [r for r in csv.DictReader(fh) if int(r["seed"]) not in args.seeds]
    rows = []
    for seed in args.seeds:
        rows.append(one(args.kind, seed))
        print(rows[-1], file=sys.stderr, flush=True)
    with open(out, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS)
        writer.writeheader()
        for row in sorted([*kept, *rows], key=lambda r: int(r["seed"])):
            writer.writerow({k: row.get(k) for k in FIELDS})
    print(f"-> {out}")


if __name__ == "__main__":
    main()
