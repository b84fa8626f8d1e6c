"""``toywalk diagnose M.csv --params P.toml --out REPORT_DIR``: what the model gets wrong, the
cause named, the gain measured (:mod:`toywalk.sysid.discrepancy`).

Several walks of one walker under known conditions (``toywalk diagnose A.csv B.csv --params
A.toml --params B.toml``: one parameter file per walk, or one for all) are analysed together
(:func:`toywalk.sysid.walks.diagnose_walks`)."""

from __future__ import annotations

from toywalk.model.files import software_version

from .common import CommandError, load_walker, say

__all__ = ["cmd_diagnose", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("diagnose", help="find what the model lacks and name the cause")
    p.add_argument("trajectory", metavar="M.csv", nargs="+",
                   help="the measured walk, or a gait's summary statistics (a CSV with the "
                        "columns quantity, value, unit, stated, resolution, note, as "
                        "data/paper/measurements.csv); several walks of one walker under known, "
                        "different conditions (slope, a moved mass) are analysed together")
    p.add_argument("--params", required=True, action="append",
                   help="the base model's parameter file; with several walks, one per walk (its "
                        "condition), in their order, or one for all")
    p.add_argument("--free", default="", help="base parameters to fit (comma-separated names)")
    p.add_argument("--effects", help="restrict the candidate effects (comma-separated names; none: "
                                     "no library effect; library: the library's, as in "
                                     "library,soft_heel)")
    p.add_argument("--parameters",
                   help="held parameters that are candidate causes (comma-separated; default: "
                        "foot radii, mass offsets, hip width, slope; none: no parameter; with "
                        "--effects none the analysis searches the port dictionary at once)")
    p.add_argument("--model", choices=("auto", "periodic", "transient"), default="auto",
                   help="the base model of the walk: auto tests whether the walk is on its limit "
                        "cycle (as `toywalk fit`); summary statistics are always of the limit cycle")
    p.add_argument("--alpha", type=float, default=None, help="family-wise false-alarm rate")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="local processes for the candidates' fits (default: one per core, at "
                            "most four)")
    where.add_argument("--scheduler", help="address of a Dask distributed scheduler")
    p.add_argument("--out", required=True, metavar="REPORT_DIR", help="folder for the report")
    p.set_defaults(func=cmd_diagnose)


def cmd_diagnose(args) -> int:
    from pathlib import Path

    from toywalk.model.parameters import ParameterError
    from toywalk.model.trajectory import read_trajectory
    from toywalk.sysid.diagnosis_report import write_diagnosis
    from toywalk.sysid.discrepancy import diagnose
    from toywalk.sysid.fit import FitError
    from toywalk.sysid.measurement import MeasurementError, observations
    from toywalk.sysid.naming import DiagnoseError, candidates
    from toywalk.sysid.summary import is_summary_file

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CommandError(f"--out must name a folder, got the file {out}")
    if not out.parent.is_dir():
        raise CommandError(f"output folder's parent does not exist: {out.parent}")
    if len(args.trajectory) > 1:
        return _walks(args, out)
    if len(args.params) > 1:
        raise CommandError(f"one walk takes one --params, got {len(args.params)}")
    args.trajectory, args.params = args.trajectory[0], args.params[0]
    params = load_walker(args.params)
    if is_summary_file(args.trajectory):
        return _summary(args, params, out)
    try:
        table = read_trajectory(args.trajectory)
        obs = observations(table)  # a walk that cannot be fitted is refused before the progress lines
    except (OSError, ValueError) as err:
        raise CommandError(str(err)) from err
    if obs.note:
        _say(obs.note)

    alpha = _alpha(args)
    workers = _workers(args)
    free = _free(args)
    try:
        candidates(params, free, _split(args.effects), _split(args.parameters))
    except (DiagnoseError, ParameterError) as err:
        raise CommandError(str(err)) from err

    try:
        result = diagnose(table, params, free=free, effects=_split(args.effects),
                          parameters=_split(args.parameters), alpha=alpha, model=args.model, progress=_say,
                          workers=workers, scheduler=args.scheduler)
    except (DiagnoseError, FitError, MeasurementError, ParameterError) as err:
        raise CommandError(str(err)) from err
    write_diagnosis(result, out, {"trajectory": str(args.trajectory), "params": str(args.params),
                                  "free": free, "model": result.base.model, "software": software_version()})
    _print_verdict(result)
    for row in result.ranking[:5]:
        extra = (f", likelihood ratio {row['lr']:.1f} (p = {row['lr_p']:.2g})" if "lr" in row else "")
        print(f"  {row['effect']:<32s} score z {row['score_z']:+.2f}{extra}")
    if result.gain:
        g = result.gain
        print(f"held-out chi-square {g['base']:.1f} -> {g['extended']:.1f}; max |eigenvalue| "
              f"{g['max_abs_eigenvalue']['base']:#.4g} -> {g['max_abs_eigenvalue']['extended']:#.4g}")
    _print_next_walk(result)
    if result.missing_force is not None:
        from toywalk.sysid.missing_force import term_sentence

        found = result.missing_force
        for term in found.terms:
            print(f"missing force: {term_sentence(term)}")
        if not found.terms:
            print(f"missing force: no term of the port dictionary singled out ({found.stop})")
    print(f"report -> {out / 'report.md'}")
    return 0


def _print_verdict(result, suffix: str = "") -> None:
    """The verdict, the effective description of a 'partly explained' one, and the evidence."""
    from toywalk.sysid.diagnosis_report import explanation_line

    print(f"verdict: {result.verdict}; cause: {result.cause}{suffix}")
    e = result.effective
    if e and not e["explains"]:
        print(f"effective description (not a named cause): {' + '.join(e['candidates'])}; "
              f"{explanation_line(e)}")
    print(f"evidence: {result.evidence}")


def _print_next_walk(result) -> None:
    """The suggested further walk, where the analysis left causes tied and weighed one."""
    if result.next_walk and result.next_walk.get("suggestion"):
        print(f"next walk: {result.next_walk['suggestion']} (report.md, 'Which further walk would "
              "tell them apart')")


def _split(text):
    """A comma-separated option as a list of names (None when not given, empty for ``none``)."""
    if text and text.strip().lower() == "none":
        return []
    return [n.strip() for n in text.split(",") if n.strip()] if text else None


def _say(message: str) -> None:
    """A progress line on stderr, flushed, to a terminal, file or pipe alike
    (:func:`toywalk.sysid.commands.common.say`)."""

    say(message)


def _alpha(args) -> float:
    from toywalk.sysid.naming import ALPHA

    alpha = ALPHA if args.alpha is None else args.alpha
    if not 0 < alpha < 1:
        raise CommandError(f"--alpha must be a false-alarm rate in (0, 1), got {alpha}")
    return alpha


def _workers(args) -> int:
    """``--workers``: by default one process a core, at most four (the candidates' fits and the
    held-out folds run side by side)."""
    import os


    workers = min(4, os.cpu_count() or 1) if args.workers is None else args.workers
    if workers < 1:
        raise CommandError(f"--workers must be >= 1, got {workers}")
    return workers


def _free(args) -> list[str]:
    """``--free``'s names, checked before any fit: a misspelt one is refused at once, not after
    minutes of fitting."""
    from toywalk.model.parameters import PARAMETER_NAMES

    free = _split(args.free) or []
    unknown = [name for name in free if name not in PARAMETER_NAMES]
    if unknown:
        raise CommandError(f"--free: {unknown[0]!r} is not a parameter (names are those of a "
                           "parameter file: foot_radius, com_offset[1], effects.hip_damping, ...)")
    return free


def _walks(args, out) -> int:
    """diagnose on several walks together (:func:`toywalk.sysid.walks.diagnose_walks`)."""
    from toywalk.model.parameters import ParameterError
    from toywalk.model.trajectory import read_trajectory
    from toywalk.sysid.diagnosis_report import write_walks_diagnosis
    from toywalk.sysid.fit import FitError
    from toywalk.sysid.measurement import MeasurementError, observations
    from toywalk.sysid.naming import DiagnoseError, candidates
    from toywalk.sysid.summary import is_summary_file
    from toywalk.sysid.walks import diagnose_walks

    paths = list(args.trajectory)
    files = list(args.params) * len(paths) if len(args.params) == 1 else list(args.params)
    if len(files) != len(paths):
        raise CommandError(f"{len(paths)} walks need one --params each or one for all, got "
                           f"{len(args.params)}")
    workers = _workers(args)
    params = [load_walker(f) for f in files]
    tables = []
    for path in paths:
        if is_summary_file(path):
            raise CommandError(f"{path} holds summary statistics: those are analysed one file at a time")
        try:
            table = read_trajectory(path)
            obs = observations(table)
        except (OSError, ValueError) as err:
            raise CommandError(f"{path}: {err}") from err
        if obs.note:
            _say(f"{path}: {obs.note}")
        tables.append(table)
    alpha = _alpha(args)
    free = _free(args)
    try:
        candidates(params[0], free, _split(args.effects), _split(args.parameters))
        result = diagnose_walks(tables, params, free=free, effects=_split(args.effects),
                                parameters=_split(args.parameters), alpha=alpha, model=args.model,
                                progress=_say, workers=workers, scheduler=args.scheduler)
    except (DiagnoseError, FitError, MeasurementError, ParameterError) as err:
        raise CommandError(str(err)) from err
    write_walks_diagnosis(result, out, {"trajectories": paths, "params": files, "free": free,
                                        "model": result.base.walks[0].model, "software": software_version()})
    _print_verdict(result, f" ({len(paths)} walks together)")
    held = result.gain.get("held_out")
    if held:
        print(f"held-out chi-square (alternate strides of every walk): base {held['base']:.1f}, "
              f"{held['candidate']} {held['extended']:.1f}")
    for row in result.ranking[:5]:
        extra = (f", likelihood ratio {row['lr']:.1f} (p = {row['lr_p']:.2g})" if "lr" in row else "")
        z = f"score z {row['score_z']:+.2f}" if "score_z" in row else "not screened"
        print(f"  {row['effect']:<32s} {z}{extra}")
    _print_next_walk(result)
    print(f"report -> {out / 'report.md'}")
    return 0


def _summary(args, params, out) -> int:
    """diagnose on summary statistics (:mod:`toywalk.sysid.summary`)."""
    from toywalk.model.parameters import ParameterError
    from toywalk.sysid.diagnosis_report import write_summary_diagnosis
    from toywalk.sysid.naming import DiagnoseError
    from toywalk.sysid.summary import SummaryError, diagnose_summary, read_summary

    if args.model != "auto":
        raise CommandError("--model does not apply to summary statistics (they describe the "
                           "limit cycle)")
    free = _free(args)
    alpha = _alpha(args)
    try:
        data = read_summary(args.trajectory)
        result = diagnose_summary(params, data, free=free, effects=_split(args.effects),
                                  parameters=_split(args.parameters), alpha=alpha, progress=_say)
    except (SummaryError, DiagnoseError, ParameterError) as err:
        raise CommandError(str(err)) from err
    write_summary_diagnosis(result, out, {"summary": str(args.trajectory), "params": str(args.params),
                                          "free": free, "software": software_version()})
    _print_verdict(result)
    for row in result.ranking[:5]:
        if "chi2" in row:
            print(f"  {row['effect']:<32s} chi-square {row['chi2']:.2f} on {row['dof']} "
                  f"(likelihood ratio p = {row['lr_p']:.2g})")
    print(f"report -> {out / 'report.md'}")
    return 0
