"""``toywalk fit M.csv --params P.toml --free NAME[,NAME...] --out F.json``: fit the model to a walk.

By default (``--model auto``) the walk is fitted both as a repeated gait and as a transient from a
free start, and the periodicity test (:func:`toywalk.sysid.fit.periodicity_test`) chooses: a walk
released off its cycle fitted as a gait gives biased parameters. ``--model periodic`` or
``transient`` fits one model only.
"""

from __future__ import annotations

import math

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
    p.add_argument("--intervals", type=int, default=None,
                   help="collocation intervals per step (default 30 periodic, 12 transient)")
    p.add_argument("--prior", action="append", metavar="NAME=MEAN,SD",
                   help="a Gaussian prior on a free parameter, e.g. the slope as measured: "
                        "slope=0.0785,0.002 (repeatable)")
    p.set_defaults(func=cmd_fit)


def cmd_fit(args) -> int:
    from toywalk.model.files import atomic_write_json
    from toywalk.model.trajectory import read_trajectory
    from toywalk.sysid.cli import CommandError, _load, _version, output_path
    from toywalk.sysid.fit import FitError, fit, periodicity_test

    out = output_path(args.out, (".json",))
    if args.intervals is not None and args.intervals < 4:
        raise CommandError(f"--intervals must be >= 4, got {args.intervals}")
    params = _load(args.params)
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
    options = dict(offsets=not args.no_offsets, n_intervals=args.intervals, priors=priors)
    test = None
    try:
        if args.model == "auto":
            test = periodicity_test(table, params, free, **options)
            result = test.chosen
        else:
            result = fit(table, params, free, model=args.model, **options)
    except FitError as err:
        raise CommandError(str(err)) from err
    report = result.to_json()
    if test is not None:
        report["periodicity"] = test.to_json()
        print(f"periodicity: {test.message}")
    print(f"model: {result.model}")
    report["input"] = {"trajectory": str(args.trajectory), "params": str(args.params),
                       "software": _version()}
    atomic_write_json(out, report)
    for name in result.names:
        print(f"{name:<28s} {result.estimates[name]: .6g} +/- {result.std[name]:.2g}")
    gait = result.gait
    if gait:
        print(f"fitted gait: {gait['map']} map, max |eigenvalue| {gait['max_abs_eigenvalue']:.4g} "
              f"({'stable' if gait['stable'] else 'unstable'})")
    rms = ", ".join(f"{k} {math.degrees(v):.3g} deg" for k, v in result.residual_rms.items()
                    if k != "step_duration")
    print(f"residual RMS: {rms}; step duration {1e3 * result.residual_rms['step_duration']:.3g} ms")
    for note in result.warnings:
        print(f"warning: {note}")
    print(f"{result.status} in {result.iterations} iterations -> {out}")
    return 0 if result.success else 1
