"""``toywalk gait --params P.toml``: find the walker's gait and its stability; with ``--continue
NAME FROM TO --out TABLE.csv``, follow the gait family in one parameter (table, events and plot);
with ``--all``, every distinct gait found from many starts, and with ``--out GAITS.csv`` each of
them followed in slope (table, families and plot)."""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

from toywalk.model.files import staged_files

from .common import CommandError, load_walker, output_path, with_effects

__all__ = ["cmd_gait", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("gait", help="find the symmetric gait and its stability")
    p.add_argument("--params", required=True, help="parameter TOML file")
    p.add_argument("--effect", action="append", metavar="NAME=VALUE",
                   help="set an effect's strength (repeatable; `toywalk effects` lists them)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--continue", dest="continue_", nargs=3, metavar=("NAME", "FROM", "TO"),
                   help="follow the gait family in parameter NAME from FROM to TO")
    p.add_argument("--points", type=int, default=None,
                   help="with --continue: at most this many gaits (default 100); with --all --out: a "
                        "side of each family (default 60)")
    p.add_argument("--out", help="with --continue: table TABLE.csv (plot and events beside it); with "
                                 "--all: each gait followed in slope, table GAITS.csv (plot and "
                                 "families beside it)")
    p.add_argument("--slopes", nargs=2, type=float, metavar=("LOW", "HIGH"),
                   help="with --all --out: the slope range (rad) to follow each gait over (default "
                        "half to one and a half times the walker's)")
    p.add_argument("--basin", action="store_true",
                   help="also the basin: radii along eigenvectors and random directions, hand launches")
    p.add_argument("--directions", type=int, default=20, metavar="N",
                   help="with --basin: random directions (default 20)")
    p.add_argument("--seed", type=int, default=0,
                   help="with --basin: seed of the random directions; with --all: of the random starts")
    p.add_argument("--all", dest="all_gaits", action="store_true",
                   help="every distinct gait found from many starts (model.gait_search.all_gaits)")
    p.add_argument("--random-starts", type=int, default=0, metavar="N",
                   help="with --all: also N random starts (default 0)")
    p.add_argument("--soft-steps", type=int, default=None, metavar="N",
                   help="with effects.soft_heel on: RK4 steps per contact time constant of the "
                        "compliant heel strike (default 20; the report checks it at 4 x)")
    p.set_defaults(func=cmd_gait)


def cmd_gait(args) -> int:
    params = with_effects(load_walker(args.params), args.effect)
    if args.continue_:
        return _continue(args, params)
    if args.all_gaits:
        return _all_gaits(args, params)
    soft = params.effects.get("soft_heel", 0.0) > 0.0
    if args.soft_steps is not None:
        if not soft:
            raise CommandError("--soft-steps needs the soft heel strike on (--effect soft_heel=TAU)")
        if args.soft_steps < 1:
            raise CommandError(f"--soft-steps must be >= 1, got {args.soft_steps}")
        if args.basin:
            raise CommandError("--soft-steps is not taken by --basin, which walks at the default")
    gait = _find_gait(params, args.soft_steps)
    report = _gait_report(params, gait)
    if soft:
        report["strike_resolution"] = _strike_resolution(gait, args.soft_steps)
    if args.basin:
        from toywalk.model.basin import basin_report

        report["basin"] = basin_report(gait, n_random=args.directions, seed=args.seed)
    if args.json:
        json.dump(report, sys.stdout, indent=2, default=float)
        sys.stdout.write("\n")
    else:
        _print_gait(report)
        if soft:
            _print_strike_resolution(report["strike_resolution"])
        if args.basin:
            _print_basin(report["basin"])
    return 0


def _all_gaits(args, params) -> int:
    from toywalk.model.gait_search import FIXED_POINT_TOL, SAME_GAIT, all_gaits

    out, low, high, points = _slope_range(args, params)
    search = all_gaits(params, n_random=args.random_starts, seed=args.seed)
    report = {"gaits": [f.summary() for f in search.gaits], "starts": search.starts,
              "converged": search.converged, "seconds": search.seconds,
              "fixed_point_tol": FIXED_POINT_TOL, "same_gait": SAME_GAIT,
              "units": {"step_time": "s", "stride_length": "m", "angles": "rad", "clearance": "m"}}
    if out is not None and search.gaits:
        from toywalk.model.gait_search import follow_in_slope

        families = follow_in_slope(params, search, low, high, max_points=points)
        report["families"] = _write_families(params, search, families, out)
    if args.json:
        json.dump(report, sys.stdout, indent=2, default=float)
        sys.stdout.write("\n")
        return 0
    print(f"{len(search.gaits)} distinct gaits from {search.starts} starts ({search.converged} "
          f"converged, {search.seconds:.1f} s)")
    print(f"{'step time':>11s} {'stride':>9s} {'lean':>7s} {'steer':>7s} {'max|eig|':>9s} "
          f"{'stable':>6s} {'clearance':>9s}  found from")
    for row in report["gaits"]:
        print(f"{row['step_time']:9.6g} s {row['stride_length']:7.4g} m "
              f"{math.degrees(row['lean_amplitude']):5.3g}dg {math.degrees(row['steer_amplitude']):5.3g}dg "
              f"{row['max_abs_eigenvalue']:9.4g} {'yes' if row['stable'] else 'no':>6s} "
              f"{1e3 * row['clearance']:6.3g} mm  {row['how']} (+{row['found_from'] - 1} more)")
    for i, family in enumerate(report.get("families", []), start=1):
        print(f"gait {i} in slope: {family['summary']}")
    if out is not None:
        print(f"-> {out}, {out.with_suffix('.png')}, {out.with_suffix('.json')}" if search.gaits
              else f"no gait to follow: nothing written to {out}")
    return 0


def _slope_range(args, params) -> tuple[Path | None, float, float, int]:
    """``--all``'s output file, slope range and points a side, checked before the search runs."""
    if args.out is None:
        if args.slopes is not None:
            raise CommandError("--slopes needs --out GAITS.csv (the families are written there)")
        return None, math.nan, math.nan, 0
    out = output_path(args.out, (".csv",))
    own = float(params.slope)
    low, high = args.slopes if args.slopes is not None else (0.5 * own, 1.5 * own)
    if not (math.isfinite(low) and math.isfinite(high) and low <= own <= high and low < high):
        raise CommandError(f"--slopes LOW HIGH must hold the walker's slope {own:.6g} rad, "
                           f"got {low:g} {high:g}")
    return out, float(low), float(high), _points(args, 60)


def _points(args, default: int) -> int:
    """``--points``, or ``default`` where not given; refused below 2."""
    points = default if args.points is None else args.points
    if points < 2:
        raise CommandError(f"--points must be >= 2, got {points}")
    return points


def _family_summary(family) -> str:
    """Where a gait's family goes in slope: each side's end, its folds and stability changes."""
    parts = []
    for side, branch in (("down", family.down), ("up", family.up)):
        if branch is None:
            continue
        events = "; ".join(e.detail for e in branch.events)
        parts.append(f"{side}: {branch.status} ({branch.message})" + (f"; {events}" if events else ""))
    if family.joins is not None:
        parts.append(f"one family with gait {family.joins + 1}, through a fold")
    if family.why:
        parts.append(f"not followed {family.why}")
    return " | ".join(parts) if parts else "not followed"


def _write_families(params, search, families, out: Path) -> list[dict]:
    """Every family's gaits (CSV: a row per gait, its family's number first), each family's ends
    and events (JSON) and a plot (PNG), written atomically; returns the JSON's families."""
    import csv
    import io

    buf = io.StringIO()
    writer = csv.writer(buf)
    info = []
    for family in families:
        cols, rows = family.table()
        if buf.tell() == 0:
            writer.writerow(["gait", *cols])
        for row in rows:
            writer.writerow([family.gait + 1, *(repr(float(v)) for v in row)])
        info.append({"gait": family.gait + 1, "summary": _family_summary(family),
                     "sides": [{"side": side, "status": b.status, "message": b.message,
                                "events": [{"kind": e.kind, "value": e.value, "detail": e.detail}
                                           for e in b.events]}
                               for side, b in (("down", family.down), ("up", family.up)) if b is not None],
                     "not_followed": family.why,
                     "joins": None if family.joins is None else family.joins + 1})
    outputs = [out, out.with_suffix(".json"), out.with_suffix(".png")]
    with staged_files(outputs) as (csv_file, json_file, png):
        csv_file.write_text(buf.getvalue())
        json_file.write_text(json.dumps({"walker_slope": float(params.slope), "families": info},
                                        indent=2) + "\n")
        _plot_families(params, search, families, png)
    return info


def _plot_families(params, search, families, path: Path) -> None:
    """Step time and max |eigenvalue| against the slope (degrees), a colour per gait of the
    catalogue: solid where stable, dashed where not; the walker's own slope and its gaits marked,
    folds as open circles; the legend beside the axes, not on the curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True, layout="constrained")
    for family in families:
        colour = f"C{family.gait % 10}"
        pts = family.points
        x = np.degrees([p.value for p in pts])
        t = np.array([p.step_time for p in pts])
        eig = np.array([p.max_abs_eigenvalue for p in pts])
        stable = np.array([p.stable for p in pts])
        for k in range(len(pts) - 1):
            style = "-" if stable[k] and stable[k + 1] else "--"
            for ax, y in ((axes[0], eig), (axes[1], t)):
                ax.plot(x[k:k + 2], y[k:k + 2], style, color=colour, lw=2 if style == "-" else 1)
        gait = search.gaits[family.gait].gait
        label = (f"gait {family.gait + 1}: {gait.step_time:.4g} s, "
                 f"{'stable' if gait.stable else 'unstable'} ({gait.max_abs_eigenvalue:.3g})")
        for ax, y in ((axes[0], gait.max_abs_eigenvalue), (axes[1], gait.step_time)):
            ax.plot(math.degrees(params.slope), y, "o", color=colour, ms=7,
                    label=label if ax is axes[0] else None)
        for branch in family.branches:
            for event in branch.events:
                if event.kind != "fold":
                    continue
                j = int(np.argmin(np.abs(x - math.degrees(event.value))))
                for ax, y in ((axes[0], eig), (axes[1], t)):
                    ax.plot(x[j], y[j], "o", mfc="none", color=colour, ms=9)
    axes[0].axhline(1.0, color="k", lw=0.8, ls=":")
    axes[0].set_yscale("log")
    axes[0].set_ylabel("step-map max |eigenvalue|")
    axes[1].set_ylabel("step time (s)")
    axes[1].set_xlabel("slope (degrees)")
    for ax in axes:
        ax.axvline(math.degrees(params.slope), color="0.6", lw=0.8)
        ax.ticklabel_format(axis="x", useOffset=False)
    axes[1].yaxis.get_major_formatter().set_useOffset(False)
    axes[0].set_title("every gait found, followed in slope (solid: stable; dashed: unstable; "
                      "open circle: fold)", fontsize=9)
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)


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
    points = _points(args, 100)
    try:
        branch = continue_branch(params, name, start, end, max_points=points,
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


def _find_gait(params, soft_steps: int | None = None):
    from toywalk.model.gait import GaitNotFound, find_gait, solve_fixed_point
    from toywalk.model.walker import Walker

    try:
        gait = find_gait(params)
        if soft_steps is not None:
            gait = solve_fixed_point(Walker(params, planar=gait.planar, soft_steps_per_tau=soft_steps),
                                     gait.fixed_point)
        return gait
    except GaitNotFound as err:
        raise CommandError(f"no gait found: {err}") from err


def _strike_resolution(gait, soft_steps: int | None) -> dict:
    """The soft strike's integration checked at 4 x its steps per tau (model.gait.strike_resolution)."""
    from toywalk.model.gait import GaitNotFound, strike_resolution

    try:
        check = strike_resolution(gait, soft_steps)
    except GaitNotFound as err:
        return {"checked": False, "why": f"the gait was lost at 4 x the steps per tau: {err}"}
    return {"checked": True, **dataclasses.asdict(check), "eigenvalue_error": check.eigenvalue_error,
            "resolved": check.resolved}


def _print_strike_resolution(check: dict, out=None) -> None:
    from toywalk.model.gait import STRIKE_EIGENVALUE_RESOLUTION

    out = sys.stdout if out is None else out
    if not check["checked"]:
        print(f"soft strike       not checked: {check['why']}", file=out)
        return
    print(f"soft strike       integrated at {check['steps_per_tau']} RK4 steps per tau; at "
          f"{check['fine_steps_per_tau']}: max |eigenvalue| {check['fine_max_abs_eigenvalue']:.6g}, "
          f"step time {check['fine_step_time']:.6g} s, fixed point moved {check['shift']:.2g}", file=out)
    if not check["resolved"]:
        print(f"WARNING           the largest eigenvalue moves by {check['eigenvalue_error']:.3g} "
              f"(> {STRIKE_EIGENVALUE_RESOLUTION:g}) when the strike is integrated finer: the numbers above "
              f"carry that error; rerun with --soft-steps {check['fine_steps_per_tau']}", file=out)


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
