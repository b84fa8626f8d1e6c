"""Which second walk would tell apart the effects that a walk on its cycle cannot?

    python docs/make_tie_design.py            -> docs/tie_design.csv (about 1 min)
    python docs/make_tie_design.py joint      -> docs/tie_joint.csv (about 8 min)
    python docs/make_tie_design.py null FIRST LAST -> docs/tie_null.csv (about 30 s a seed)

On a walk of the stable toy on its cycle the hip's viscous and dry friction and the stance foot's
pivot friction explain one another's walks (docs/diagnosis.md, "Each effect of the library hidden
in turn"): their fits come within 1 to 5 in chi-square where the rule asks for 9.2. This measures
(:mod:`toywalk.sysid.design`: first order, about the base fit) how far apart they come when the
same toy is also walked under a changed, known condition and the walks are analysed together:
they share the toy's parameters and the hidden effect, each has its own nuisances.

Walks: as docs/make_diagnose_validation.py's (12 steps from the gait, its sampling, noise 0.002
rad; the base frees the foot radius and the lateral mass offset, the fit the offsets of lean, steer
and pitch), noise-free, the noise given to the fit. Hidden: each of the three at the validation
table's strength (3 noise SDs beyond the base on the toy's own slope). Candidates: the library's
symmetric effects and held parameters (an uneven build and a cross slope need a stride's BVP and
are told apart from these by their left-right signature).

Designs: the toy's slope alone (the validation's walk: compare these first-order gaps with the
fitted ones measured there), the same walk two and three times (as much data, no new condition),
a second walk on a ramp at 0.8 or 0.6 of the slope (the gait stays stable: max |eigenvalue| 0.974
and 0.979; at 1.25 times the slope it is 1.0005), or with the balance masses moved 1 cm further
out or in (``com_offset[1]`` +-0.01 m on the same ramp: a known change to the build), and both
changes as two more walks.

``joint`` checks the last design by analysing the walks together
(:func:`toywalk.sysid.walks.diagnose_walks`): each of the three effects hidden in the three walks
(toy's slope, 0.8 of it, balance masses 1 cm out; 12 steps each, 0.002 rad of white noise, seeds
600 + 10 i + walk), the base freeing the foot radius and lateral offset, the three effects and the
slope the candidates; each walk weighed by its samples' scatter; the fits in two worker processes.
The held-out check's gain (``held_out_gain``: base minus named model, held-out chi-square of
alternate strides of every walk) is on the leading candidate's row.

``null`` measures the joint analysis's false alarms: the three walks of the toy itself (no effect
hidden; seeds 10 s + walk for s in FIRST..LAST-1), the whole library as candidates. Rows are
appended as measured, so a killed run keeps them.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from make_diagnose_validation import FREE, NOISE, TOY, _append, walk  # noqa: E402
from toywalk.sysid.design import separation, walk_columns  # noqa: E402
from toywalk.sysid.naming import candidates  # noqa: E402
from toywalk.sysid.walks import diagnose_walks  # noqa: E402

HERE = Path(__file__).parent
#: The hidden effects at the validation table's strengths (docs/diagnose_effects.csv).
HIDDEN = {"effects.hip_damping": 4.961e-05, "effects.hip_coulomb": 0.0001796,
          "effects.pivot_friction": 0.0006535}
EFFECTS = ["hip_damping", "hip_coulomb", "rolling_resistance", "pivot_friction",
           "impact_trailing_share", "impact_spin_arrest"]
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
#: Each design's further walks, as changes to the toy (a slope factor, a lateral offset shift, m).
DESIGNS = {
    "one walk": [],
    "the same walk twice": [{}],
    "the same walk three times": [{}, {}],
    "second walk, slope x0.8": [{"slope": 0.8}],
    "second walk, slope x0.6": [{"slope": 0.6}],
    "second walk, balance masses 1 cm out": [{"com_offset[1]": 0.01}],
    "second walk, balance masses 1 cm in": [{"com_offset[1]": -0.01}],
    "two more walks: slope x0.8, balance masses 1 cm out": [{"slope": 0.8}, {"com_offset[1]": 0.01}],
}


def changed(change: dict):
    """The toy under a design's change."""
    if "slope" in change:
        return TOY.replace(slope=TOY.slope * change["slope"])
    if "com_offset[1]" in change:
        offset = list(TOY.com_offset)
        offset[1] += change["com_offset[1]"]
        return TOY.replace(com_offset=offset)
    return TOY


def main() -> None:
    cands = candidates(TOY, FREE, EFFECTS)
    names = [c.name for c in cands]
    cache = {}

    def columns(change: dict):
        key = tuple(sorted(change.items()))
        if key not in cache:
            params = changed(change)
            cache[key] = walk_columns(walk(params, 0, noise=0.0), params, FREE, names, label=str(change),
                                      model="periodic", noise_sd=dict.fromkeys(SIGNALS, NOISE))
        return cache[key]

    out = HERE / "tie_design.csv"
    tmp = out.with_name(out.name + ".tmp")
    rows = []
    for design, extra in DESIGNS.items():
        walks = [columns({})] + [columns(c) for c in extra]
        for r in separation(walks, cands, HIDDEN, rng=7):
            rows.append({"design": design, "walks": len(walks), "hidden": r["hidden"],
                         "lr": f"{r['lr']:.1f}", "nearest": r["nearest"], "gap": f"{r['gap']:.1f}",
                         "named_rate": f"{r['named_rate']:.3f}",
                         **{f"gap_{n.removeprefix('effects.')}": f"{g:.1f}" for n, g in r["gaps"].items()}})
        print(design, "; ".join(f"{r['hidden']} {r['gap']} ({r['nearest']}) {r['named_rate']}"
                                for r in rows[-len(HIDDEN):]), flush=True)
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, restval="")
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(out)


def joint() -> None:
    out = HERE / "tie_joint.csv"
    tmp = out.with_name(out.name + ".tmp")
    bases = [TOY, *(changed(c) for c in DESIGNS["two more walks: slope x0.8, balance masses 1 cm out"])]
    fields = ["hidden", "truth", "verdict", "cause", "candidate", "status", "chi2", "behind", "lr",
              "estimate", "low", "high", "holds", "held_out_gain", "base_status", "base_chi2", "seconds"]
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, restval="")
        writer.writeheader()
        for i, (name, strength) in enumerate(HIDDEN.items()):
            tables = [walk(b.replace(**{name: strength}), 600 + 10 * i + k) for k, b in enumerate(bases)]
            d = diagnose_walks(tables, bases, model="periodic", free=FREE, parameters=["slope"],
                               effects=[h.removeprefix("effects.") for h in HIDDEN], workers=2)
            best = min(f.chi2 for f in d.extended.values() if f.success)
            for r in d.ranking:
                f = d.extended.get(r["effect"])
                row = {"hidden": name, "truth": f"{strength:.4g}", "verdict": d.verdict, "cause": d.cause,
                       "candidate": r["effect"], "base_status": d.base.status,
                       "base_chi2": f"{d.gain['base']:.1f}", "seconds": f"{d.seconds:.0f}"}
                if f is not None:
                    row.update(status=f.status, chi2=f"{f.chi2:.1f}", behind=f"{f.chi2 - best:.1f}")
                if "lr" in r:
                    low, high = r["interval"][r["effect"]]
                    row.update(lr=f"{r['lr']:.1f}", estimate=f"{r['estimate'][r['effect']]:.4g}",
                               low=f"{low:.4g}", high=f"{high:.4g}",
                               holds=(low < strength < high) if r["effect"] == name else "")
                if "held_out_gain" in r:
                    row["held_out_gain"] = f"{r['held_out_gain']:.1f}"
                writer.writerow(row)
                fh.flush()
            print(name, d.verdict, d.cause, d.evidence, flush=True)
    tmp.replace(out)


def null(first: int, last: int) -> None:
    out = HERE / "tie_null.csv"
    bases = [TOY, *(changed(c) for c in DESIGNS["two more walks: slope x0.8, balance masses 1 cm out"])]
    for seed in range(first, last):
        d = diagnose_walks([walk(b, 10 * seed + k) for k, b in enumerate(bases)], bases, model="periodic",
                           free=FREE)
        best = max(d.ranking, key=lambda r: abs(r.get("score_z", 0.0)))
        row = {"seed": seed, "verdict": d.verdict, "cause": d.cause or "", "largest_score": best["effect"],
               "z": f"{best.get('score_z', float('nan')):.2f}", "base_status": d.base.status,
               "seconds": f"{d.seconds:.0f}"}
        _append(out, row)
        print(row, flush=True)


if __name__ == "__main__":
    if sys.argv[1:2] == ["joint"]:
        joint()
    elif sys.argv[1:2] == ["null"] and len(sys.argv) == 4:
        null(int(sys.argv[2]), int(sys.argv[3]))
    elif sys.argv[1:]:
        sys.exit(__doc__)
    else:
        main()
