"""``toywalk effects``: list the effect library (each effect's unit, null value, typical strength,
bounds, where it enters and its physics)."""

from __future__ import annotations

import json
import sys

__all__ = ["cmd_effects", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("effects", help="list the effect library")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_effects)


def cmd_effects(args) -> int:
    from toywalk.model.effects import EFFECTS

    rows = [e.describe() for e in EFFECTS.values()]
    if args.json:
        json.dump(rows, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    for r in rows:
        low, high = r["bounds"]
        symmetry = "; breaks the left-right symmetry" if r["breaks_symmetry"] else ""
        port = "; port-only (not a default cause of diagnose)" if r["port_only"] else ""
        if not r["port_only"] and not r["screened"]:
            port = f"; not a default cause of diagnose (its fits cost minutes): --effects library,{r['name']}"
        print(f"{r['name']:<22s} [{r['unit']}] null {r['null']:g}, typical {r['typical']:g}, "
              f"bounds [{low:g}, {high:g}]; enters the {r['enters']}{symmetry}{port}")
        print(f"{'':<22s} {r['physics']}")
    return 0
