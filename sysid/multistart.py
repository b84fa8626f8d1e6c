"""Multi-start fits: the same walk fitted from several starting points, and whether they agree.

The fit (:func:`toywalk.sysid.fit.fit`) is a local method: IPOPT follows the misfit downhill from
its start, so a start in another basin ends at another local optimum, or at none. This module
fits the walk from the user's own parameters and from one start per shipped parameter set
(``data/params/*.toml``), chooses the converged fit with the lowest chi-square, and says when the
starts disagree: when two converged fits are distinct local optima.

**Starts from other walkers.** A shipped set describes another walker (a 1 m compass walker, a
15 cm toy). It gives only the values of the free parameters, carried over to the user's walker in
dimensionless form (Buckingham; the units of leg length ``l``, total mass ``m`` and the pendulum
time ``sqrt(l / g)``, as in Garcia et al. 1998, J. Biomech. Eng. 120:281):

- lengths (foot radii, hip width, leg length, the mass offset) scale with ``l``;
- masses with ``m`` (:attr:`toywalk.model.parameters.Params.total_mass`);
- inertias with ``m l^2``;
- the slope and dimensionless effect strengths (unit ``1`` or ``rad``) are taken as they are;
- torques (unit ``N m``) scale with ``m g l``, and damping coefficients (``N m s/rad``) with
  ``m l^2 / sqrt(l / g)``;
- gravity, and an effect in any other unit, have no dimensionless form in ``l`` and ``m``
  alone: the user's value is kept, and the run says so.

Everything that is not free stays the user's. Each start is clipped into the parameter's physical
bounds (:func:`toywalk.sysid.problem.fit_bounds`, and the foot radii kept in order as the fit
keeps them), and starts equal within :data:`DUPLICATE_RTOL` are fitted once, with every set
they came from named.

**One noise model.** Chi-squares compare only under one noise model. When neither the file's
``*_sd`` columns nor ``noise_sd`` give it, the first start that converges estimates it from its
residuals (as a single fit does), and every later start is fitted with that noise model.

**Distinct optima.** Two converged fits are distinct local optima when their estimates differ by
more than :data:`DISTINCT_SE` combined standard errors ``sqrt(se_a^2 + se_b^2)`` in some free
parameter and their chi-squares differ by more than :data:`DISTINCT_CHI2`. Otherwise they reached
the same optimum, and those starts agree.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

from toywalk.model.effects import EFFECTS
from toywalk.model.files import DATA_DIR
from toywalk.model.parameters import ParameterError, Params, load_params
from toywalk.model.trajectory import TrajectoryTable

from .fit import FitError, FitResult, fit, fit_bounds
from .measurement import MeasurementError, observations

__all__ = ["DISTINCT_CHI2", "DISTINCT_SE", "DUPLICATE_RTOL", "SHIPPED_PARAMS", "MultiStart", "Start",
           "carried_over", "multi_start", "shipped_starts"]

#: The shipped parameter sets (``data/params``), the default starts.
SHIPPED_PARAMS = DATA_DIR / "params"
#: Two starts whose free values agree to this relative difference are one start.
DUPLICATE_RTOL = 1e-9
#: Distinct optima differ by more than this many combined standard errors in some parameter: at 3,
#: two fits of one optimum differ by that much by chance less than 0.3 % of the time per parameter
#: (their differences are at most as wide as the combined SE; Gaussian tails).
DISTINCT_SE = 3.0
#: ... and by more than this in chi-square: a difference of 4 is the likelihood ratio of two
#: standard deviations in one parameter, so optima closer than that are both consistent with the
#: data and not told apart.
DISTINCT_CHI2 = 4.0
#: The user's own start is named so in the runs.
USER = "user"

# How a parameter-file name carries over between walkers: the power of (l, m, g) in its unit.
# Slope and dimensionless effect strengths have none.
_LENGTHS = {"leg_length", "foot_radius", "foot_lateral_radius", "hip_width",
            "com_offset[0]", "com_offset[1]", "com_offset[2]"}
_MASSES = {"leg_mass", "axle_mass"}
_EFFECT_POWERS = {"1": (0.0, 0.0, 0.0), "rad": (0.0, 0.0, 0.0),
                  "N m": (1.0, 1.0, 1.0),                 # torque: m g l
                  "N m/rad": (1.0, 1.0, 1.0),             # stiffness: m g l (per radian)
                  "N m/rad^3": (1.0, 1.0, 1.0),           # cubic stiffness: m g l (per rad^3)
                  "N m s/rad": (1.5, 1.0, 0.5)}           # damping: m l^2 / sqrt(l / g)
# The fit's own options that multi_start passes through (everything of fit() but its data).
_FIT_OPTIONS = tuple(inspect.signature(fit).parameters)[3:]


def _powers(name: str) -> tuple[float, float, float] | None:
    """Exponents of (leg length, total mass, gravity) in the unit of a parameter; None for one
    with no dimensionless form in them (gravity, an effect in another unit)."""
    if name in _LENGTHS:
        return 1.0, 0.0, 0.0
    if name in _MASSES:
        return 0.0, 1.0, 0.0
    if name.startswith("inertia["):
        return 2.0, 1.0, 0.0
    if name == "slope":
        return 0.0, 0.0, 0.0
    if name.startswith("effects."):
        return _EFFECT_POWERS.get(EFFECTS[name.split(".", 1)[1]].unit)
    return None


@dataclasses.dataclass
class Start:
    """One starting point: the values of the free parameters, and where they came from.

    Attributes
    ----------
    sources : list of str
        The user's parameters (``'user'``), shipped sets by file stem (``'tinkertoy'``), or the
        names of explicit starts; more than one when equal starts were merged.
    values : dict of str to float
        The free parameters' starting values (SI), clipped into their bounds.
    notes : list of str
        Clipping, and free parameters for which a set gave no value (the user's was kept).
    """

    sources: list
    values: dict
    notes: list = dataclasses.field(default_factory=list)

    @property
    def source(self) -> str:
        return ", ".join(self.sources)


@dataclasses.dataclass
class MultiStart:
    """The fits from every start, the distinct optima they reached, and whether they agree.

    Attributes
    ----------
    best : FitResult
        The converged fit with the lowest chi-square (with the Jacobian cross-check when asked
        for); the lowest-chi-square fit when none converged.
    runs : list of dict
        Per start: ``source``, ``sources``, ``start`` (free values), ``notes``, ``success``,
        ``status`` (IPOPT's, or ``'skipped'`` with the ``reason`` when no fit could be made),
        ``chi2``, ``estimates`` and ``std`` (free parameters), ``iterations``, ``seconds``,
        ``noise_source`` and ``optimum`` (index into ``optima``; None when not converged).
    optima : list of dict
        Distinct local optima, best first: ``chi2``, ``estimates``, ``std``, ``sources`` (the
        starts that reached it) and ``runs`` (their indices).
    agree : bool
        Every converged start reached one optimum (False also when none converged).
    warnings : list of str
        Disagreement, starts that failed or were skipped, with numbers.
    noise_sd : dict of str to float
        The one noise model all chi-squares were computed with; ``noise_source`` says where it
        came from.
    """

    best: FitResult
    runs: list
    optima: list
    agree: bool
    warnings: list
    noise_sd: dict
    noise_source: str

    def to_json(self) -> dict:
        """The multi-start block of a fit file: runs, optima, verdict (the best fit itself is the
        file's top level, :meth:`FitResult.to_json`)."""
        best = next((o["sources"] for o in self.optima), [])
        return {"model": self.best.model, "agree": self.agree, "best_from": best,
                "runs": self.runs, "optima": self.optima,
                "warnings": self.warnings, "noise_sd": self.noise_sd,
                "noise_source": self.noise_source,
                "criteria": {"distinct_se": DISTINCT_SE, "distinct_chi2": DISTINCT_CHI2}}


# ---------------------------------------------------------------------------------- starts
def _clipped(params: Params, free: list[str], values: dict, notes: list) -> dict:
    out = {}
    for name in free:
        low, high = fit_bounds(params, free, name)
        value = float(min(max(values[name], low), high))
        if value != values[name]:
            notes.append(f"{name} {values[name]:.4g} clipped to its bound {value:.4g}")
        out[name] = value
    if {"foot_radius", "foot_lateral_radius"} <= set(free) and \
            out["foot_lateral_radius"] > out["foot_radius"]:
        notes.append(f"foot_lateral_radius {out['foot_lateral_radius']:.4g} lowered to the "
                     f"foot_radius {out['foot_radius']:.4g} (a sideways radius never exceeds it)")
        out["foot_lateral_radius"] = out["foot_radius"]
    return out


def carried_over(params: Params, other: Params, free) -> tuple[dict, list]:
    """The free parameters of ``other`` carried over to ``params``' walker in dimensionless form.

    Returns the values (SI, in ``params``' units, not yet clipped) and notes on the parameters
    that have no dimensionless form (their value is ``params``' own).
    """
    ratio = (params.leg_length / other.leg_length, params.total_mass / other.total_mass,
             params.gravity / other.gravity)
    values, notes = {}, []
    for name in free:
        powers = _powers(name)
        if powers is None:
            values[name] = params.get(name)
            notes.append(f"{name} has no dimensionless form in leg length and mass: "
                         "the user's value kept")
            continue
        factor = math.prod(r ** k for r, k in zip(ratio, powers, strict=True))
        values[name] = other.get(name) * factor
    return values, notes


def shipped_starts(params: Params, free, folder: str | Path = SHIPPED_PARAMS) -> list[Start]:
    """One start per parameter set in ``folder`` (``*.toml``, by name): its free parameters
    carried over to ``params`` (:func:`carried_over`) and clipped into their bounds."""
    folder = Path(folder)
    files = sorted(folder.glob("*.toml"))
    if not files:
        raise FitError(f"no parameter sets (*.toml) in {folder}")
    starts = []
    for path in files:
        try:
            other = load_params(path)
        except ParameterError as err:
            raise FitError(f"cannot start from {path}: {err}") from err
        values, notes = carried_over(params, other, free)
        starts.append(Start([path.stem], _clipped(params, free, values, notes), notes))
    return starts


def _explicit_starts(params: Params, free, starts) -> list[Start]:
    items = list(starts.items()) if isinstance(starts, Mapping) else \
        [(f"start {k + 1}", s) for k, s in enumerate(starts)]
    out = []
    for name, other in items:
        if not isinstance(other, Params):
            raise TypeError(f"starts must hold Params, got {type(other).__name__} for {name!r}")
        notes: list[str] = []
        out.append(Start([str(name)], _clipped(params, free, {n: other.get(n) for n in free}, notes),
                         notes))
    return out


def _same(a: dict, b: dict) -> bool:
    return all(abs(a[n] - b[n]) <= DUPLICATE_RTOL * max(abs(a[n]), abs(b[n])) for n in a)


def _merged(starts: list[Start]) -> list[Start]:
    """Equal starts fitted once, with every source named (the first's order kept)."""
    out: list[Start] = []
    for start in starts:
        twin = next((s for s in out if _same(s.values, start.values)), None)
        if twin is None:
            out.append(Start(list(start.sources), dict(start.values), list(start.notes)))
        else:
            twin.sources.extend(start.sources)
            twin.notes.extend(n for n in start.notes if n not in twin.notes)
    return out


# -------------------------------------------------------------------------------- the runs
def multi_start(table: TrajectoryTable, params: Params, free, *, starts=None,
                **fit_options) -> MultiStart:
    """Fit ``free`` parameters from several starts and say whether the starts agree.

    Parameters
    ----------
    table, params, free
        As :func:`toywalk.sysid.fit.fit`; ``params`` is the user's walker and the first start.
    starts : None, str or Path, sequence or mapping of Params, optional
        The other starts. None: the shipped parameter sets (:data:`SHIPPED_PARAMS`); a folder:
        its parameter sets; both carried over to the user's walker in dimensionless form (module
        docstring). A sequence (named ``start 1``, ...) or a mapping ``name -> Params``: starts
        for the user's walker, whose free values are taken as they are.
    **fit_options
        Passed to every :func:`~toywalk.sysid.fit.fit` (``model``, ``offsets``, ``n_intervals``,
        ``priors``, ``noise_sd``, ...). ``z_guess`` applies to the user's start only.
        ``check_jacobian`` (default True) is made on the best fit only: on the user's start's run,
        and on the best by a second fit from its estimates when another start wins.
        ``progress`` (a callable) is given one line before each start's fit, and before the
        best's second fit, not the stages within each.

    Raises
    ------
    FitError
        Bad names or data (as :func:`fit`), or no start gave a fit (each one's reason).
    TypeError
        An unknown option, or a start that is not a Params.
    """
    if not isinstance(params, Params):
        raise TypeError(f"params must be a Params, got {type(params).__name__}")
    unknown = sorted(set(fit_options) - set(_FIT_OPTIONS))
    if unknown:
        raise TypeError(f"multi_start got an unknown option {unknown[0]!r}; fit options are "
                        f"{', '.join(_FIT_OPTIONS)}")
    free = list(free)
    for name in free:
        try:
            params.get(name)
        except ParameterError as err:
            raise FitError(f"cannot fit {name!r}: {err}") from err
    try:  # unusable data fail every start alike: refused before any start's progress line
        observations(table)
    except MeasurementError as err:
        raise FitError(str(err)) from err
    if starts is None or isinstance(starts, (str, Path)):
        others = shipped_starts(params, free, SHIPPED_PARAMS if starts is None else starts)
    elif isinstance(starts, (Sequence, Mapping)):
        others = _explicit_starts(params, free, starts)
    else:
        raise TypeError(f"starts must be None, a folder, or a sequence or mapping of Params, got "
                        f"{type(starts).__name__}")
    notes: list[str] = []
    user = Start([USER], _clipped(params, free, {n: params.get(n) for n in free}, notes), notes)
    candidates = _merged([user, *others])

    say = fit_options.pop("progress", None) or (lambda _msg: None)
    check = fit_options.pop("check_jacobian", True)
    z_guess = fit_options.pop("z_guess", None)
    noise_sd = fit_options.pop("noise_sd", None)
    noise_source = "given" if noise_sd is not None else None
    runs, results = [], []
    for k, start in enumerate(candidates):
        run = {"source": start.source, "sources": start.sources, "start": start.values,
               "notes": start.notes}
        options = dict(fit_options, check_jacobian=check and k == 0,
                       z_guess=z_guess if k == 0 else None)
        if noise_sd is not None:
            options["noise_sd"] = noise_sd
        clock = time.perf_counter()
        say(f"multistart: start {k + 1} of {len(candidates)} ({start.source})")
        try:
            result = fit(table, params.replace(**start.values), free, **options)
        except (FitError, ParameterError) as err:
            # No gait at this start, or not a valid walker there: reported, not fatal. An error of
            # the request or the data fails every start alike, and is raised below.
            run.update(success=False, status="skipped", reason=str(err), chi2=None,
                       seconds=time.perf_counter() - clock)
            runs.append(run)
            results.append(None)
            continue
        run.update(success=result.success, status=result.status, chi2=result.chi2,
                   estimates={n: result.estimates[n] for n in free},
                   std={n: result.std[n] for n in free}, iterations=result.iterations,
                   noise_source=result.noise_source, seconds=time.perf_counter() - clock)
        runs.append(run)
        results.append(result)
        if noise_sd is None and result.success:
            # The first converged start's noise model is every later start's (module docstring).
            noise_sd = result.noise_sd
            noise_source = f"{result.noise_source} (the fit from {start.source})"
    if all(r is None for r in results):
        reasons = {r["reason"] for r in runs}
        if len(reasons) == 1:
            raise FitError(reasons.pop())
        raise FitError("no start gave a fit: " + "; ".join(f"{r['source']}: {r['reason']}"
                                                            for r in runs))
    optima, warnings = _optima(runs, results, free)
    agree = len(optima) == 1
    if optima:
        best_index = optima[0]["runs"][0]
    else:
        best_index = min((k for k, r in enumerate(results) if r is not None),
                         key=lambda k: results[k].chi2)
    best = results[best_index]
    if check and best_index != 0 and best.success:
        # The Jacobian cross-check of the best, from its own optimum (one more fit, continued
        # from it: started afresh from its parameters alone, the fit has run to IPOPT's cap, as
        # when another start wins by round-off at the same optimum)
        options = dict(fit_options, check_jacobian=True, noise_sd=noise_sd, warm=best)
        say(f"multistart: the best start's fit ({runs[best_index]['source']}) again, its Jacobian "
            "checked")
        best = dataclasses.replace(fit(table, best.params, free, **options),
                                   noise_source=noise_source)
    return MultiStart(best, runs, optima, agree, warnings, noise_sd or best.noise_sd,
                      noise_source or best.noise_source)


def _distinct(a: dict, b: dict, free: list[str]) -> list[str]:
    """The parameters in which two runs differ by more than DISTINCT_SE combined SEs, when their
    chi-squares differ by more than DISTINCT_CHI2; empty when they are one optimum."""
    if abs(a["chi2"] - b["chi2"]) <= DISTINCT_CHI2:
        return []
    return [n for n in free if abs(a["estimates"][n] - b["estimates"][n])
            > DISTINCT_SE * math.hypot(a["std"][n], b["std"][n])]


def _optima(runs: list, results: list, free: list[str]) -> tuple[list, list]:
    """Group the converged runs into distinct optima (best first) and write the warnings."""
    order = sorted((k for k, r in enumerate(results) if r is not None and r.success),
                   key=lambda k: results[k].chi2)
    optima: list[dict] = []
    for k in order:
        run = runs[k]
        home = next((o for o in optima if not _distinct(runs[o["runs"][0]], run, free)), None)
        if home is None:
            home = {"chi2": run["chi2"], "estimates": run["estimates"], "std": run["std"],
                    "sources": [], "runs": []}
            optima.append(home)
        home["sources"].extend(run["sources"])
        home["runs"].append(k)
        run["optimum"] = optima.index(home)
    for run in runs:
        run.setdefault("optimum", None)
    warnings = []
    if len(optima) > 1:
        best = optima[0]
        others = []
        for o in optima[1:]:
            differ = _distinct(runs[best["runs"][0]], runs[o["runs"][0]], free)
            values = ", ".join(f"{n} {best['estimates'][n]:.4g} vs {o['estimates'][n]:.4g}"
                               for n in differ)
            others.append(f"chi2 {o['chi2']:.1f} (from {', '.join(o['sources'])}): {values}")
        warnings.append(f"starts disagree: {len(optima)} distinct optima; the best (chi2 "
                        f"{best['chi2']:.1f}, from {', '.join(best['sources'])}) and "
                        + "; ".join(others))
    for o in optima:
        # One optimum by chi-square, yet estimates far apart: a valley the data do not close.
        ref = runs[o["runs"][0]]
        for k in o["runs"][1:]:
            far = [n for n in free if abs(ref["estimates"][n] - runs[k]["estimates"][n])
                   > DISTINCT_SE * math.hypot(ref["std"][n], runs[k]["std"][n])]
            if far:
                values = ", ".join(f"{n} {ref['estimates'][n]:.4g} vs {runs[k]['estimates'][n]:.4g}"
                                   for n in far)
                warnings.append(f"the starts from {ref['source']} and {runs[k]['source']} end "
                                f"{DISTINCT_SE:g} SEs apart at chi-squares within "
                                f"{DISTINCT_CHI2:g} ({ref['chi2']:.1f}, {runs[k]['chi2']:.1f}): "
                                f"the data do not tell them apart ({values})")
    failed = [f"{r['source']} ({r['status']}, chi2 {r['chi2']:.1f})" for r in runs
              if r["status"] != "skipped" and not r["success"]]
    if failed:
        warnings.append(f"{len(failed)} start(s) did not converge: {'; '.join(failed)}")
    skipped = [f"{r['source']} ({r['reason']})" for r in runs if r["status"] == "skipped"]
    if skipped:
        warnings.append(f"{len(skipped)} start(s) skipped, no fit could start there: "
                        + "; ".join(skipped))
    if not optima:
        warnings.append("no start converged: the best is the lowest chi-square of fits that "
                        "did not converge")
    return optima, warnings

