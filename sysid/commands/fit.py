"""``toywalk fit M.csv --params P.toml --free NAME[,NAME...] --out F.json``: fit the model to a walk.

By default (``--model auto``) the walk is fitted both as a repeated gait and as a transient from a
free start, and the periodicity test (:func:`toywalk.sysid.fit.periodicity_test`) chooses: a walk
released off its cycle fitted as a gait gives biased parameters. ``--model periodic`` or
``transient`` fits one model only.

Whatever takes more than a few seconds says one line on stderr before it starts, flushed, whether
stderr is a terminal, a file or a pipe (:func:`toywalk.sysid.commands.common.say`): under ``--model auto``
each of the periodicity test's fits and the chosen fit (``... the transient model, on its own heel
strikes``), with ``--model`` each stage of the one fit, with ``--multistart`` each start. A long
walk's default fit takes a minute or more (60 steps off its cycle: 56 s).

``--multistart`` fits from the user's parameters and from one start per shipped parameter set
(:func:`toywalk.sysid.multistart.multi_start`), writes the best fit with a ``multistart`` block
(every run and the distinct optima), and says whether the starts agree.
"""

from __future__ import annotations

import math
import sys

from toywalk.model.files import software_version

from .common import CommandError, load_walker, output_path, say

__all__ = ["cmd_fit", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("fit", help="fit free parameters of the model to a measured walk")
    p.add_argument("trajectory", metavar="M.csv", help="measured walk (trajectory file)")
    p.add_argument("--params", required=True, help="parameter TOML file: the start and the fixed values")
    p.add_argument("--free", required=True, metavar="NAME[,NAME...]",
                   help="parameters to fit: foot_radius, com_offset[1], effects.hip_damping, ...")
    p.add_argument("--out", required=True, help="fit file F.json to write")
    p.add_argument("--no-offsets", action="store_true",
                   help="do not fit the ramp-frame offsets of lean, steer and pitch")
    p.add_argument("--model", choices=("auto", "periodic", "transient"), default="auto",
                   help="the walk as a repeated gait, as a transient from a free start, or both "
                        "with the periodicity test choosing (default)")
    p.add_argument("--strikes", choices=("model", "measured"), default="model",
                   help="read the samples between the model's heel strikes, the measured ones "
                        "being data with their time_sd (default), or between the measured "
                        "strikes taken as exact (robust to step-to-step variability, biased by "
                        "strike-time errors)")
    p.add_argument("--intervals", type=int, default=None,
                   help="collocation intervals per step (default 30 periodic, 12 transient)")
    p.add_argument("--prior", action="append", metavar="NAME=MEAN,SD",
                   help="a Gaussian prior on a free parameter, e.g. the slope as measured: "
                        "slope=0.0785,0.002 (repeatable)")
    p.add_argument("--multistart", nargs="?", const="", default=None, metavar="DIR",
                   help="also fit from one start per parameter set in DIR (default: the shipped "
                        "sets), carried over to this walker in dimensionless form; write the "
                        "best fit and say whether the starts agree. With --model auto the starts "
                        "are compared on the periodic model, and the periodicity test then runs "
                        "from the best start: local optima are a property of the parameters, "
                        "which both models share, and the periodic fit is the cheaper one")
    p.set_defaults(func=cmd_fit)


def cmd_fit(args) -> int:
    from toywalk.model.files import atomic_write_json, strict_json
    from toywalk.model.trajectory import read_trajectory
    from toywalk.model.walker import CLEARANCE_RESOLUTION, describe_scuffs
    from toywalk.sysid.fit import CONTACT_KEYS, FitError, fit

    out = output_path(args.out, (".json",))
    if args.intervals is not None and args.intervals < 4:
        raise CommandError(f"--intervals must be >= 4, got {args.intervals}")
    params = load_walker(args.params)
    free = [name.strip() for name in args.free.split(",") if name.strip()]
    if not free:
        raise CommandError("--free names no parameter")
    priors = {}
    for item in args.prior or ():
        name, _, value = item.partition("=")
        try:
            mean, sd = (float(v) for v in value.split(","))
        except ValueError as err:
            raise CommandError(f"--prior expects NAME=MEAN,SD, got {item!r}") from err
        priors[name.strip()] = (mean, sd)
    try:
        table = read_trajectory(args.trajectory)
    except (OSError, ValueError) as err:
        raise CommandError(str(err)) from err
    options = dict(offsets=not args.no_offsets, n_intervals=args.intervals, priors=priors,
                   strikes=args.strikes)
    starts = None
    try:
        if args.multistart is not None:
            starts = _multi_start(table, params, free, args, options)
            params = starts.best.params
        if starts is not None and args.model != "auto":
            result = starts.best
        else:
            result = fit(table, params, free, model=args.model, progress=say, **options)
    except FitError as err:
        raise CommandError(str(err)) from err
    report = result.to_json()
    if starts is not None:
        report["multistart"] = starts.to_json()
        report["warnings"] = report["warnings"] + starts.warnings
    if result.periodicity is not None:
        print(f"periodicity: {result.periodicity.message}")
    print(f"model: {result.model}")
    report["input"] = {"trajectory": str(args.trajectory), "params": str(args.params),
                       "software": software_version()}
    atomic_write_json(out, strict_json(report))  # a standard error not determined is null
    for name in result.names:
        se = result.std[name]
        print(f"{name:<28s} {result.estimates[name]: .6g} "
              + (f"+/- {se:.2g}" if math.isfinite(se) else "(not determined by these data)"))
    if result.shared_widening:
        print("standard errors widened by the errors the samples share by phase (the file's *_phase_sd): "
              + ", ".join(f"{n} x{f:.2g}" for n, f in result.shared_widening.items()))
    if result.undetermined:
        print(f"not determined: {', '.join(result.undetermined)} (the information is singular along "
              "a direction they share; no standard error is given; see the warnings)", file=sys.stderr)
    gait = result.gait
    if gait:
        scuffs = "" if gait["scuffs"] is None else describe_scuffs(
            gait["scuffs"], len(gait["step_times"]), gait["swing_clearance"],
            CLEARANCE_RESOLUTION * result.params.leg_length)
        print(f"fitted gait: {gait['map']} map, max |eigenvalue| {gait['max_abs_eigenvalue']:#.4g} "
              f"({'stable' if gait['stable'] else 'unstable'})" + (f"; {scuffs}" if scuffs else ""))
    rms = ", ".join(f"{k} {math.degrees(v):.3g} deg" for k, v in result.residual_rms.items()
                    if k not in ("step_duration", "strike_time", *CONTACT_KEYS))
    if CONTACT_KEYS[0] in result.residual_rms:
        rms += ", contact positions " + ", ".join(
            f"{k.removeprefix('contact_')} {1e3 * result.residual_rms[k]:.3g} mm" for k in CONTACT_KEYS)
    timing = f"; step duration {1e3 * result.residual_rms['step_duration']:.3g} ms"
    if "strike_time" in result.residual_rms:
        timing += f", heel strikes {1e3 * result.residual_rms['strike_time']:.3g} ms"
    print(f"residual RMS: {rms}{timing}")
    for note in report["warnings"]:
        print(f"warning: {note}")
    print(f"{result.status} in {result.iterations} iterations -> {out}")
    if not result.success:
        hint = (" (a model far from the walk may converge aligned on the measured heel strikes: "
                "--strikes measured)" if args.strikes == "model" else "")
        print(f"toywalk fit: the fit did not succeed ({result.status} after {result.iterations} "
              f"iterations): {out} records the attempt and its warnings; its estimates are not a "
              f"usable optimum{hint}", file=sys.stderr)
        return 1
    return 0


def _multi_start(table, params, free, args, options):
    """The multi-start fits (periodic under ``--model auto``), one line per start and the verdict."""
    from pathlib import Path

    from toywalk.sysid.multistart import multi_start

    folder = Path(args.multistart) if args.multistart else None
    if folder is not None and not folder.is_dir():
        raise CommandError(f"--multistart needs a folder of parameter files, got {folder}")
    model = "periodic" if args.model == "auto" else args.model
    # The Jacobian cross-check is the chosen fit's: under --model auto the periodicity test refits.
    result = multi_start(table, params, free, starts=folder, model=model,
                         check_jacobian=args.model != "auto", progress=say, **options)
    for k, run in enumerate(result.runs):
        if run["status"] == "skipped":
            print(f"start {k + 1} ({run['source']}): skipped: {run['reason']}")
            continue
        values = ", ".join(f"{n} {v:.4g}" for n, v in run["estimates"].items())
        where = f"optimum {run['optimum'] + 1}" if run["optimum"] is not None else "not converged"
        print(f"start {k + 1} ({run['source']}): {run['status']}, chi2 {run['chi2']:.1f}, "
              f"{values} ({where})")
    n = len(result.optima)
    verdict = "the starts agree" if result.agree else \
        f"the starts disagree ({n} distinct optima)" if n > 1 else "no start converged"
    print(f"multistart ({model}): {verdict}; best chi2 {result.best.chi2:.1f}")
    return result
