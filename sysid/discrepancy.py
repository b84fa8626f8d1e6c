"""Name what the model lacks: fit the base model, find the cause, extend the model, measure the gain.

The base model is the walker of the parameter file with the parameters the user frees. The
candidate causes are the effects of the library (:data:`toywalk.model.effects.EFFECTS`) and the
base parameters the analysis holds fixed (:data:`PARAMETERS`): a foot radius fixed at zero is a
cause as much as a missing damper. Every candidate nests the base model (the base is the candidate
at its value in the file), so each is one more free parameter.

The procedure, and the rule that decides (``alpha`` is the family-wise false-alarm rate):

1. **Base fit** (:func:`toywalk.sysid.fit.fit`) and its residuals
   (:mod:`toywalk.sysid.residuals`): a pattern repeated every step, whiteness, gait features.
2. **Screening by score tests** of every candidate at the base fit (Rao 1948: the gradient of
   chi-square in the held parameter, projected off the fitted ones; no refit, one Jacobian per
   candidate: :func:`toywalk.sysid.score.score_tests`). A candidate whose base value sits on a
   physical bound (a damper at zero) is tested one-sided.
3. **Adequate** when no candidate's score p-value is below ``alpha / K`` (K candidates,
   Bonferroni) and no signal shows a repeated pattern at ``alpha``.
4. Otherwise **extended fits** of the best-screened candidates (at most :data:`MAX_EXTENDED`), and of
   every candidate whose score at its null does not speak for its range (``Effect.local`` False:
   the soft heel strike, fitted from :data:`NONLOCAL_STARTS` and the best converged start kept),
   each scored by the likelihood ratio against the base with one noise model (the base fit's: a
   misfit inflates it, which only makes the test conservative; where the file carries errors
   shared by phase, divided by the candidate's design effect for its p-value, Rao & Scott 1981,
   as its score test's standard error is widened: :func:`toywalk.sysid.score.score_statistics`;
   compared with the others on one scale, the largest design effect fitted), chi-square
   on one degree of freedom (a 50:50 mixture with zero for a bounded null: Self & Liang 1987,
   JASA 82:605), and by
   **held-out prediction grouped by stride**: the strides are split into two folds (alternate
   strides), each model is fitted on one fold and predicts the other's angles (samples within a
   stride are not independent; strides are). A Savage-Dickey ratio at the null value (Dickey
   1971, Ann. Math. Stat. 42:204; Gaussian posterior of the extended fit, prior normal about the
   base value with the candidate's :attr:`Candidate.prior_sd`, half-normal on a bounded null)
   is reported beside.
5. **The rule** (:func:`toywalk.sysid.naming.decide`, written once for every analysis): a cause
   is named when its likelihood ratio's p-value is below ``alpha / K``, it predicts the held-out
   strides better than the base (summed over both folds), it beats every other significant
   candidate by at least :data:`SEPARATION` in chi-square, and the model with it explains the
   walk (:func:`toywalk.sysid.naming.judge`: held-out RMS within the noise, measured without the
   model; no pattern repeated every step; no gait feature missed; no correlation in time beyond
   white noise where the noise is white). Two causes are named when the runner-up, added to the
   named one, is itself significant at ``alpha / (K - 1)``.
6. **Partly explained** when that candidate improves the model but does not explain the walk: it
   is reported as an effective description (``Diagnosis.effective``), not as the cause.
   **Unexplained** when the data disagree with the base model but no candidate is significant,
   decisive, or better on held-out strides.
"""

from __future__ import annotations

import dataclasses
import math
import time

from scipy import special
from toywalk.model.effects import EFFECTS
from toywalk.model.parameters import Params
from toywalk.model.trajectory import TrajectoryTable

from .fit import FitResult, fit, gait_period, periodicity_test, score_tests
from .heldout import FitPool, held_out, held_out_fits, held_out_score, held_out_tasks, run_fits
from .measurement import observations
from .missing_force import MissingForce, discover, missing_force_clause
from .naming import (
    ALPHA,
    MAX_EXTENDED,
    NOISE_GROUPS,
    NOISE_WHITENESS,
    PARAMETERS,
    SEPARATION,
    Candidate,
    DiagnoseError,
    Explanation,
    Verdict,
    candidates,
    compatible,
    complete_rows,
    decide,
    judge,
    lr_p_value,
    noise_reference,
    parameter_note,
    rule_text,
    tied,
    white_components,
)
from .residuals import (
    NOISE_INFLATION,
    ResidualReport,
    feature_misfit,
    missed_features,
    residual_report,
    scatter_noise,
)
from .ties import further_walk_clause, weigh_ties

__all__ = ["ALPHA", "MAX_EXTENDED", "PARAMETERS", "SEPARATION", "Candidate", "Diagnosis",
           "DiagnoseError", "FitPool", "Verdict", "candidates", "chosen_model", "complete_rows", "diagnose",
           "held_out", "held_out_fits", "held_out_score", "held_out_tasks", "lr_p_value", "run_fits", "tied"]

#: IPOPT's iteration cap for a candidate's fit from the base fit: a candidate that does not
#: converge from there in this many is not an explanation of the walk (measured: the hidden
#: effect's fit converges in under 20).
_CANDIDATE_ITERATIONS = 100
#: IPOPT's iteration cap for the base fit on the model's own heel strikes before the analysis
#: falls back to the measured strikes (a failing one otherwise runs to 500: 6 min on a loaded machine).
_BASE_ITERATIONS = 200
#: A base fit on the model's own strikes whose angle residuals' RMS ends over this many times
#: that of its aligned stage (the measured strikes taken as exact; ``FitResult.aligned_rms``) in
#: some signal has found another minimum of the time offset, and is treated as not converged.
#: Measured: 1.00 +- 0.01 on walks of the stable toy (the base model's own, and with rolling
#: resistance hidden); 3.5 to 8.7 with hip dry friction hidden (1.8e-4 N m, seed 202), an IPOPT
#: "acceptable" exit 8 to 15 times the noise, from which the analysis named the slope.
ANOTHER_MINIMUM = 2.0


@dataclasses.dataclass
class Diagnosis(Verdict):
    """The analysis (:func:`diagnose`); :meth:`to_json` is ``report.json`` (docs/formats.md, "Reports").

    Attributes
    ----------
    verdict, cause, causes, evidence
        As in :class:`Verdict`.
    ranking : list of dict
        Every candidate, best first: screening score, and for those fitted the likelihood ratio,
        held-out gain, estimate with its 95 % interval and Savage-Dickey ratio.
    gain : dict
        Held-out chi-square of the base and of the extended model, per signal RMS before and
        after, the change in predicted stability and in the gait features.
    base : FitResult
    extended : dict of str to FitResult
    residuals, residuals_extended : ResidualReport
    features, features_extended : dict
        :func:`toywalk.sysid.residuals.feature_misfit` of the base and the named model.
    rule : str
    alpha : float
    seconds : dict
        Wall time of each stage (s): the base fit, the screening, each candidate's fit (its CPU
        time in a worker), the held-out folds, the pair fit, the further walks weighed, and the
        total.
    next_walk : dict or None
        Where candidates are left tied: which further walk would tell them apart
        (:func:`toywalk.sysid.design.next_walk`; ``tied`` and ``reason`` where it could not be
        weighed); None otherwise.
    missing_force : MissingForce or None
        Where no cause is named: the terms of the port dictionary the walk selects
        (:func:`toywalk.sysid.missing_force.discover`); None where it was not searched.
    """

    base: FitResult
    extended: dict
    residuals: ResidualReport
    residuals_extended: ResidualReport | None
    features: dict
    features_extended: dict | None
    rule: str
    alpha: float
    seconds: dict = dataclasses.field(default_factory=dict)
    next_walk: dict | None = None
    missing_force: MissingForce | None = None

    def to_json(self) -> dict:
        return {
            "missing_force": self.missing_force.to_json() if self.missing_force else None,
            "verdict": self.verdict, "cause": self.cause, "causes": self.causes,
            "ranking": self.ranking, "gain": self.gain, "evidence": self.evidence,
            "rule": self.rule, "alpha": self.alpha, "seconds": self.seconds,
            "next_walk": self.next_walk, "effective": self.effective,
            "base": {"free": self.base.free, "estimates": self.base.estimates, "std": self.base.std,
                     "chi2": self.base.chi2, "n_residuals": self.base.n_residuals,
                     "noise_sd": self.base.noise_sd, "noise_source": self.base.noise_source,
                     "gait": self.base.gait, "model": self.base.model},
            "residuals": self.residuals.to_json(),
            "residuals_extended": self.residuals_extended.to_json() if self.residuals_extended else None,
            "features": self.features, "features_extended": self.features_extended,
        }


#: What explaining a walk means (:func:`toywalk.sysid.naming.judge`), in words.
EXPLAINS = ("per signal the held-out RMS within 1.1 times the noise, widened by 3 standard errors of "
            "the noise estimate; no pattern repeated every step; no gait feature missed beyond "
            "alpha over the features; no correlation in time beyond white noise where the noise is "
            "known to be white")

RULE = ("adequate: no candidate's score test below alpha/K and no signal with a pattern repeated "
        "every step (alpha over the signals); "
        + rule_text(held_out="held-out strides (two folds of alternate strides)", explains=EXPLAINS))


def _normal_log_density(x: float, mean: float, sd: float) -> float:
    """log of the normal density of mean ``mean`` and SD ``sd`` at ``x``."""
    return -0.5 * ((x - mean) / sd) ** 2 - math.log(sd) - 0.5 * math.log(2.0 * math.pi)


def _savage_dickey(estimate: float, se: float, candidate: Candidate) -> float:
    """log Bayes factor of the extended model against the base (positive favours the effect):
    prior over posterior density at the base value, both Gaussian (half-Gaussian on the allowed
    side of a bounded null)."""
    if not (se > 0 and math.isfinite(estimate)):
        return math.nan
    v, s = candidate.base, candidate.prior_sd
    log_prior = _normal_log_density(v, v, s) + (math.log(2.0) if candidate.side else 0.0)
    log_post = _normal_log_density(v, estimate, se)
    if candidate.side:  # the posterior truncated to the allowed side
        u = (v - estimate) / se
        mass = special.ndtr(-u) if candidate.side > 0 else special.ndtr(u)
        log_post -= math.log(max(mass, 1e-300))
    return float(log_prior - log_post)


def chosen_model(tables, params, free, *, progress=None, **fit_options) -> str:
    """The base model for walks analysed together (``model='auto'``): each walk's
    :func:`toywalk.sysid.fit.periodicity_test`, and the transient model when any walk is off its
    cycle (one model for all), else the periodic one."""
    say = progress or (lambda _msg: None)
    options = {k: v for k, v in fit_options.items() if k not in ("model", "check_jacobian")}
    chosen = []
    for k, (table, walker) in enumerate(zip(tables, params, strict=True), start=1):
        which = "the walk" if len(tables) == 1 else f"walk {k}"
        say(f"periodicity test of {which} (is it on the model's limit cycle?)")
        chosen.append(periodicity_test(table, walker, free, check_jacobian=False, progress=say,
                                       **options).chosen.model)
    return "transient" if "transient" in chosen else "periodic"


def diagnose(table: TrajectoryTable, params: Params, *, free=(), effects=None, parameters=None,
             alpha: float = ALPHA, model: str = "auto", progress=None, workers: int = 1,
             scheduler: str | None = None, tie_design: bool = True, missing_force: bool = True,
             **fit_options) -> Diagnosis:
    """Find what the base model lacks (module docstring).

    Parameters
    ----------
    table : TrajectoryTable
        The measured walk.
    params : Params
        The base model; ``free`` its parameters to fit.
    effects : sequence of str, optional
        Restrict the candidate effects (default: the whole library).
    parameters : sequence of str, optional
        The held parameters that are candidates (default :data:`PARAMETERS`).
    alpha : float
        Family-wise false-alarm rate.
    model : {'auto', 'periodic', 'transient'}
        The base model of the walk; 'auto' (default, as ``toywalk diagnose``) lets
        :func:`chosen_model` say which.
    progress : callable, optional
        Called with one line of text at each stage.
    workers, scheduler
        The candidates' fits and the held-out folds in ``workers`` local processes or on a Dask
        cluster (:func:`toywalk.sysid.heldout.run_fits`).
    tie_design : bool
        When candidates are left tied (within :data:`SEPARATION`), weigh which further walk
        would tell them apart (:func:`toywalk.sysid.design.next_walk`, ``Diagnosis.next_walk``).
    missing_force : bool
        When no cause is named (``unexplained`` or ``partly explained``), search the port
        dictionary for the shape of the missing force (:mod:`toywalk.sysid.missing_force`,
        ``Diagnosis.missing_force``).
    **fit_options
        Passed to every fit (``offsets``, ``priors``, ``strikes``, ...).
    """
    if not candidates(params, free, effects, parameters) and not missing_force:
        raise DiagnoseError("no candidate causes to test: give some effects or parameters, or let the "
                            "analysis search the port dictionary for the missing force")
    started = time.perf_counter()  # the model's choice is part of the analysis's time
    if model == "auto":
        model = chosen_model([table], [params], free, progress=progress, **fit_options)
    with FitPool(workers, scheduler) as pool:
        return _diagnose(table, params, free=free, effects=effects, parameters=parameters, alpha=alpha,
                         model=model, progress=progress, pool=pool, tie_design=tie_design,
                         missing_force=missing_force, started=started, **fit_options)


def _diagnose(table: TrajectoryTable, params: Params, *, free, effects, parameters, alpha: float,
              model: str, progress, pool: FitPool, tie_design: bool, missing_force: bool = False,
              started: float | None = None, **fit_options) -> Diagnosis:
    say = progress or (lambda _msg: None)
    clock = time.perf_counter()
    seconds: dict = {}
    if started is not None:  # the choice of the base model (diagnose's 'auto') came first
        seconds["model_choice"] = clock - started
        clock = started
    if not 0 < alpha < 1:
        raise DiagnoseError(f"alpha must be in (0, 1), got {alpha!r}")
    free = list(free)
    cands = candidates(params, free, effects, parameters)
    k = len(cands)
    options = dict(fit_options, model=model)
    candidate_options = dict(options, max_iter=min(options.get("max_iter", 500), _CANDIDATE_ITERATIONS))
    say(f"base fit ({', '.join(free) or 'no free parameters'})")
    base, strikes, fallback = _base_fit(table, params, free, options, say)
    seconds["base"] = base.seconds
    if not base.success:
        raise DiagnoseError(f"the base model does not fit the walk ({base.status}); "
                            + "; ".join(base.warnings))
    if set(free) & set(base.undetermined):
        raise DiagnoseError(f"the {base.model} base fit does not determine "
                            f"{', '.join(n for n in free if n in base.undetermined)} (its information is "
                            "singular): free fewer parameters"
                            + (", or use the periodic model" if base.model == "transient" else ""))
    obs = observations(table)
    noise_note = ""
    if base.noise_source == "estimated from residuals":
        noise, taken, noise_note = _scatter_check(obs, base)
        if noise is not None:
            say("refitting the base with the noise of the samples' scatter")
            again, strikes_again, fallback_again = _base_fit(
                table, params, free, dict(options, strikes=strikes), say, noise)
            seconds["base"] += again.seconds
            if again.success:
                again.noise_source = "scatter within steps (4th differences)" + (
                    "" if len(taken) == len(noise) else f" for {', '.join(taken)}; the others' residual RMS")
                base, strikes, fallback = again, strikes_again, fallback or fallback_again
            else:
                noise_note += (f"; refitted with the scatter as the noise the base did not converge "
                               f"({again.status}), so the residual RMS stands for the noise")
    # Every later fit reads the walk on the base fit's strikes, so that all are compared alike.
    options["strikes"] = candidate_options["strikes"] = strikes
    res_base = residual_report(obs, base.residuals, alpha=alpha)
    sigma = base.sigma[:len(obs.value)]
    features = feature_misfit(obs, obs.value, obs.value + base.residuals, base.model_durations,
                              sigma=sigma, rng=0)
    noise = dict(base.noise_sd)
    noise_opt = {} if base.noise_source in ("file", "given") else {"noise_sd": noise}
    say(f"screening {k} candidates by score tests")
    lap = time.perf_counter()
    by_period: dict[int, list[Candidate]] = {}
    for c in cands:
        by_period.setdefault(gait_period(params, free + [c.name]), []).append(c)
    scores = {}
    for group in by_period.values():
        scores.update(score_tests(table, base, [c.name for c in group]))
    ranking = []
    for c in cands:
        s = scores[c.name]
        z = s["z"]
        # log p as well: far from the base model p underflows to 0 for several candidates at
        # once (z of 50 to 200), and the ranking must still tell them apart
        log_p = (float(special.log_ndtr(-c.side * z)) if c.side
                 else math.log(2.0) + float(special.log_ndtr(-abs(z))))
        ranking.append({"effect": c.name, "kind": c.kind, "score_z": z, "score_p": math.exp(log_p),
                        "score_log_p": log_p, "linear_estimate": c.base + s["step"],
                        "linear_se": s["se"], "design_effect": s["inflation"]})
    ranking.sort(key=lambda r: r["score_log_p"])
    seconds["screening"] = time.perf_counter() - lap
    level = alpha / max(k, 1)
    significant = [r for r in ranking if r["score_p"] < level]
    evidence = _evidence(res_base, features, ranking[:3])
    if noise_note:
        evidence = f"{noise_note}; {evidence}"
    if fallback:
        evidence = f"{fallback}; {evidence}"
    if not significant and not res_base.systematic:
        seconds["total"] = time.perf_counter() - clock
        complete_rows(ranking)
        return Diagnosis("adequate", None, [], ranking, {}, evidence, base, {}, res_base, None,
                         features, None, RULE, alpha, seconds)
    to_fit = (significant or ranking[:2])[:MAX_EXTENDED]
    # An effect whose score at its null does not speak for its range (Effect.local False:
    # soft_heel) is fitted whatever its score says.
    to_fit += [r for r in ranking if r not in to_fit and not _local(r["effect"])]
    extended = {}
    by_name = {c.name: c for c in cands}
    say(f"extended fits: {', '.join(r['effect'] for r in to_fit)}")
    tasks, owner = [], []
    for i, row in enumerate(to_fit):
        for value in _starts(row["effect"]):  # a local candidate from the base fit, else several
            tasks.append(dict(table=table, free=free + [row["effect"]], check_jacobian=False,
                              **(dict(params=base.params, warm=base) if value is None else
                                 dict(params=base.params.replace(**{row["effect"]: value}))),
                              **candidate_options, **noise_opt))
            owner.append(i)
    results = run_fits(tasks, pool)
    fits = [_best([r for r, o in zip(results, owner, strict=True) if o == i]) for i in range(len(to_fit))]
    # One scale for the chi-squares the candidates are compared on: the largest design effect of
    # those fitted (1 with nothing shared), so that their order and gaps stay chi-square's; each
    # candidate's own design effect for its p-value (score.score_statistics).
    common = max((r["design_effect"] for r in to_fit), default=1.0)
    for row, ext in zip(to_fit, fits, strict=True):
        name = row["effect"]
        if isinstance(ext, str):
            row.update(fitted=False, reason=ext)
            continue
        if name in ext.undetermined:  # no interval, no Bayes factor, never named
            row.update(fitted=False, reason=f"{name} is not determined by this walk (the fit's "
                       "information is singular)")
            continue
        extended[name] = ext
        seconds[name] = ext.seconds
        # the errors shared by phase make chi-square's drop larger than chance alone would with
        # every error its own: divided by a design effect (score.score_statistics)
        drop = base.chi2 - ext.chi2
        lr = drop / common
        est, se = ext.estimates[name], ext.std[name]
        row.update(fitted=bool(ext.success), status=ext.status, lr=lr,
                   lr_p=lr_p_value(drop / row["design_effect"], bool(by_name[name].side)), score=lr,
                   estimate={name: est}, interval={name: [est - 1.96 * se, est + 1.96 * se]},
                   std=se, log_bayes_factor=_savage_dickey(est, se, by_name[name]),
                   shared_widening=ext.shared_widening.get(name),
                   max_abs_eigenvalue=ext.gait.get("max_abs_eigenvalue"))
    fitted = sorted((r for r in to_fit if r.get("fitted")), key=lambda r: -r["lr"])
    held: dict = {}
    reference = noise_reference(obs, base.noise_sd, base.noise_source)

    def held_out_gain(row: dict) -> tuple[float, str]:
        name = row["effect"]
        say(f"held-out prediction by stride: base and {name}")
        tasks = (held_out_tasks(table, base.params, free, noise, base, **options)
                 + held_out_tasks(table, extended[name].params, free + [name], noise, extended[name],
                                  **options))
        lap = time.perf_counter()
        fits = held_out_fits(tasks, pool)
        seconds["held_out"] = time.perf_counter() - lap
        held["base"] = held_out_score(table, fits[:2], noise)
        held[name] = held_out_score(table, fits[2:], noise)
        reasons = "; ".join(h["reason"] for h in held.values() if h.get("reason"))
        return held["base"]["chi2"] - held[name]["chi2"], reasons

    def together(best: dict, runner: dict) -> bool:
        if not compatible(best["effect"], runner["effect"]):  # the fits refuse them together
            return False
        say(f"pair fit: {best['effect']} + {runner['effect']}")
        pair = fit(table, extended[best["effect"]].params, free + [best["effect"], runner["effect"]],
                   check_jacobian=False, warm=extended[best["effect"]], **candidate_options, **noise_opt)
        seconds["pair"] = pair.seconds
        lr_pair = extended[best["effect"]].chi2 - pair.chi2
        if pair.success and lr_p_value(lr_pair, bool(by_name[runner["effect"]].side)) < alpha / max(k - 1, 1):
            extended[f"{best['effect']}+{runner['effect']}"] = pair
            return True
        return False

    explained: dict = {}

    def explain(names: list) -> Explanation:
        ext = extended["+".join(names)]
        report = residual_report(obs, ext.residuals, bins=res_base.bins, alpha=alpha)
        misfit = feature_misfit(obs, obs.value, obs.value + ext.residuals, ext.model_durations,
                                sigma=sigma, rng=0)
        explained.update(fit=ext, residuals=report, features=misfit)
        h_base, h_ext = held["base"], held[names[0]]
        walk = {"rms": h_ext["rms"], "rms_base": h_base["rms"], "n": h_ext["n_by_signal"]}
        return judge(names, held=[("", walk, reference)], patterns=[("", report)],
                     features=[("", misfit)], alpha=alpha,
                     whiteness=white_components(reference, report, base.noise_source))

    decision = decide(fitted, level, explain=explain, held_out=held_out_gain, together=together)
    res_ext, features_ext, gain_block = explained.get("residuals"), explained.get("features"), {}
    if decision.explanation is not None:
        ext, lead = explained["fit"], decision.lead["effect"]
        h_base, h_ext = held["base"], held[lead]
        gain_block = {
            "metric": "held-out chi-square (two folds of alternate strides)",
            "model": "+".join(decision.explanation.candidates),
            "base": h_base["chi2"], "extended": h_ext["chi2"],
            "held_out_rms": {"base": h_base["rms"], "extended": h_ext["rms"]},
            "chi2": {"base": base.chi2, "extended": ext.chi2},
            "max_abs_eigenvalue": {"base": base.gait.get("max_abs_eigenvalue"),
                                   "extended": ext.gait.get("max_abs_eigenvalue")},
            "stable": {"base": base.gait.get("stable"), "extended": ext.gait.get("stable")},
            "features": {key: {"base": features[key]["z"], "extended": features_ext[key]["z"]}
                         for key in features},
        }
    if decision.reason:
        evidence += f"; {decision.reason}"
    if decision.causes:
        note = parameter_note(decision.lead, by_name[decision.lead["effect"]])
        evidence += f"; {note}" if note else ""
    further = None
    close = tied(fitted, level) if decision.tied and tie_design else []
    if close:
        lap = time.perf_counter()
        further = weigh_ties([table], [base], cands, close, pool=pool, alpha=alpha, say=say,
                             **fit_options)
        seconds["next_walk"] = time.perf_counter() - lap
        evidence += further_walk_clause(further)
    found = None
    if missing_force and decision.cause == "unexplained":
        lap = time.perf_counter()
        found = discover(table, base, free, alpha=alpha, pool=pool, noise=noise, say=say,
                         **candidate_options, **noise_opt)
        seconds["missing_force"] = time.perf_counter() - lap
        evidence += f"; {missing_force_clause(found)}"
    complete_rows(ranking)
    ranking.sort(key=lambda r: (-r["lr"] if "lr" in r else math.inf, r["score_log_p"]))
    return Diagnosis(decision.verdict, decision.cause, decision.causes, ranking, gain_block, evidence,
                     base, extended, res_base, res_ext, features, features_ext, RULE, alpha,
                     dict(seconds, total=time.perf_counter() - clock), further, found,
                     effective=decision.explanation.to_json() if decision.explanation else None)


def _base_fit(table, params: Params, free, options: dict, say,
              noise_sd: dict | None = None) -> tuple[FitResult, str, str]:
    """The base fit, the heel strikes it reads the walk on (``options``' ``strikes``, or
    ``"measured"`` after a fallback), and why it fell back (empty: it did not).
    A base model far from the walk can fail on its own heel strikes (its clock drifts through the
    walk and the time offset has other minima; measured: a stable-toy walk with hip damping 2e-4
    ended at IPOPT's cap with the offset a whole step out) while the same misfit aligned on the
    measured strikes converges; every fit of the analysis then reads the walk between the measured
    strikes, so that all are compared alike."""
    given = {} if noise_sd is None else {"noise_sd": noise_sd}
    strikes = options.get("strikes", "model")
    first = dict(options, max_iter=min(options.get("max_iter", 500), _BASE_ITERATIONS))
    base = fit(table, params, free, check_jacobian=False, **first, **given)
    if strikes != "model":
        return base, strikes, ""
    worse = max((base.residual_rms[n] / v for n, v in (base.aligned_rms or {}).items() if v > 0), default=0.0)
    if base.success and worse <= ANOTHER_MINIMUM:
        return base, strikes, ""
    if base.success:
        fallback = (f"the base fit on the model's own heel strikes ended {worse:.1f} times further from "
                    "the angles than aligned on the measured strikes (another minimum of the time "
                    "offset), so every fit reads the walk between the measured strikes")
    else:
        fallback = (f"the base fit on the model's own heel strikes did not converge ({base.status}), "
                    "so every fit reads the walk between the measured strikes")
    say(fallback)
    spent = base.seconds
    base = fit(table, params, free, check_jacobian=False, **dict(options, strikes="measured"), **given)
    base.seconds += spent
    return base, "measured", fallback


def _scatter_check(obs, base: FitResult) -> tuple[dict | None, list[str], str]:
    """The noise SDs to refit the base with where its residual RMS is mostly misfit (None: keep
    the residual RMS), the signals whose noise is their scatter in it, and what was found, in
    words (empty: nothing to say).

    A signal whose residual RMS is more than :data:`NOISE_INFLATION` times its samples' scatter
    takes the scatter as its noise, provided its scatter is white (:data:`NOISE_WHITENESS`);
    when every signal's is, every signal takes its scatter. Otherwise each kind of signal
    (:data:`NOISE_GROUPS`: lean, steer, the pitches) is judged on its own: a fast pitch's
    curvature can push its scatter over alternate samples past the limit (white noise or not),
    and should not keep a steer misfit ten times its noise standing for the steer's noise
    (docs/diagnosis.md, the cross slope at 10 noise SDs)."""
    scatter = scatter_noise(obs)
    ratio = {n: base.noise_sd[n] / v["sd"] for n, v in scatter.items() if v["sd"] > 0 and n in base.noise_sd}
    if not ratio or max(ratio.values()) <= NOISE_INFLATION:
        return None, [], ""
    shown = ", ".join(f"{n} {r:.1f}" for n, r in ratio.items())
    white = {n: v["sd_alternate"] / v["sd"] for n, v in scatter.items() if v["sd"] > 0}
    if len(ratio) == len(scatter) and max(white.values()) <= NOISE_WHITENESS:
        return ({n: v["sd"] for n, v in scatter.items()}, list(scatter),
                f"the noise is the samples' scatter within steps: the base fit's residual RMS is {shown} "
                "times it, mostly the model's misfit")
    # judged by kind of signal: the two legs' pitches together, so that the weights keep the
    # walker's mirror symmetry (one pitch's scatter taken and the other's refused made a walk of
    # a symmetric walker score an uneven build at z = 3.1)
    groups = [[n for n in group if n in ratio] for group in NOISE_GROUPS]
    taken, refused = [], []
    for group in groups:
        if any(ratio[n] > NOISE_INFLATION for n in group):
            (taken if all(white[n] <= NOISE_WHITENESS for n in group) else refused).extend(group)
    correlated = (f"the noise of {', '.join(refused)} is correlated from sample to sample (scatter "
                  f"over alternate samples {', '.join(f'{white[n]:.2f}' for n in refused)} times "
                  "larger), so the residual RMS stands for it and the likelihood ratios are understated: "
                  "give the noise SD")
    unmeasured = "not every signal's scatter could be measured: give the noise SD"
    if not taken or len(ratio) < len(scatter):
        return None, [], (f"the base fit's residual RMS is {max(ratio.values()):.1f} times the samples' "
                      f"scatter ({shown}), but " + (correlated if refused else unmeasured))
    note = (f"the noise of {', '.join(taken)} is the samples' scatter within steps (the base fit's "
            f"residual RMS is {shown} times it, mostly the model's misfit); the other signals keep "
            f"their residual RMS (scatter over alternate samples up to {max(white.values()):.2f} times "
            "that over every sample)")
    if refused:
        note += f"; {correlated}"
    return {n: (scatter[n]["sd"] if n in taken else base.noise_sd[n]) for n in scatter}, taken, note


def _local(name: str) -> bool:
    """A candidate's score test at its null speaks for its range (:attr:`Effect.local`)."""
    return not name.startswith("effects.") or EFFECTS[name.split(".", 1)[1]].local


#: The starts of a candidate whose score does not speak for its range (:func:`_local`), in units
#: of its typical strength: soft_heel's 0.5 to 4 ms, MuJoCo's contact times and the brass
#: strip's estimate (docs/soft_feet.md section 4). Its misfit has several minima in tau, and a
#: fit from tau = 0 ended in the wrong one (docs/soft_feet.md section 8).
NONLOCAL_STARTS = (0.5, 1.0, 2.0, 4.0)


def _starts(name: str) -> list:
    """A candidate's extended fits' starts: None (the base fit's solution) for a local one, else
    its value at each of :data:`NONLOCAL_STARTS` within its bounds."""
    if _local(name):
        return [None]
    effect = EFFECTS[name.split(".", 1)[1]]
    low, high = effect.bounds
    return [v for v in (f * effect.typical for f in NONLOCAL_STARTS) if low <= v <= high]


def _best(results: list):
    """Of one candidate's fits from several starts, the converged one with the least chi-square;
    else the first fit; else the first reason why none could be set up."""
    done = [r for r in results if not isinstance(r, str)]
    converged = [r for r in done if r.success]
    if converged:
        return min(converged, key=lambda r: r.chi2)
    return done[0] if done else results[0]


def _evidence(res: ResidualReport, features: dict, top: list) -> str:
    """What the base residuals show, in a sentence."""
    parts = []
    if res.systematic:
        parts.append("a pattern repeated every step in " + ", ".join(
            f"{n} (p = {res.tests[n]['pattern_p']:.2g})" for n in res.systematic))
    missed = missed_features(features)
    if missed:
        parts.append("gait features missed: " + ", ".join(f"{k} by {features[k]['z']:+.1f} SE"
                                                          for k in missed[:4]))
    parts.append("score tests point to " + ", ".join(
        f"{r['effect']} (z = {r['score_z']:+.1f})" for r in top))
    return "; ".join(parts)
