"""``toywalk simulate --params P.toml --steps N --out T.csv``: simulate steps from the walker's
gait and write them as a trajectory (with ``--noise``, measurement noise added to the angles)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from .common import CommandError, load_walker, output_path, scuffs_in, with_effects

__all__ = ["cmd_simulate", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("simulate", help="simulate steps from the gait and write a trajectory")
    p.add_argument("--params", required=True, metavar="P.toml", help="parameter TOML file (the walker)")
    p.add_argument("--steps", type=int, required=True, metavar="N",
                   help="steps to simulate from the gait's fixed point (heel strikes)")
    p.add_argument("--effect", action="append", metavar="NAME=VALUE",
                   help="set an effect's strength (repeatable; `toywalk effects` lists them)")
    p.add_argument("--noise", type=float, default=0.0, metavar="SD",
                   help="measurement noise SD added to the angles (rad; default 0: exact angles)")
    p.add_argument("--position-noise", type=float, default=0.0, metavar="M",
                   help="measurement noise SD added to the heel strikes' contact positions (m; "
                        "default 0: exact positions)")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help="random seed of the noise (default: fresh entropy, a different draw each run)")
    p.add_argument("--out", required=True, metavar="T.csv",
                   help="trajectory file T.csv (T.events.csv and T.json beside it)")
    p.set_defaults(func=cmd_simulate)


def cmd_simulate(args) -> int:
    params = with_effects(load_walker(args.params), args.effect)
    if args.steps < 1:
        raise CommandError(f"--steps must be >= 1, got {args.steps}")
    if not (args.noise >= 0 and math.isfinite(args.noise)):
        raise CommandError(f"--noise must be a finite standard deviation >= 0 (rad), got {args.noise}")
    if not (args.position_noise >= 0 and math.isfinite(args.position_noise)):
        raise CommandError("--position-noise must be a finite standard deviation >= 0 (m), got "
                           f"{args.position_noise}")
    out = output_path(args.out, (".csv",))
    info = _simulate_to_file(params, args.steps, out, args.noise, args.seed, str(args.params),
                             args.position_noise)
    scuffs = f"; {info['scuffs']}" if info["scuffs"] else ""
    print(f"{info['status']}: {info['message']}; {info['samples']} samples, "
          f"{info['heel_strikes']} heel strikes{scuffs} -> {out}")
    return 0 if info["status"] == "completed" else 1


def _simulate_to_file(params, steps: int, out: Path, noise: float, seed, source: str,
                      position_noise: float = 0.0) -> dict:
    from toywalk.model.gait import GaitNotFound
    from toywalk.model.simulate import gait_walk
    from toywalk.model.trajectory import write_trajectory

    try:
        table = gait_walk(params, steps, noise=noise, position_noise=position_noise, seed=seed, source=source,
                          progress=sys.stderr.isatty())
    except GaitNotFound as err:
        raise CommandError(f"no gait found: {err}") from err
    write_trajectory(table, out)
    meta = table.metadata
    return {"status": meta["status"], "message": meta["message"], "samples": len(table.time),
            "heel_strikes": len(table.events), "scuffs": scuffs_in(table, params.leg_length)}
