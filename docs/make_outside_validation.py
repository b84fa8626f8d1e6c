"""Measure what the discrepancy analysis says of walks whose physics lies outside its library.

    python docs/make_outside_validation.py KIND [SEED ...] [--out CSV] [--walks DIR] [--walks-only]
        [--effects NAMES] -> docs/outside_KIND.csv

KIND is one of the generators of tests/sysid/outside.py: ``contact`` (the clearing walker in
MuJoCo with soft, overdamped, slipping contacts), ``hinge_spring`` (the stable toy with a torsion
spring between the legs) or ``foot_profile`` (the clearing walker in MuJoCo on feet whose fore-aft
radius of curvature changes along the rim). No effect of the library is any of these, so a cause
named with confidence is a wrong one; "unexplained" (or a verdict that says the library explains
the walk only in part) is the honest answer, and "adequate" says the difference is below what the
walk can show.

Each walk (its generator's defaults: 20 heel strikes at 120 samples/s, 0.003 rad of noise, the
seed drawing the noise and a small perturbation of the start) is analysed by
``toywalk.sysid.discrepancy.diagnose`` with its default options, the base model the walker's
parameter file, ``free=['foot_radius', 'com_offset[1]']`` and one worker. One row per seed, written
as soon as it is measured (a killed run keeps its rows; seeds already in the table are skipped):
``seed, verdict, cause, causes``, the candidate the analysis named (else the best fitted one) with
its likelihood ratio against the base, its held-out gain (the base's held-out chi-square less
its own) and, where the analysis named it, the held-out chi-square of the base and of the
extended model and the held-out RMS of each signal (rad); the best fitted other candidate and
its likelihood ratio; where no cause was named, what the search of the port dictionary found
(``missing_force``: each term's port and form, coefficient, 95 % interval and unit; ``none``) and
why it stopped; the seconds the analysis took and its evidence (why that verdict). A walk
that cannot be made (the clearing walker falls in MuJoCo from some starts) is a row with verdict
``no walk`` and the reason.

``--effects`` gives the candidate effects (comma-separated, ``library`` for the library's; the
default is the library): ``--effects library,soft_heel`` adds the compliant heel strike, which
the analysis does not try by default. A column ``requested`` then says, for each effect named
beyond the library, its score, and its fit where it was fitted.

``--walks DIR`` keeps the walks as trajectory files (``KIND_SEED.csv``) and reads them from there
when present, so that the same walks can be analysed by another version of the analysis
(``--walks-only`` makes them without analysing). The baseline tables
``docs/outside_KIND_before.csv`` are the analysis of commit bba3775 (its packages unpacked by
``git archive`` and put first on ``PYTHONPATH``) on walks made this way by the generators.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the generators live in the tests' helper module

from toywalk.model.parameters import load_params  # noqa: E402
from toywalk.model.trajectory import SIGNALS, read_trajectory, write_trajectory  # noqa: E402

from tests.sysid.outside import KINDS, OutsideWalkError, walk  # noqa: E402

FREE = ["foot_radius", "com_offset[1]"]
#: The base model of each kind: the parameter file of the walker the generator walks.
PARAMS = {"contact": "clearing-toy.toml", "hinge_spring": "stable-toy.toml",
          "foot_profile": "clearing-toy.toml"}
#: Seeds when none are given.
SEEDS = (0, 2, 3)
#: The table's columns (module docstring).
COLUMNS = ["seed", "verdict", "cause", "causes", "candidate", "candidate_named", "lr", "held_out_gain",
           "held_out_chi2_base", "held_out_chi2_extended",
           *(f"rms_{which}_{name}" for which in ("base", "extended") for name in SIGNALS),
           "runner_up", "runner_up_lr", "missing_force", "missing_force_stop", "seconds", "evidence"]


def _append(path: Path, row: dict, columns: list = COLUMNS) -> None:
    new = not path.exists()
    with open(path, "a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns, restval="")
        if new:
            writer.writeheader()
        writer.writerow(row)
        fh.flush()


def _get(kind: str, seed: int, walks: Path | None):
    """The walk of ``kind`` and ``seed``: from ``walks`` where it is there, else made (and kept
    there)."""
    path = None if walks is None else walks / f"{kind}_{seed}.csv"
    if path is not None and path.exists():
        return read_trajectory(path)
    table = walk(kind, seed)
    if path is not None:
        walks.mkdir(parents=True, exist_ok=True)
        write_trajectory(table, path)
    return table


def _fmt(value) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.6g}"


def requested(d, names) -> str:
    """What the analysis ``d`` says of each effect in ``names``: its score z, and where it was
    fitted its estimate, standard error, likelihood ratio and IPOPT's status."""
    out = []
    for row in d.ranking:
        if row["effect"] not in names:
            continue
        text = f"{row['effect']}: score z {row['score_z']:+.2f}"
        if "estimate" in row:
            text += (f"; fitted {row['estimate'][row['effect']]:.4g} +- {row['std']:.2g}, "
                     f"lr {row['lr']:.4g} ({row['status']})")
        elif row.get("reason"):
            text += f"; not fitted: {row['reason']}"
        out.append(text)
    return " | ".join(out)


def row_of(seed: int, d, seconds: float) -> dict:
    """The table's row of one analysis ``d`` (a :class:`toywalk.sysid.discrepancy.Diagnosis`)."""
    from toywalk.sysid.missing_force import term_sentence

    fitted = [r for r in d.ranking if "lr" in r]
    named = d.causes[0] if d.causes else None
    pick = next((r for r in fitted if r["effect"] == named), fitted[0] if fitted else None)
    gain = d.gain or {}
    rms = gain.get("held_out_rms", {})
    row = {"seed": seed, "verdict": d.verdict, "cause": d.cause or "", "causes": ";".join(d.causes),
           "candidate": pick["effect"] if pick else "", "candidate_named": bool(named),
           "lr": _fmt(pick["lr"]) if pick else "",
           "held_out_gain": _fmt(pick.get("held_out_gain")) if pick else "",
           "held_out_chi2_base": _fmt(gain.get("base")), "held_out_chi2_extended": _fmt(gain.get("extended"))}
    for which in ("base", "extended"):
        for name in SIGNALS:
            row[f"rms_{which}_{name}"] = _fmt(rms.get(which, {}).get(name))
    others = [r for r in fitted if pick is None or r["effect"] != pick["effect"]]
    row["runner_up"] = others[0]["effect"] if others else ""
    row["runner_up_lr"] = _fmt(others[0]["lr"]) if others else ""
    found = d.missing_force
    if found is not None:
        row["missing_force"] = "; ".join(term_sentence(t) for t in found.terms) or "none"
        row["missing_force_stop"] = found.stop
    row["seconds"] = f"{seconds:.1f}"
    row["evidence"] = d.evidence
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=list(KINDS))
    parser.add_argument("seeds", nargs="*", type=int, default=list(SEEDS))
    parser.add_argument("--out", type=Path, help="the table (default docs/outside_KIND.csv)")
    parser.add_argument("--walks", type=Path, help="keep (and reuse) the walks in this folder")
    parser.add_argument("--walks-only", action="store_true", help="make the walks, do not analyse them")
    parser.add_argument("--effects", help="candidate effects, comma-separated ('library': the library's)")
    args = parser.parse_args(argv)
    from toywalk.model.effects import LIBRARY

    effects = None
    if args.effects:
        effects = [e for name in args.effects.split(",")
                   for e in (LIBRARY if name.strip() == "library" else (name.strip(),))]
    beyond = [f"effects.{e}" for e in effects or () if e not in LIBRARY]
    columns = COLUMNS + (["requested"] if beyond else [])
    if args.walks_only and args.walks is None:
        parser.error("--walks-only needs --walks DIR")
    out = args.out or HERE / f"outside_{args.kind}.csv"
    done = set()
    if out.exists() and not args.walks_only:
        with open(out) as fh:
            done = {int(r["seed"]) for r in csv.DictReader(fh)}
    from toywalk.sysid.discrepancy import diagnose

    params = load_params(HERE.parent / "data" / "params" / PARAMS[args.kind])
    for seed in args.seeds:
        if seed in done:
            continue
        clock = time.perf_counter()
        try:
            table = _get(args.kind, seed, args.walks)
        except OutsideWalkError as err:
            print(seed, "no walk:", err, flush=True)
            if not args.walks_only:
                _append(out, {"seed": seed, "verdict": "no walk", "cause": str(err)[:160], "causes": "",
                              "seconds": f"{time.perf_counter() - clock:.1f}"})
            continue
        if args.walks_only:
            print(seed, "walk made", flush=True)
            continue
        clock = time.perf_counter()
        d = diagnose(table, params, model="periodic", free=FREE, workers=1, effects=effects,
                     progress=lambda line: print("  ...", line, flush=True))
        row = row_of(seed, d, time.perf_counter() - clock)
        if beyond:
            row["requested"] = requested(d, beyond)
        _append(out, row, columns)
        print(seed, row["verdict"], row["cause"], row["candidate"], row["lr"], row.get("requested", ""),
              row["seconds"], flush=True)


if __name__ == "__main__":
    main()
