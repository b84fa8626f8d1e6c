"""toywalk: film a passive-dynamic walker, fit its model, and find what the model gets wrong.

The command line (every option: docs/cli.md). Every command exits non-zero with one clear line on
stderr for bad input, and never leaves a half-written output file behind.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

from toywalk.model.files import staged_files

__all__ = ["PROGRESS", "main", "say"]

#: How a progress line on stderr starts (every command's stages; the robustness suite tells them
#: from error lines by it).
PROGRESS = "... "


def say(message: str) -> None:
    """One progress line on stderr, flushed at once, whether stderr is a terminal, a file or a
    pipe: a stage that takes more than a few seconds says what it does before it starts, so that
    a log shows where a long run is (a progress bar, which redraws its line, only in a
    terminal)."""
    print(f"{PROGRESS}{message}", file=sys.stderr, flush=True)


class CommandError(Exception):
    """Bad input or an impossible request: printed as one line, exit status 2."""


def output_path(value: str, suffixes: tuple[str, ...], option: str = "--out") -> Path:
    """The path an option names for writing: one of ``suffixes`` (case-insensitive), in a folder
    that exists; otherwise :class:`CommandError` with one line."""
    out = Path(value)
    if out.suffix.lower() not in suffixes:
        raise CommandError(f"{option} must name a {' or '.join(suffixes)} file, got {out}")
    if not out.parent.is_dir():
        raise CommandError(f"output folder does not exist: {out.parent}")
    return out


def refuse_overwrite(outputs, inputs) -> None:
    """:class:`CommandError` (one line) when an output path is one of the input paths (None: none)."""
    given = {Path(p).resolve() for p in inputs if p is not None}
    clash = [p for p in outputs if p is not None and Path(p).resolve() in given]
    if clash:
        raise CommandError(f"the output would overwrite the input {clash[0]}; choose another --out name")


def parse_size(text: str) -> tuple[int, int]:
    """An image size ``WxH`` in pixels (16 to 8192 each), or a :class:`CommandError`."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as err:
        raise CommandError(f"--size must be WxH in pixels, e.g. 1280x720, got {text!r}") from err
    if w < 16 or h < 16 or w > 8192 or h > 8192:
        raise CommandError(f"--size must be between 16x16 and 8192x8192, got {text!r}")
    return w, h


def load_walker(path: str):
    """The parameter file ``path`` read, or its error as one :class:`CommandError` line."""
    from toywalk.model.parameters import ParameterError, load_params

    try:
        return load_params(path)
    except ParameterError as err:
        raise CommandError(str(err)) from err


def _find_gait(params):
    from toywalk.model.gait import GaitNotFound, find_gait

    try:
        return find_gait(params)
    except GaitNotFound as err:
        raise CommandError(f"no gait found: {err}") from err


def _gait_report(params, gait) -> dict:
    from toywalk.model.statics import can_stand
    from toywalk.model.walker import CLEARANCE_RESOLUTION

    report = gait.summary()
    standing = can_stand(params)
    report["can_stand"] = bool(standing.can_stand)
    report["standing"] = standing.reason
    report["clearance_resolution"] = CLEARANCE_RESOLUTION * params.leg_length  # 0 to round-off
    report["units"] = {"step_time": "s", "stride_length": "m", "angles": "rad",
                       "rates": "rad/s", "clearance": "m"}
    return report


def _print_gait(report: dict, out=None) -> None:
    from toywalk.model.walker import describe_scuffs

    out = sys.stdout if out is None else out  # looked up per call, not bound at import
    fp = report["fixed_point"]
    print(f"status            {report['status']}{' (planar reduction)' if report['planar'] else ''}",
          file=out)
    stride = report["map"] == "stride"
    if stride:
        print("periodic over     a stride (two steps): an effect breaks the left-right symmetry; "
              "eigenvalues are the stride map's", file=out)
        times = ", ".join(f"{t:.6g}" for t in report["step_times"])
        print(f"step times        {times} s  (stride {report['stride_time']:.6g} s)", file=out)
    else:
        print(f"step time         {report['step_time']:.6g} s  (stride {report['stride_time']:.6g} s)",
              file=out)
    print(f"stride length     {report['stride_length']:.6g} m", file=out)
    if stride:
        print(f"sideways drift    {report['stride_drift']:.4g} m per stride (heading "
              f"{math.degrees(report['heading']):.4g} deg from the fall line, left +)", file=out)
    print(f"lean amplitude    {math.degrees(report['lean_amplitude']):.4g} deg", file=out)
    print(f"steer amplitude   {math.degrees(report['steer_amplitude']):.4g} deg", file=out)
    print("fixed point (just after heel strike):", file=out)
    for name, value in fp.items():
        print(f"  {name:<14s} {value: .10g}", file=out)
    print(f"{report['map']}-map eigenvalues (|lambda|, dominant components):", file=out)
    for e in report["eigenvalues"]:
        print(f"  {e['re']: .6f} {e['im']:+.6f}i   |{e['abs']:.6f}|   {', '.join(e['dominant'])}",
              file=out)
    verdict = "stable" if report["stable"] else "unstable"
    print(f"max |eigenvalue|  {report['max_abs_eigenvalue']:.6g} ({verdict}; over 20 steps a "
          f"perturbation grows by {report['growth_factor_20_steps']:.3g})", file=out)
    lam = report.get("fold_eigenvalue")
    if lam is not None:
        print(f"at a fold         an eigenvalue {lam:.6g} lies {abs(1 - lam):.2g} from 1: the gait is at the "
              f"end of its branch, and a small change of slope or an effect can remove it", file=out)
    losses = ", ".join(f"{loss:.4g}" for loss in report["collision_loss"])
    print(f"collision loss    {losses} J per heel strike", file=out)
    swing, tol = report["swing_clearance"], report["clearance_resolution"]
    where = "as the legs pass" if swing["where"] == "legs passing" else (
        f"{1e3 * abs(swing['ahead']):.3g} mm {'ahead of' if swing['ahead'] > 0 else 'behind'} the "
        "stance foot")
    print(f"swing clearance   the swing foot {_height(report['clearance'], tol)} at its lowest "
          f"({100 * swing['phase']:.0f} % into the step, {where}); after the legs pass it "
          f"{_height(report['clearance_after_passing'], tol)}; it rises {1e3 * swing['apex']:.3g} mm "
          "at its highest", file=out)
    scuffs = describe_scuffs(report["scuffs"], report["period_steps"], report["clearance"], tol)
    print(f"scuffs            {scuffs or 'none before the legs pass'}", file=out)
    print(f"can stand         {report['can_stand']}: {report['standing']}", file=out)


def _height(height: float, resolution: float) -> str:
    """How the swing foot stands to the ramp at ``height`` (m), in mm: "clears the ramp by 3.48 mm",
    "touches the ramp (0 mm to round-off)" within ``resolution`` (m) of 0, or "goes 0.536 mm below
    the ramp"."""
    if height > resolution:
        return f"clears the ramp by {1e3 * height:.3g} mm"
    if height >= -resolution:
        return "touches the ramp (0 mm to round-off)"
    return f"goes {-1e3 * height:.3g} mm below the ramp"


def _with_effects(params, items):
    """``params`` with the command line's ``--effect NAME=VALUE`` settings."""
    from toywalk.model.parameters import ParameterError

    effects = _parse_effects(items)
    if not effects:
        return params
    try:
        return params.replace(**{f"effects.{k}": v for k, v in effects.items()})
    except ParameterError as err:
        raise CommandError(str(err)) from err


def cmd_gait(args) -> int:
    params = _with_effects(load_walker(args.params), args.effect)
    if args.continue_:
        return _continue(args, params)
    gait = _find_gait(params)
    report = _gait_report(params, gait)
    if args.basin:
        from toywalk.model.basin import basin_report

        report["basin"] = basin_report(gait, n_random=args.directions, seed=args.seed)
    if args.json:
        json.dump(report, sys.stdout, indent=2, default=float)
        sys.stdout.write("\n")
    else:
        _print_gait(report)
        if args.basin:
            _print_basin(report["basin"])
    return 0


def _print_basin(basin: dict, out=None) -> None:
    out = sys.stdout if out is None else out
    eig, rnd = basin["eigenvector_radius"], basin["random"]["radius"]
    print(f"basin             (sizes in {basin['units']}; scuffs "
          f"{'end a walk' if basin['scuffs_fail'] else 'let through, as the gait does'})", file=out)
    print(f"  along eigenvectors   min {eig['min']:.3g}  median {eig['median']:.3g}  max {eig['max']:.3g}"
          f"  ({len(basin['eigenvectors'])} directions)", file=out)
    if rnd is not None:
        print(f"  along random dirs    min {rnd['min']:.3g}  median {rnd['median']:.3g}  max {rnd['max']:.3g}"
              f"  ({basin['random']['n']} directions, seed {basin['random']['seed']})", file=out)
    for row in basin["hand_launch"]:
        verdict = "walks into the gait" if row["recovered"] else f"{row['reason']} after {row['steps']} steps"
        print(f"  hand launch tipped {math.degrees(row['tip']):5.2f} deg "
              f"({row['tip_over_lean']:.1f} x lean), heading {math.degrees(row['heading']):.1f} deg: "
              f"{verdict}", file=out)
    print(f"  ({basin['seconds']:.1f} s)", file=out)


def _continue(args, params) -> int:
    from toywalk.model.continuation import continue_branch
    from toywalk.model.gait import GaitNotFound
    from toywalk.model.parameters import ParameterError

    name, start, end = args.continue_
    try:
        start, end = float(start), float(end)
    except ValueError as err:
        raise CommandError(
            f"--continue NAME FROM TO: FROM and TO must be numbers, got {start!r} {end!r}"
        ) from err
    if args.out is None:
        raise CommandError("--continue needs --out TABLE.csv (the plot is written beside it)")
    out = output_path(args.out, (".csv",))
    if args.points < 2:
        raise CommandError(f"--points must be >= 2, got {args.points}")
    try:
        branch = continue_branch(params, name, start, end, max_points=args.points,
                                 progress=sys.stderr.isatty())
    except (ParameterError, ValueError) as err:
        raise CommandError(str(err)) from err
    except GaitNotFound as err:
        raise CommandError(f"no gait found at {name} = {start}: {err}") from err
    _write_branch(branch, out)
    for event in branch.events:
        print(event.detail)
    hint = " (more with a larger --points)" if branch.status == "max_points" else ""
    print(f"{branch.status}: {branch.message}{hint}; {len(branch.points)} gaits -> {out}, "
          f"{out.with_suffix('.png')}, {out.with_suffix('.json')}")
    return 0


def _write_branch(branch, out: Path) -> None:
    """Table (CSV), events and status (JSON) and a plot (PNG), each written atomically."""
    import csv
    import io

    cols, rows = branch.table()
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(cols)
    for row in rows:
        writer.writerow([repr(float(v)) for v in row])
    info = {"parameter": branch.name, "status": branch.status, "message": branch.message,
            "planar": branch.planar, "map": "step" if branch.period == 1 else "stride",
            "events": [{"kind": e.kind, "value": e.value, "detail": e.detail} for e in branch.events]}
    outputs = [out, out.with_suffix(".json"), out.with_suffix(".png")]
    with staged_files(outputs) as (csv_file, json_file, png):
        csv_file.write_text(buf.getvalue())
        json_file.write_text(json.dumps(info, indent=2) + "\n")
        _plot_branch(branch, rows, png)


def _plot_branch(branch, rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator
    from toywalk.model.parameters import parameter_unit

    fig, axes = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    x = rows[:, 0]
    stable = rows[:, 4] > 0.5
    axes[0].plot(x, rows[:, 3], "-", color="0.6", lw=1)
    axes[0].plot(x[stable], rows[stable, 3], "o", ms=3, label="stable")
    axes[0].plot(x[~stable], rows[~stable, 3], "x", ms=4, label="unstable")
    axes[0].axhline(1.0, color="k", lw=0.8, ls="--")
    axes[0].set_ylabel(f"{'step' if branch.period == 1 else 'stride'} map max |eigenvalue|")
    axes[0].legend(loc="best", fontsize=8)
    axes[1].plot(x, rows[:, 1], "-o", ms=3)
    axes[1].set_ylabel("step time (s)")
    axes[1].set_xlabel(f"{branch.name} ({parameter_unit(branch.name)})")
    for ax in axes:  # plain numbers: an offset ("1e-7+3.6951e-1") hides the values read off
        ax.ticklabel_format(useOffset=False)
    axes[1].xaxis.set_major_locator(MaxNLocator(nbins=6))  # room for their many digits
    axes[1].tick_params(axis="x", labelrotation=30)
    for event in branch.events:
        for ax in axes:
            ax.axvline(event.value, color="r" if event.kind != "fold" else "b", lw=0.8, alpha=0.7)
    axes[0].set_title(f"gait family in {branch.name}" + (" (planar reduction)" if branch.planar else ""))
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)


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
        print(f"{r['name']:<22s} [{r['unit']}] null {r['null']:g}, typical {r['typical']:g}, "
              f"bounds [{low:g}, {high:g}]; enters the {r['enters']}{symmetry}{port}")
        print(f"{'':<22s} {r['physics']}")
    return 0


def _parse_effects(items) -> dict:
    out = {}
    for item in items or ():
        if "=" not in item:
            raise CommandError(f"--effect expects NAME=VALUE, got {item!r}")
        name, value = item.split("=", 1)
        name = name.strip().removeprefix("effects.")
        try:
            out[name] = float(value)
        except ValueError as err:
            raise CommandError(f"--effect {name}: not a number: {value!r}") from err
    return out


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


def scuffs_in(table, leg_length: float) -> str:
    """The scuffs of a simulated walk, said as every command says them
    (:func:`toywalk.model.walker.describe_scuffs`), from its metadata (``scuffs``,
    ``swing_clearance_m``; counted over its heel strikes); "" for none, or a walk that does not
    record them (a tracked one)."""
    from toywalk.model.walker import CLEARANCE_RESOLUTION, describe_scuffs

    scuffs = table.metadata.get("scuffs")
    if not isinstance(scuffs, int) or isinstance(scuffs, bool) or scuffs <= 0:
        return ""
    lowest = table.metadata.get("swing_clearance_m")
    return describe_scuffs(scuffs, max(len(table.events), 1),
                           lowest if isinstance(lowest, (int, float)) else None,
                           CLEARANCE_RESOLUTION * leg_length)


def cmd_simulate(args) -> int:
    params = _with_effects(load_walker(args.params), args.effect)
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


#: The modules of the commands but gait, effects and simulate (here): each defines
#: ``register(subparsers)``, adding its sub-parser with ``set_defaults(func=...)``, and its
#: function raises :class:`CommandError` for bad input. Imported by name as the parser is built,
#: so that each imports this module's helpers inside its functions without an import cycle.
_COMMAND_MODULES = (
    "toywalk.sysid.cmd_calibrate",
    "toywalk.sysid.cmd_render",
    "toywalk.sysid.cmd_track",
    "toywalk.sysid.cmd_accuracy",
    "toywalk.sysid.cmd_fit",
    "toywalk.sysid.cmd_sample",
    "toywalk.sysid.cmd_diagnose",
    "toywalk.sysid.cmd_demo",
)


def build_parser() -> argparse.ArgumentParser:
    import importlib

    parser = argparse.ArgumentParser(prog="toywalk", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    p = sub.add_parser("gait", help="find the symmetric gait and its stability")
    p.add_argument("--params", required=True, help="parameter TOML file")
    p.add_argument("--effect", action="append", metavar="NAME=VALUE",
                   help="set an effect's strength (repeatable; `toywalk effects` lists them)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--continue", dest="continue_", nargs=3, metavar=("NAME", "FROM", "TO"),
                   help="follow the gait family in parameter NAME from FROM to TO")
    p.add_argument("--points", type=int, default=100, help="with --continue: at most this many gaits")
    p.add_argument("--out", help="with --continue: table TABLE.csv (plot and events beside it)")
    p.add_argument("--basin", action="store_true",
                   help="also the basin: radii along eigenvectors and random directions, hand launches")
    p.add_argument("--directions", type=int, default=20, metavar="N",
                   help="with --basin: random directions (default 20)")
    p.add_argument("--seed", type=int, default=0, help="with --basin: seed of the random directions")
    p.set_defaults(func=cmd_gait)
    p = sub.add_parser("effects", help="list the effect library")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_effects)
    p = sub.add_parser("simulate", help="simulate steps from the gait and write a trajectory")
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
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except CommandError as err:
        print(f"toywalk {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"toywalk {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout went away (`toywalk gait --json | head`): stop quietly, as Unix
        # tools do; point stdout at /dev/null so that Python's own flush at exit cannot raise
        # (https://docs.python.org/3/library/signal.html#note-on-sigpipe)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    # Run the imported module's main, so that command modules and this entry point share one
    # CommandError class (as __main__, this file would define a second one).
    from toywalk.sysid.cli import main as _main

    sys.exit(_main())
