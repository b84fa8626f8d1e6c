"""The hand launch against the fore-aft margin: docs/gaits.md section 7's "what to do next", measured.

Section 7 found no walker that walks into its gait from a hand launch, and blamed the fore-aft
margin h - r (the centre of mass above the feet's fore-aft centre of curvature): with a positive
one the walker at rest falls forward, the first step comes too early for the swing leg, and every
stable gait found had a margin of 15-46 mm. This script follows the stable gaits of
docs/robust_best.toml (the rigid design search's best, docs/gaits.md section 7) and
data/params/clearing-toy.toml towards a smaller margin by pseudo-arclength continuation
(:func:`toywalk.model.continuation.continue_branch`, Newton from the previous fixed point, folds
and stability changes reported) in

- ``foot_radius`` r (raised; the box of docs/make_clearance_design.py ends at 30 mm, the paths go
  on to 60 mm, past a zero margin),
- ``com_offset[2]`` d_z (lowered, to -148 mm: the legs' centre of mass stays above the foot's
  bottom, 150 mm below the hip),
- ``slope`` (down to 0.01 rad: the gait gets slower, its start closer to rest),

and measures every branch point: the margin (:func:`fore_aft_margin`), max |eigenvalue|, the swing
foot's clearance, ``can_stand``, step time, stride, the stance leg's rate just after heel strike
and the walker's kinetic energy there (over M g l), the distance of a launch from rest to the
fixed point, and the hand launch at 0.5-3 x the gait's lean amplitude as docs/make_robust_design.py
walks and scores it (:func:`launch_walk`: steps walked, why it stopped, closest approach d_min to the
fixed point in state_scale units, 150 steps at most). A grid of :data:`GRID` x :data:`GRID`
designs, foot radius (so margin) against slope on robust_best's r path, each gait followed in slope
from the path by :func:`toywalk.model.gait.continue_gait`, gives the 2D picture; from each grid
radius's slowest stable gait the branch is followed on down in slope to where it folds or loses
stability (:func:`to_fold`), the slow end of the window, where the gait starts each step closest
to rest; and from each of those paths' design whose launch at 1.5 x lean walks furthest, the gait
is followed in hip width down to 30 mm (:func:`narrow_hips`). The shipped
walkers with a stable gait (and paper-toy, whose gait is the real toy's, unstable) are measured
the same way.

Outputs: docs/launch_margin.csv (one row a design: ``path`` names the path, ``grid`` the grid,
``fold r ...`` and ``hips r ...`` the slope and hip-width paths, ``shipped`` the shipped walkers;
1.5 MB), docs/launch_margin.png; if any design's launches at 1.5 and 2.5 x lean both walk
:data:`HEADLINE_STEPS` steps, docs/launch_best.toml (the design that comes closest, its fixed
point as ``[gait] start``); if any design's launch converges at some tip, docs/launch_converging.toml
(the one with the most clearance, checked by :func:`hand_launch` over tips and headings), and
with ``--window`` that design followed in slope and hip width, the tips that converge at each
point (:func:`converging_window`, docs/launch_converging.csv).

Run (2 cores shared with another job, compiled kernels cached: 1361 s for 3912 designs,
most of it ``can_stand`` at 0.5 s a design; the hip-width paths alone, from the CSV, 160 s; the
windows 80 s)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_margin.py
    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_margin.py --hips-only
    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_margin.py --window
    OPENBLAS_NUM_THREADS=1 .venv/bin/python docs/make_launch_margin.py --plot-only
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
from toywalk.model import GaitNotFound, Walker, can_stand, load_params, save_params, solve_fixed_point
from toywalk.model.basin import LAUNCH_MULTIPLES, hand_launch, launch_state
from toywalk.model.continuation import continue_branch
from toywalk.model.gait import continue_gait, state_scale
from toywalk.model.parameters import ParameterError

sys.path.insert(0, str(Path(__file__).resolve().parent))
# The launch as the design search walks and scores it, and its fore-aft margin.
from make_clearance_design import Z_STABLE  # noqa: E402
from make_robust_design import fore_aft_margin, launch_walk  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: (walker, continued parameter, end value): the paths from the two shipped feasible walkers.
PATHS = (
    ("robust_best", "foot_radius", 0.06),
    ("robust_best", "com_offset[2]", -0.148),
    ("robust_best", "slope", 0.01),
    ("clearing-toy", "foot_radius", 0.06),
    ("clearing-toy", "com_offset[2]", -0.148),
    ("clearing-toy", "slope", 0.01),
)
#: Largest arclength step of the paths, in units of the path's range: 0.02 of 48 mm of foot radius
#: is 1 mm, fine enough to stay on branches that section 7's search (steps of 0.3-10 % of the box
#: in all eleven parameters at once) kept losing.
DS_MAX = 0.02
#: Shipped walkers measured for comparison: (file, its gait is stable).
SHIPPED = ("robust_best", "clearing-toy", "stable-toy", "paper-toy")
#: The grid: GRID foot radii along robust_best's r path x GRID slopes.
GRID = 15
GRID_RADII = (0.0114591, 0.05)  # m: robust_best's own to a margin of about -7 mm
GRID_SLOPES = (0.01, 0.10)  # rad
#: The slope paths from the grid's slowest stable gaits: how low they are followed, and how often
#: ``can_stand`` is checked on them.
FOLD_END = 0.005  # rad
FOLD_STAND = 10
#: The hip-width paths from the slow end go down to this (m; robust_best's hips are 94 mm apart).
HIPS_END = 0.03
#: A launch that walks this many steps at 1.5 and 2.5 x lean is the headline (issue 44's tips).
HEADLINE_STEPS = 30
HEADLINE_MULTIPLES = (1.5, 2.5)
#: Tips (multiples of the lean amplitude) at which docs/launch_converging.toml's launch is checked.
CONVERGING_TIPS = (0.5, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.5, 2.0, 2.5)
#: How far up in slope docs/launch_converging.toml is followed (rad).
WINDOW_SLOPE = 0.03
COLUMNS = ["path", "walker", "parameter", "value", "foot_radius", "com_offset[2]", "slope", "margin_mm",
           "max_abs_eigenvalue", "stable", "clearance_mm", "can_stand", "step_time", "stride_mm", "lean_deg",
           "stance_rate", "stance_rate_scaled", "kinetic_mgl", "rest_distance",
           *(f"{k}_{m:g}" for m in LAUNCH_MULTIPLES for k in ("steps", "reason", "dmin")),
           "best_dmin", *(f"z{i}" for i in range(8))]


def walker_path(name: str) -> Path:
    """A walker's parameter file by name: docs/robust_best.toml, or data/params/NAME.toml."""
    return HERE / "robust_best.toml" if name == "robust_best" else ROOT / "data" / "params" / f"{name}.toml"


def kinetic_energy(walker: Walker, z: np.ndarray) -> float:
    """The walker's kinetic energy at public state ``z`` (J): its energy less that of the same
    configuration at rest."""
    rest = np.array(z, dtype=float)
    rest[1::2] = 0.0
    return walker.energy(walker.full_state(z)) - walker.energy(walker.full_state(rest))


def measure(params, gait, path: str, walker_name: str, parameter: str, value: float,
            stand: bool = True) -> dict:
    """One design's row of :data:`COLUMNS`: its gait, ``can_stand`` and its hand launches."""
    walker = Walker(params)
    z = gait.fixed_point
    scale = state_scale(params)
    l, g = params.leg_length, params.gravity
    row = {"path": path, "walker": walker_name, "parameter": parameter, "value": value,
           "foot_radius": params.foot_radius, "com_offset[2]": params.com_offset[2], "slope": params.slope,
           "margin_mm": 1e3 * fore_aft_margin(params), "max_abs_eigenvalue": gait.max_abs_eigenvalue,
           "stable": int(gait.max_abs_eigenvalue < 1), "clearance_mm": 1e3 * gait.clearance,
           "can_stand": int(can_stand(params).can_stand) if stand else "",
           "step_time": gait.step_time, "stride_mm": 1e3 * gait.stride_length,
           "lean_deg": math.degrees(gait.lean_amplitude), "stance_rate": z[5],
           "stance_rate_scaled": z[5] * math.sqrt(l / g),
           "kinetic_mgl": kinetic_energy(walker, z) / (params.total_mass * g * l),
           "rest_distance": float(np.linalg.norm((launch_state(1.5 * gait.lean_amplitude) - z) / scale)),
           **{f"z{i}": v for i, v in enumerate(z)}}
    for m in LAUNCH_MULTIPLES:
        walk = launch_walk(walker, gait, m * gait.lean_amplitude)
        row.update({f"steps_{m:g}": walk["steps"], f"reason_{m:g}": walk["reason"],
                    f"dmin_{m:g}": walk["dmin"]})
    row["best_dmin"] = min(row[f"dmin_{m:g}"] for m in LAUNCH_MULTIPLES)
    return row


def follow(params, parameter: str, end: float, z_start: np.ndarray, path: str, walker_name: str,
           stand_every: int = 1, max_points: int = 400) -> list[dict]:
    """The gait of ``params`` (near ``z_start``) followed to ``parameter = end`` by
    :func:`continue_branch`, every branch point measured (``can_stand`` at every ``stand_every``-th
    point and the last)."""
    t0 = time.perf_counter()
    branch = continue_branch(params, parameter, params.get(parameter), end, max_points=max_points, ds=0.005,
                             ds_max=DS_MAX, z_start=np.asarray(z_start, dtype=float), planar=False)
    print(f"{path}: {len(branch.points)} points, {branch.status} ({branch.message}), "
          f"{time.perf_counter() - t0:.0f} s", flush=True)
    for event in branch.events:
        print(f"  {event.kind} at {event.value:.6g}: {event.detail}", flush=True)
    rows = []
    for k, point in enumerate(branch.points):
        p = params.replace(**{parameter: point.value})
        try:
            gait = solve_fixed_point(Walker(p), point.fixed_point)
        except GaitNotFound as err:
            print(f"  {parameter} = {point.value:.6g}: the branch point does not solve again ({err})")
            continue
        stand = k % stand_every == 0 or k == len(branch.points) - 1
        rows.append(measure(p, gait, path, walker_name, parameter, point.value, stand=stand))
    _report(rows)
    print(f"  measured in {time.perf_counter() - t0:.0f} s", flush=True)
    return rows


def follow_shipped(walker_name: str, parameter: str, end: float) -> list[dict]:
    """A path of :data:`PATHS`: from the shipped walker's gait (its ``[gait] start``)."""
    params = load_params(walker_path(walker_name))
    return follow(params, parameter, end, np.array(params.gait_start), f"{walker_name} {parameter}",
                  walker_name)


def to_fold(grid_rows: list[dict]) -> list[dict]:
    """For each grid radius, its gait at the lowest grid slope where it is stable, followed down in
    slope (to :data:`FOLD_END`) until the branch folds back: the slow end of the stable window,
    where the gait starts each step closest to rest. ``can_stand`` at every :data:`FOLD_STAND`-th
    point (on every path above it changes exactly where the fore-aft margin crosses 0, which the
    slope does not move)."""
    params = load_params(walker_path("robust_best"))
    rows = []
    for r in sorted({q["value"] for q in grid_rows}):
        stable = [q for q in grid_rows if q["value"] == r and q["stable"] == 1]
        if not stable:
            continue
        low = min(stable, key=lambda q: q["slope"])
        p = params.replace(foot_radius=float(r), slope=float(low["slope"]))
        z = np.array([low[f"z{i}"] for i in range(8)])
        rows += follow(p, "slope", FOLD_END, z, f"fold r {1e3 * r:.1f} mm", "robust_best",
                       stand_every=FOLD_STAND, max_points=150)
    return rows


def _report(rows: list[dict]) -> None:
    shown = rows[:: max(1, len(rows) // 12)]
    for r in shown + [q for q in rows[-1:] if q is not shown[-1]]:
        print(f"  {r['walker']} {r['parameter']} {r['value']:.5g}: margin {r['margin_mm']:6.2f} mm, |lambda| "
              f"{r['max_abs_eigenvalue']:.3f}, clear {r['clearance_mm']:.2f} mm, stands {r['can_stand']}, "
              f"T {r['step_time']:.3f} s, stride {r['stride_mm']:.0f} mm, rate {r['stance_rate']:.2f} rad/s, "
              f"K/Mgl {r['kinetic_mgl']:.4f}; launch steps " + " ".join(
                  f"{r[f'steps_{m:g}']}{r[f'reason_{m:g}'][:4]}" for m in LAUNCH_MULTIPLES)
              + f", d_min {r['best_dmin']:.3f}", flush=True)


def narrow_hips(rows: list[dict]) -> list[dict]:
    """From each slow-end path's design whose launch at 1.5 x lean walks furthest, the gait followed
    in hip width down to :data:`HIPS_END` (narrower hips: its lean slower, the lateral rocking
    that times the first step slower too), ``can_stand`` at every :data:`FOLD_STAND`-th point."""
    out = []
    for path in sorted({r["path"] for r in rows if str(r["path"]).startswith("fold")}):
        stable = [r for r in rows if r["path"] == path and r["stable"] == 1]
        if not stable:
            continue
        best = max(stable, key=lambda r: (r["steps_1.5"], -r["best_dmin"]))
        params = load_params(walker_path("robust_best"))
        p = params.replace(foot_radius=float(best["foot_radius"]), slope=float(best["slope"]))
        z = np.array([float(best[f"z{i}"]) for i in range(8)])
        out += follow(p, "hip_width", HIPS_END, z, "hips" + path[4:], "robust_best", stand_every=FOLD_STAND,
                      max_points=120)
    return out


def grid(rows_r: list[dict]) -> list[dict]:
    """:data:`GRID` foot radii on robust_best's r path x :data:`GRID` slopes: each radius's gait
    from the nearest path point, then followed in slope each way from robust_best's slope by
    :func:`continue_gait`; a slope past where the gait is lost gets no row."""
    params = load_params(walker_path("robust_best"))
    radii = np.linspace(*GRID_RADII, GRID)
    slopes = np.linspace(*GRID_SLOPES, GRID)
    out = []
    t0 = time.perf_counter()
    for r in radii:
        near = min(rows_r, key=lambda q: abs(q["value"] - r))
        base = params.replace(foot_radius=float(r))
        try:
            gait0 = solve_fixed_point(Walker(base), np.array([near[f"z{i}"] for i in range(8)]))
        except GaitNotFound:
            continue
        for side in (slopes[slopes < base.slope][::-1], slopes[slopes >= base.slope]):
            gait, p = gait0, base
            for s in side:
                target = base.replace(slope=float(s))
                try:
                    gait = continue_gait(p, target, gait.fixed_point, planar=False)
                except (GaitNotFound, ParameterError):
                    break
                p = target
                out.append(measure(p, gait, "grid", "robust_best", "foot_radius slope", float(r)))
        print(f"grid r = {1e3 * r:.1f} mm: {sum(q['value'] == r for q in out)} slopes with a gait, "
              f"{time.perf_counter() - t0:.0f} s", flush=True)
    return out


def shipped() -> list[dict]:
    rows = []
    for name in SHIPPED:
        params = load_params(walker_path(name))
        start = params.gait_start if params.gait_start is not None else Z_STABLE  # stable-toy's has none
        gait = solve_fixed_point(Walker(params), np.array(start))
        rows.append(measure(params, gait, "shipped", name, "", math.nan))
    _report(rows)
    return rows


def headline(rows: list[dict]) -> dict | None:
    """The design whose launches at :data:`HEADLINE_MULTIPLES` x lean both walk
    :data:`HEADLINE_STEPS` steps, a stable one first, then the closest approach, if any."""
    good = [r for r in rows if r["path"] != "shipped"
            and all(int(r[f"steps_{m:g}"]) >= HEADLINE_STEPS for m in HEADLINE_MULTIPLES)]
    return min(good, key=lambda r: (-r["stable"], float(r["best_dmin"]))) if good else None


def write_csv(rows: list[dict]) -> None:
    # five digits for the measurements, ten for the fixed point (a Newton start)
    write_rows(HERE / "launch_margin.csv", rows, COLUMNS, digits=5, fixed_point_digits=10)


def report_long(rows: list[dict]) -> None:
    """Print how many designs have a launch that walks :data:`HEADLINE_STEPS` steps, and the
    headline design, written to docs/launch_best.toml, if any."""
    for m in HEADLINE_MULTIPLES:
        long = [r for r in rows if int(r[f"steps_{m:g}"]) >= HEADLINE_STEPS]
        print(f"launch at {m:g} x lean walks {HEADLINE_STEPS}+ steps: {len(long)} designs, "
              f"{sum(r['stable'] == 1 for r in long)} of them stable", flush=True)
    best = headline(rows)
    if best is None:
        print(f"no design walks {HEADLINE_STEPS} steps from both 1.5 and 2.5 x lean", flush=True)
    else:
        print(f"headline: {best}", flush=True)
        write_best(best)
    converging = [r for r in rows if r["path"] != "shipped"
                  and any(r[f"reason_{m:g}"] == "recovered" for m in LAUNCH_MULTIPLES)]
    print(f"a launch converges at some tip: {len(converging)} designs", flush=True)
    if converging:
        first = max(converging, key=lambda r: (r["clearance_mm"], -r["max_abs_eigenvalue"]))
        write_best(first, HERE / "launch_converging.toml", check=CONVERGING_TIPS)


def write_best(row: dict, path: Path = HERE / "launch_best.toml", check: tuple = ()) -> None:
    """``row``'s design to ``path``, its fixed point as ``[gait] start``; with ``check`` (multiples of
    the lean amplitude), :func:`hand_launch` at those tips and headings 0, +-1 and 2 degrees (400
    steps) says in the header where it converges."""
    params = load_params(walker_path(row['walker']))
    changes = {"foot_radius": float(row["foot_radius"]), "slope": float(row["slope"]),
               "com_offset[2]": float(row["com_offset[2]"])}
    if str(row["path"]).startswith("hips"):
        changes["hip_width"] = float(row["value"])
    params = params.replace(**changes)
    gait = solve_fixed_point(Walker(params), np.array([float(row[f"z{i}"]) for i in range(8)]))
    note = ""
    if check:
        headings = (0.0, math.radians(1), -math.radians(1), math.radians(2))
        launch = hand_launch(params, [m * gait.lean_amplitude for m in check], headings=headings, gait=gait,
                             steps=400)
        lines = []
        for heading, ok in zip(headings, launch.recovered(), strict=True):
            tips = " ".join(f"{m:g}" for m, k in zip(check, ok, strict=True) if k) or "none"
            lines.append(f"heading {math.degrees(heading):+.0f} deg: {tips}")
        note = (f"\nhand_launch (400 steps, tips {min(check):g}-{max(check):g} x lean) converges at "
                + "; ".join(lines) + f" x lean ({math.degrees(gait.lean_amplitude):.3f} deg).")
        print(f"{path.name}:{note}", flush=True)
    if path.name == "launch_converging.toml":
        title = ("The first design of docs/make_launch_margin.py whose hand launch converges to its gait "
                 f"({row['path']},\nhip width {1e3 * params.hip_width:.1f} mm)")
    else:
        title = f"A walker launched by hand from docs/make_launch_margin.py ({row['path']})"
    header = (f"{title}: fore-aft margin {1e3 * fore_aft_margin(params):.2f} mm, max |eigenvalue| "
              f"{gait.max_abs_eigenvalue:.3f},\nclearance {1e3 * gait.clearance:.2f} mm, can_stand "
              f"{can_stand(params).can_stand}; launch steps at 1.5 / 2.5 x lean {int(row['steps_1.5'])} / "
              f"{int(row['steps_2.5'])} ({row['reason_1.5']} / {row['reason_2.5']}).{note}\n"
              "[gait] start is its fixed point.")
    save_params(dataclasses.replace(params, gait_start=tuple(float(v) for v in gait.fixed_point)), path,
                header=header)


def fmt_cell(v, digits: int = 7):
    """A CSV cell: a float to ``digits`` significant digits, anything else as it is."""
    return f"{v:.{digits}g}" if isinstance(v, float) else v


def fmt_row(row: dict, digits: int = 6, fixed_point_digits: int | None = None) -> dict:
    """A row's cells (:func:`fmt_cell`), the fixed point's (columns ``z0``..``z7``, any key starting
    with ``z``) to ``fixed_point_digits`` when given: they are Newton starts."""
    return {k: fmt_cell(v, fixed_point_digits if fixed_point_digits and k[0] == "z" else digits)
            for k, v in row.items()}


def write_rows(path: Path, rows: list[dict], columns: list[str] | None = None, digits: int = 6,
               fixed_point_digits: int | None = None) -> None:
    """A CSV of ``rows`` (:func:`fmt_row`), ``columns`` those of the first row unless given (a row
    without one of them leaves its cell empty)."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]) if columns is None else columns)
        writer.writeheader()
        writer.writerows(fmt_row(r, digits, fixed_point_digits) for r in rows)


def parse_pair(parser, text: str | None, option: str, form: str = "START:END",
               scale: float = 1.0) -> tuple[float, float] | None:
    """The two numbers of an option written ``A:B`` (``form`` names them in the error), times
    ``scale``; None when the option was not given. Anything else ends the run with ``parser``'s
    one-line usage error."""
    if text is None:
        return None
    try:
        values = tuple(scale * float(v) for v in text.split(":"))
    except ValueError:
        values = ()
    if len(values) != 2:
        parser.error(f"{option} must be {form}, got {text!r}")
    return values


def read_rows(path: Path) -> list[dict]:
    """A CSV's rows, every cell that reads as a number a float (the others as they are)."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k, v in r.items():
            try:
                r[k] = float(v)
            except (TypeError, ValueError):
                pass
    return rows


def plot(rows: list[dict]) -> None:
    """docs/launch_margin.png: (a) max |eigenvalue| and (b) launch steps along the r and d_z paths
    against the fore-aft margin; (c) the closest approach of the launches against the gait's kinetic
    energy at heel strike, every design; (d) the grid of foot radius (margin) x slope."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    colours = {"robust_best foot_radius": "tab:blue", "robust_best com_offset[2]": "tab:orange",
               "clearing-toy foot_radius": "tab:red", "clearing-toy com_offset[2]": "tab:purple"}
    for path, colour in colours.items():
        sel = [r for r in rows if r["path"] == path]
        x = [r["margin_mm"] for r in sel]
        axes[0, 0].plot(x, [r["max_abs_eigenvalue"] for r in sel], "-", color=colour, label=path)
        stands = [r for r in sel if r["can_stand"] == 1]
        axes[0, 0].plot([r["margin_mm"] for r in stands], [r["max_abs_eigenvalue"] for r in stands], "x",
                        color=colour, ms=3)
        for m, style in ((1.5, ":"), (2.5, "--")):
            axes[0, 1].plot(x, [r[f"steps_{m:g}"] for r in sel], style, color=colour)
    ax = axes[0, 0]
    ax.axhline(1, color="0.5", lw=0.8)
    ax.axvline(0, color="0.5", lw=0.8)
    ax.set_ylim(0.8, 1.3)
    ax.set_xlabel("fore-aft margin h - r (mm)")
    ax.set_ylabel("max |eigenvalue| (x: can stand)")
    ax.set_title("(a) the paths in foot radius and leg COM height", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.set_xlabel("fore-aft margin h - r (mm)")
    ax.set_ylabel("steps walked from a launch at 1.5 (:) and 2.5 (--) x lean")
    ax.set_title("(b) the same paths: hand launches", fontsize=9)
    ax.axvline(0, color="0.5", lw=0.8)
    ax = axes[1, 0]
    kinds = (("robust_best foot_radius", "tab:blue"), ("robust_best com_offset[2]", "tab:orange"),
             ("robust_best slope", "tab:green"), ("clearing-toy", "tab:red"), ("grid", "0.4"),
             ("fold", "tab:cyan"), ("hips", "tab:pink"))
    for prefix, colour in kinds:
        sel = [r for r in rows if r["path"].startswith(prefix)]
        for stable, marker in ((1, "o"), (0, ".")):
            s = [r for r in sel if r["stable"] == stable]
            ax.plot([r["kinetic_mgl"] for r in s], [r["best_dmin"] for r in s], marker, color=colour, ms=3,
                    alpha=0.6, label=f"{prefix} ({'stable' if stable else 'unstable'})" if s else None)
    for r in (r for r in rows if r["path"] == "shipped"):
        ax.plot(r["kinetic_mgl"], r["best_dmin"], "k*", ms=10)
        ax.annotate(r["walker"], (r["kinetic_mgl"], r["best_dmin"]), fontsize=7, xytext=(4, 2),
                    textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("kinetic energy just after heel strike / (M g l)")
    ax.set_ylabel("closest approach of the launches at 0.5-3 x lean (state units)")
    ax.set_title("(c) every design: how far the gait starts from rest", fontsize=9)
    ax.legend(fontsize=6, ncol=2, loc="lower right")
    ax = axes[1, 1]
    g = [r for r in rows if r["path"] == "grid"]
    if g:
        stable = np.array([r["stable"] == 1 for r in g])
        walked = np.array([min(r["steps_1.5"], r["steps_2.5"]) for r in g])
        x = np.array([r["slope"] for r in g])
        y = np.array([r["margin_mm"] for r in g])
        ax.scatter(x[~stable], y[~stable], s=30, facecolors="none", edgecolors="0.5", label="unstable gait")
        sc = ax.scatter(x[stable], y[stable], s=40, c=walked[stable], cmap="viridis", vmin=0, vmax=20,
                        label="stable gait")
        fig.colorbar(sc, ax=ax, label="steps walked from 1.5 and 2.5 x lean (the fewer)")
        stands = np.array([r["can_stand"] == 1 for r in g])
        ax.plot(x[stands], y[stands], "r+", ms=8, label="can stand")
        fold = [r for r in rows if r["path"].startswith("fold") and r["stable"] == 1]
        if fold:
            ax.scatter([r["slope"] for r in fold], [r["margin_mm"] for r in fold], s=6,
                       c=[min(r["steps_1.5"], r["steps_2.5"]) for r in fold], cmap="viridis", vmin=0, vmax=20,
                       marker="s", label="stable, followed down in slope to the fold")
        ax.set_xlabel("slope (rad)")
        ax.set_ylabel("fore-aft margin (mm; robust_best, foot radius 11.5-50 mm)")
        ax.set_title("(d) margin x slope: stability and hand launch", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(HERE / "launch_margin.png", dpi=110)


def converging_window() -> None:
    """docs/launch_converging.toml followed in slope (up to :data:`WINDOW_SLOPE`) and in hip width
    (both ways) by :func:`continue_branch`; at every branch point :func:`hand_launch` at
    :data:`CONVERGING_TIPS` x lean, heading 0, 400 steps: which tips converge. Written to
    docs/launch_converging.csv (one row a design)."""
    params = load_params(HERE / "launch_converging.toml")
    z = np.array(params.gait_start)
    rows = []
    for name, end in (("slope", WINDOW_SLOPE), ("hip_width", 0.03), ("hip_width", 0.094)):
        branch = continue_branch(params, name, params.get(name), end, max_points=120, ds=0.005, ds_max=DS_MAX,
                                 z_start=z, planar=False)
        print(f"launch_converging.toml, {name} to {end:g}: {len(branch.points)} points, {branch.status}",
              flush=True)
        done = []
        for point in branch.points:
            p = params.replace(**{name: point.value})
            try:
                gait = solve_fixed_point(Walker(p), point.fixed_point)
            except GaitNotFound:
                continue
            launch = hand_launch(p, [m * gait.lean_amplitude for m in CONVERGING_TIPS], gait=gait, steps=400)
            ok = launch.recovered()[0]
            tips = " ".join(f"{m:g}" for m, k in zip(CONVERGING_TIPS, ok, strict=True) if k)
            done.append({"parameter": name, "value": point.value,
                         "max_abs_eigenvalue": gait.max_abs_eigenvalue, "clearance_mm": 1e3 * gait.clearance,
                         "lean_deg": math.degrees(gait.lean_amplitude), "converges_at": tips,
                         "steps": " ".join(str(r.steps) for r in launch.results[0])})
        rows += done
        for r in done[:: max(1, len(done) // 10)] + done[-1:]:
            print(f"  {r['parameter']} {r['value']:.6g}: |lambda| {r['max_abs_eigenvalue']:.4f}, clear "
                  f"{r['clearance_mm']:.2f} mm, converges at {r['converges_at'] or '-'} x lean", flush=True)
    write_rows(HERE / "launch_converging.csv", rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot-only", action="store_true", help="redraw docs/launch_margin.png from the CSV")
    parser.add_argument("--no-grid", action="store_true", help="skip the margin x slope grid")
    parser.add_argument("--window", action="store_true",
                        help="only the windows of docs/launch_converging.toml (docs/launch_converging.csv)")
    parser.add_argument("--hips-only", action="store_true",
                        help="only the hip-width paths, from the slow-end paths in the CSV (rows replaced)")
    args = parser.parse_args()
    out = HERE / "launch_margin.csv"
    if args.window:
        converging_window()
        return
    if not (args.plot_only or args.hips_only):
        t0 = time.perf_counter()
        rows = shipped()
        path_rows = {}
        for walker_name, parameter, end in PATHS:
            path_rows[(walker_name, parameter)] = follow_shipped(walker_name, parameter, end)
            rows += path_rows[(walker_name, parameter)]
        if not args.no_grid:
            grid_rows = grid(path_rows[("robust_best", "foot_radius")])
            rows += grid_rows + to_fold(grid_rows)
        write_csv(rows)
        # the hip-width paths start from the written rows, as --hips-only does, so that the two agree
        rows = read_rows(out)
        rows += narrow_hips(rows)
        write_csv(rows)
        report_long(rows)
        print(f"{len(rows)} designs, {time.perf_counter() - t0:.0f} s", flush=True)
    elif args.hips_only:
        t0 = time.perf_counter()
        rows = [r for r in read_rows(out) if not str(r["path"]).startswith("hips")]
        rows += narrow_hips(rows)
        write_csv(rows)
        report_long(rows)
        print(f"{len(rows)} designs, {time.perf_counter() - t0:.0f} s", flush=True)
    plot(read_rows(out))


if __name__ == "__main__":
    main()
