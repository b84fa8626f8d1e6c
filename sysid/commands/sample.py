"""``toywalk sample F.json M.csv --out CHAIN.h5``: the posterior of a fit's free parameters (emcee)."""

from __future__ import annotations

import math
from pathlib import Path

from .common import CommandError, output_path

__all__ = ["cmd_sample", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("sample", help="sample the posterior of a fit's free parameters (emcee)")
    p.add_argument("fit", metavar="F.json", help="fit file from `toywalk fit`")
    p.add_argument("trajectory", metavar="M.csv", help="the measured walk the fit used")
    p.add_argument("--out", required=True, metavar="CHAIN.h5",
                   help="chain file CHAIN.h5 (resumed when it exists; its summary CHAIN.json beside it)")
    p.add_argument("--walkers", type=int, default=32, metavar="W",
                   help="walkers per ensemble (default %(default)s)")
    p.add_argument("--steps", type=int, default=1000, metavar="N",
                   help="steps per walker (default %(default)s)")
    p.add_argument("--ensembles", type=int, default=3, metavar="E",
                   help="independent ensembles, which R-hat compares (default %(default)s)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=1, metavar="K",
                       help="local processes (default %(default)s)")
    where.add_argument("--scheduler", metavar="ADDR",
                       help="address of a Dask distributed scheduler (default: none, local processes)")
    p.add_argument("--seed", type=int, default=0, metavar="S",
                   help="seed of the ensembles' starts and moves (default %(default)s)")
    p.add_argument("--report", metavar="DIR",
                   help="write diagnostics, figures and the posterior predictive checks into DIR "
                        "(default: none)")
    p.set_defaults(func=cmd_sample)


def cmd_sample(args) -> int:
    import sys

    from toywalk.model.files import atomic_write_json, read_json_object
    from toywalk.model.parameters import parameter_unit
    from toywalk.model.trajectory import read_trajectory
    from toywalk.sysid.fit import FitError
    from toywalk.sysid.measurement import MeasurementError
    from toywalk.sysid.sample import SampleError, sample
    from toywalk.sysid.sample_report import misfit_notes, write_report

    out = output_path(args.out, (".h5", ".hdf5"))
    if args.workers < 1:
        raise CommandError(f"--workers must be >= 1, got {args.workers}")
    if args.report:
        report_dir = Path(args.report)
        if report_dir.exists() and not report_dir.is_dir():
            raise CommandError(f"--report must name a folder, got the file {report_dir}")
        if not report_dir.parent.is_dir():
            raise CommandError(f"--report: its parent folder does not exist: {report_dir.parent}")
    report = read_json_object(args.fit, "fit file", CommandError)
    try:
        table = read_trajectory(args.trajectory)
    except (OSError, ValueError) as err:
        raise CommandError(str(err)) from err
    try:
        summary = sample(report, table, out, walkers=args.walkers, steps=args.steps,
                         ensembles=args.ensembles, workers=args.workers, scheduler=args.scheduler,
                         seed=args.seed, progress=sys.stderr.isatty(),
                         log=None if sys.stderr.isatty() else
                         lambda line: print(f"... {line}", file=sys.stderr, flush=True))
    except (SampleError, FitError, MeasurementError) as err:
        raise CommandError(str(err)) from err
    except OSError as err:
        raise CommandError(f"cannot use {out} or the scheduler: {err}") from err
    data = summary.to_json()
    atomic_write_json(out.with_suffix(".json"), data)
    fit_warnings = [w for w in report.get("warnings", []) if isinstance(w, str)]
    misfit = misfit_notes(fit_warnings)
    if args.report:
        from toywalk.sysid.sample import posterior_from_fit

        folder = Path(args.report)
        write_report(out, data, folder, posterior_from_fit(report, table)[0], table, fit_warnings)
        # the predictive checks are made as the report is written; its record says which failed
        misfit = read_json_object(folder / "report.json", "report file", CommandError)["misfit"]
    for note in misfit:  # before the estimates: they assume the model fits
        print(f"warning: {note}", file=sys.stderr)
    for name in summary.names:
        q5, q50, q95 = data["quantiles_5_50_95"][name]
        rhat = data["rhat"][name] if data["rhat"] and data["rhat"][name] is not None else math.nan
        tau = data["autocorrelation_time"][name]
        unit = parameter_unit(name)
        print(f"{name:<28s} median {q50:.6g} {unit}  90 % [{q5:.6g}, {q95:.6g}] {unit}  tau "
              f"{'(never moved)' if tau is None else f'{tau:.1f}'}  R-hat {rhat:.3f}")
    if data["probability_stable"] is not None:
        print(f"P(stable gait) {data['probability_stable']:.3f}; no gait in "
              f"{100 * data['fraction_no_gait']:.1f} % of proposals")
    if not data["long_enough"]:
        print(f"warning: the chains ({data['length']} steps) are not longer than "
              f"{data['stop_rule'].split('>')[1].strip()}: run longer (the file resumes)")
    print(f"{data['length']} steps x {summary.walkers} walkers x {summary.ensembles} ensembles -> {out}")
    return 0
