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
   candidate: :func:`toywalk.sysid.fit.score_tests`). A candidate whose base value sits on a
   physical bound (a damper at zero) is tested one-sided.
3. **Adequate** when no candidate's score p-value is below ``alpha / K`` (K candidates,
   Bonferroni) and no signal shows a repeated pattern at ``alpha``.
4. Otherwise **extended fits** of the best-screened candidates (at most :data:`MAX_EXTENDED`), each
   scored by the likelihood ratio against the base with one noise model (the base fit's: a
   misfit inflates it, which only makes the test conservative), chi-square on one degree of
   freedom (a 50:50 mixture with zero for a bounded null: Self & Liang 1987, JASA 82:605), and by
   **held-out prediction grouped by stride**: the strides are split into two folds (alternate
   strides), each model is fitted on one fold and predicts the other's angles (samples within a
   stride are not independent; strides are). A Savage-Dickey ratio at the null value (Dickey
   1971, Ann. Math. Stat. 42:204; Gaussian posterior of the extended fit, prior normal about the
   base value with the candidate's :attr:`Candidate.prior_sd`, half-normal on a bounded null)
   is reported beside.
5. **A cause is named** when its likelihood ratio's p-value is below ``alpha / K``, it predicts
   the held-out strides better than the base (summed over both folds), and it beats every other
   significant candidate by at least :data:`SEPARATION` in chi-square (a likelihood ratio of
   100 between two one-parameter extensions). Two causes are named when the runner-up, added to
   the named one, is itself significant at ``alpha / (K - 1)``.
6. **Unexplained** when the data disagree with the base model but no candidate is decisive, or
   when the extended model still leaves a pattern repeated every step.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time

import numpy as np
from scipy import special
from toywalk.model.effects import EFFECTS
from toywalk.model.parameters import Params
from toywalk.model.trajectory import SIGNALS, TrajectoryTable

from .fit import FitError, FitResult, fit, fit_bounds, gait_period, score_tests
from .measurement import observations
from .residuals import (
    NOISE_INFLATION,
    ResidualReport,
    feature_misfit,
    missed_features,
    residual_report,
    scatter_noise,
)
from .sample import worker_pool

__all__ = ["ALPHA", "MAX_EXTENDED", "PARAMETERS", "SEPARATION", "Candidate", "Diagnosis",
           "DiagnoseError", "FitPool", "Verdict", "candidates", "complete_rows", "diagnose", "held_out",
           "held_out_fits", "held_out_score", "held_out_tasks", "lr_p_value", "run_fits", "tied",
           "weigh_ties"]

#: Family-wise false-alarm rate of the verdict.
ALPHA = 0.01
#: Base parameters that are candidate causes when the analysis holds them fixed: the foot's shape,
#: where the balance masses sit, the hip width and the slope.
PARAMETERS = ("foot_radius", "foot_lateral_radius", "com_offset[0]", "com_offset[1]",
              "com_offset[2]", "hip_width", "slope")
#: Candidates fitted in full after screening.
MAX_EXTENDED = 4
#: Chi-square margin by which a named cause must beat every other significant candidate.
SEPARATION = 2.0 * math.log(100.0)
#: IPOPT's iteration cap for a candidate's fit from the base fit: a candidate that does not
#: converge from there in this many is not an explanation of the walk (measured: the hidden
#: effect's fit converges in under 20).
_CANDIDATE_ITERATIONS = 100
#: IPOPT's iteration cap for the base fit on the model's own heel strikes before the analysis
#: falls back to the measured strikes (a failing one otherwise runs to 500: 6 min on a loaded machine).
_BASE_ITERATIONS = 200
#: SD of a held-out fold's samples (rad, m): weight 1e-12 of a measured one, so that the fold's
#: fit ignores them while their residuals are still computed.
_HELD_OUT_SD = 1e3
#: A base fit on the model's own strikes whose angle residuals' RMS ends over this many times
#: that of its aligned stage (the measured strikes taken as exact; ``FitResult.aligned_rms``) in
#: some signal has found another minimum of the time offset, and is treated as not converged.
#: Measured: 1.00 +- 0.01 on walks of the stable toy (the base model's own, and with rolling
#: resistance hidden); 3.5 to 8.7 with hip dry friction hidden (1.8e-4 N m, seed 202), an IPOPT
#: "acceptable" exit 8 to 15 times the noise, from which the analysis named the slope.
ANOTHER_MINIMUM = 2.0
#: When the walk gives no noise SD, the base fit's residual RMS stands for it unless it is more
#: than :data:`toywalk.sysid.residuals.NOISE_INFLATION` times the samples' own scatter: then it is
#: mostly the base model's misfit, and the scatter is the noise, provided the scatter over every
#: other sample is at most this many times that over every sample: noise correlated from sample to
#: sample has less scatter than its SD, and is not used (on 12-step walks at 140 samples/s: 4 % of
#: white signals exceed it, and 83 % of signals whose noise is a three-sample running mean).
NOISE_WHITENESS = 1.3
#: The kinds of signal whose noise is judged together (:func:`_scatter_check`).
_NOISE_GROUPS = (("lean",), ("steer",), ("pitch_left", "pitch_right"))


class DiagnoseError(ValueError):
    """The analysis cannot be made (no base fit, no candidates); the message says why."""


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One candidate cause: a parameter-file name freed from its base value.

    Attributes
    ----------
    name : str
        ``effects.<name>`` or a parameter name.
    kind : str
        'effect' or 'parameter'.
    base : float
        Its value in the base model.
    bounds : tuple of float
        Physical bounds (the fit's).
    side : int
        +1 when the base value is on the lower bound (only increases are possible), -1 on the
        upper one, 0 otherwise.
    prior_sd : float
        Scale of the Savage-Dickey prior: an effect's ``typical`` magnitude; a tenth of the leg
        length for lengths; 0.02 rad for the slope.
    breaks_symmetry : bool
    """

    name: str
    kind: str
    base: float
    bounds: tuple
    side: int
    prior_sd: float
    breaks_symmetry: bool


def candidates(params: Params, free=(), effects=None, parameters=None) -> list[Candidate]:
    """The candidate causes: the library's effects (or those named in ``effects``) and the
    parameters of :data:`PARAMETERS` (or ``parameters``), less the free ones and those that
    cannot move (both bounds at the base value)."""
    names = []
    chosen = list(EFFECTS) if effects is None else list(effects)
    for name in chosen:
        if name.removeprefix("effects.") not in EFFECTS:
            raise DiagnoseError(f"unknown effect {name!r}; the library has {', '.join(EFFECTS)}")
        names.append("effects." + name.removeprefix("effects."))
    names += list(PARAMETERS if parameters is None else parameters)
    out = []
    for name in names:
        if name in free:
            continue
        low, high = fit_bounds(params, list(free) + [name], name)
        value = params.get(name)
        tiny = 1e-12 * max(abs(value), 1.0)
        if high - low <= tiny:
            continue
        side = 1 if value - low <= tiny else (-1 if high - value <= tiny else 0)
        if name.startswith("effects."):
            effect = EFFECTS[name.split(".", 1)[1]]
            kind, prior, breaks = "effect", abs(effect.typical), effect.breaks_symmetry
        else:
            kind = "parameter"
            prior = 0.02 if name == "slope" else 0.1 * params.leg_length
            breaks = False
        out.append(Candidate(name, kind, float(value), (float(low), float(high)), side, prior, breaks))
    if not out:
        raise DiagnoseError("no candidate causes left to test (all free or fixed by their bounds)")
    return out


@dataclasses.dataclass
class Verdict:
    """What every discrepancy analysis answers: the fields of ``report.json`` (pipeline.md).

    Attributes
    ----------
    verdict : str
        'adequate' or 'discrepancy'.
    cause : str or None
        The named cause, ``"unexplained"``, or None (adequate).
    causes : list of str
        Every named cause (two when two are decisive).
    ranking : list of dict
        Every candidate, best first.
    gain : dict
        The fit before and after the named cause, and the change in predicted stability.
    evidence : str
        What in the data pointed to the cause.
    """

    verdict: str
    cause: str | None
    causes: list
    ranking: list
    gain: dict
    evidence: str


@dataclasses.dataclass
class Diagnosis(Verdict):
    """The analysis (:func:`diagnose`); :meth:`to_json` is ``report.json`` (pipeline.md).

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

    def to_json(self) -> dict:
        return {
            "verdict": self.verdict, "cause": self.cause, "causes": self.causes,
            "ranking": self.ranking, "gain": self.gain, "evidence": self.evidence,
            "rule": self.rule, "alpha": self.alpha, "seconds": self.seconds,
            "next_walk": self.next_walk,
            "base": {"free": self.base.free, "estimates": self.base.estimates, "std": self.base.std,
                     "chi2": self.base.chi2, "n_residuals": self.base.n_residuals,
                     "noise_sd": self.base.noise_sd, "noise_source": self.base.noise_source,
                     "gait": self.base.gait, "model": self.base.model},
            "residuals": self.residuals.to_json(),
            "residuals_extended": self.residuals_extended.to_json() if self.residuals_extended else None,
            "features": self.features, "features_extended": self.features_extended,
        }


RULE = ("adequate: no candidate's score test below alpha/K and no signal with a pattern repeated "
        "every step (Hotelling, alpha over the signals); a cause is named when its likelihood "
        "ratio is below alpha/K, it predicts held-out strides better than the base, and it beats "
        f"every other significant candidate by {SEPARATION:.1f} in chi-square; unexplained "
        "otherwise, or when the extended model still leaves a repeated pattern")


def lr_p_value(lr: float, bounded: bool) -> float:
    """Likelihood-ratio p-value on one degree of freedom; a 50:50 mixture with zero for a null on
    a physical bound (Self & Liang 1987, JASA 82:605)."""
    p = float(special.chdtrc(1, max(lr, 0.0)))
    return 0.5 * p if bounded else p


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


def _strides(n_steps: int) -> np.ndarray:
    """Each measured step's fold: alternate strides (pairs of steps) go to folds 0 and 1."""
    return (np.arange(n_steps) // 2) % 2


def held_out_tasks(table: TrajectoryTable, params: Params, free, noise: dict,
                   warm: FitResult | None = None, **fit_options) -> list[dict]:
    """The two fits of held-out prediction grouped by stride (:func:`held_out`), as keyword
    arguments of :func:`toywalk.sysid.fit.fit`: alternate strides form two folds (:func:`_strides`),
    each fit sees one fold. The held-out samples stay in the fit with a huge SD
    (:data:`_HELD_OUT_SD`), so the model is read at them without their weighing in; heel strikes
    and contact positions of the whole walk remain data. ``warm``, a fit of the whole walk, is
    where each fold's fit starts."""
    obs = observations(table)
    fold_of_step = _strides(obs.n_steps)
    sd = {name: float(noise[name]) for name in SIGNALS if name in noise}
    # The folds carry their noise in the table's SD columns (the held-out samples' huge SD among
    # them), so a noise SD given to the whole analysis is not passed on.
    options = {k: v for k, v in fit_options.items() if k != "noise_sd"}
    return [dict(table=_masked(table, obs, np.flatnonzero(fold_of_step == fold), sd), params=params,
                 free=list(free), noise_sd=None, check_jacobian=False, warm=warm, **options)
            for fold in (0, 1)]


def held_out_score(table: TrajectoryTable, fits: list, noise: dict) -> dict:
    """Score the two fold fits of :func:`held_out_tasks`: the held-out chi-square (with ``noise``)
    overall and per signal, the held-out RMS per signal, and whether both fits converged. A fold
    whose fit could not be set up (a string) or did not converge leaves the chi-square NaN, with
    the ``reason``: a fit stopped on its way predicts nothing about the model."""
    obs = observations(table)
    fold_of_step = _strides(obs.n_steps)
    failed = [f if isinstance(f, str) else f"fold {k}'s fit ended with {f.status}"
              for k, f in enumerate(fits) if isinstance(f, str) or not f.success]
    if failed:
        return {"chi2": math.nan, "chi2_by_signal": {}, "rms": {}, "success": False, "n": 0,
                "reason": "; ".join(failed)}
    chi2, per_signal, squares, counts = 0.0, {}, {}, {}
    for fold, result in zip((0, 1), fits, strict=True):
        held = np.isin(obs.step, np.flatnonzero(fold_of_step == fold))
        for s_i, name in enumerate(SIGNALS):
            sel = held & (obs.signal == s_i)
            if not np.any(sel):
                continue
            r = result.residuals[sel]
            c = float(np.sum((r / float(noise[name])) ** 2))
            chi2 += c
            per_signal[name] = per_signal.get(name, 0.0) + c
            squares[name] = squares.get(name, 0.0) + float(np.sum(r**2))
            counts[name] = counts.get(name, 0) + int(sel.sum())
    rms = {k: math.sqrt(squares[k] / counts[k]) for k in squares}
    return {"chi2": chi2, "chi2_by_signal": per_signal, "rms": rms,
            "success": all(f.success for f in fits), "n": int(sum(counts.values()))}


def held_out(table: TrajectoryTable, params: Params, free, noise: dict, warm: FitResult | None = None,
             workers: int = 1, **fit_options) -> dict:
    """Held-out prediction grouped by stride: fit on one fold of strides, predict the other's
    angles, both ways round (:func:`held_out_tasks`, :func:`held_out_score`)."""
    tasks = held_out_tasks(table, params, free, noise, warm, **fit_options)
    return held_out_score(table, held_out_fits(tasks, workers), noise)


def held_out_fits(tasks: list[dict], workers: int = 1, scheduler: str | None = None,
                  runner=None) -> list:
    """:func:`run_fits` of fold tasks (:func:`held_out_tasks`, consecutive pairs of one model's
    two folds), each fold whose fit fails retried once from the other fold's converged fit (or,
    when neither converged, from the model's own start: ``warm`` None). ``runner`` as
    :func:`run_fits`'s (the joint analysis of several walks passes its own).

    Why: started from the whole walk's optimum, a fold's fit can wander off. On a 12-step walk of
    the stable toy with a cross slope of 1.0667e-3 (seed 207 of docs/make_diagnose_validation.py)
    one fold's fit of the cross slope ended in IPOPT's restoration failure; scored, it made the
    extended model's held-out chi-square 350 worse than the base's, and the analysis called the
    walk unexplained. Refitted from the other fold's, it converges and the model gains 205."""
    fits = run_fits(tasks, workers, scheduler, runner)
    retry = {k: _restarted(tasks[k], start) for k, start in _fold_retries(fits).items()}
    for k, f in zip(retry, run_fits(list(retry.values()), workers, scheduler, runner), strict=True):
        if not isinstance(f, str):
            f.warnings.append(f"refitted from {'the other fold' if retry[k]['warm'] else 'its start'}: "
                              f"the first fit from the whole walk's ended with {fits[k].status}")
        fits[k] = f
    return fits


def _fold_retries(fits: list) -> dict:
    """Of fold fits in consecutive pairs (one model's two folds; a string where a fit could not
    be set up), each that failed, mapped to the fit to start it again from: the other fold's,
    when that converged, else None (the model's own start)."""
    retry = {}
    for k, f in enumerate(fits):
        if isinstance(f, str) or f.success:
            continue
        other = fits[k ^ 1]
        retry[k] = other if not isinstance(other, str) and other.success else None
    return retry


def _restarted(task: dict, start) -> dict:
    """A fit's task started again from the fit ``start`` (None: from the model's own start). A
    single walk's fit also takes ``start``'s parameters (:func:`toywalk.sysid.fit.fit`'s
    ``params`` hold its ``warm``'s estimates); a joint fit of several walks
    (:class:`toywalk.sysid.walks.WalksFit`, no ``params``) reads them from ``warm`` itself."""
    if start is None:
        return dict(task, warm=None)
    params = getattr(start, "params", None)
    return dict(task, warm=start, **({} if params is None else {"params": params}))


class FitPool:
    """Where an analysis runs its batches of fits (:func:`run_fits`): in this process, in
    ``workers`` local processes, or on a Dask cluster (``scheduler``).

    The processes (or the cluster's client) are started for the first batch of more than one fit
    and kept for the next ones until the ``with`` block ends: a spawned worker imports the model,
    loads its compiled functions and searches each walk's starting gait (kept by
    :func:`toywalk.model.gait.find_gait`) once an analysis, not once a batch.
    """

    def __init__(self, workers: int = 1, scheduler: str | None = None):
        self.workers, self.scheduler = workers, scheduler
        self._stack = contextlib.ExitStack()
        self._pool = None

    def __enter__(self) -> FitPool:
        return self

    def __exit__(self, *exc) -> None:
        self._pool = None
        self._stack.close()

    @property
    def started(self) -> bool:
        """Whether processes (or a client) serve the batches."""
        return self._pool is not None

    def map(self, runner, tasks: list) -> list:
        """``[runner(t) for t in tasks]``, side by side when there is more than one task."""
        if len(tasks) <= 1 or (self.workers <= 1 and not self.scheduler):
            return [runner(t) for t in tasks]
        if self._pool is None:
            self._pool = self._stack.enter_context(worker_pool(self.workers, self.scheduler))
        return list(self._pool.map(runner, tasks))


def run_fits(tasks: list[dict], workers: int | FitPool = 1, scheduler: str | None = None,
             runner=None) -> list:
    """``runner`` (default :func:`toywalk.sysid.fit.fit`, a fit that cannot be set up giving its
    reason, a string, in its place) of each task's keyword arguments: in this process, in
    ``workers`` local processes, or on a Dask cluster (``scheduler``); or in an analysis's
    :class:`FitPool` given as ``workers``. ``runner`` must be a module-level function, so that
    worker processes can unpickle it."""
    runner = runner or _fit_or_reason
    if isinstance(workers, FitPool):
        return workers.map(runner, tasks)
    with FitPool(min(workers, len(tasks)), scheduler) as pool:
        return pool.map(runner, tasks)


def _fit_or_reason(task: dict):
    try:
        return fit(**task)
    except FitError as err:
        return str(err)


def _masked(table: TrajectoryTable, obs, held_steps: np.ndarray, sd: dict) -> TrajectoryTable:
    """The walk with SD columns: the noise SD everywhere, :data:`_HELD_OUT_SD` in the held-out
    steps."""
    bounds = np.r_[obs.step_start, obs.step_end[-1]]
    step = np.searchsorted(bounds, table.time, side="right") - 1
    held = np.isin(step, held_steps)
    signals = dict(table.signals)
    for name in SIGNALS:
        if name in signals:
            signals[f"{name}_sd"] = np.where(held, _HELD_OUT_SD, sd[name])
    events = [dict(e) for e in table.events]
    return TrajectoryTable(table.time, signals, table.stance, events, dict(table.metadata))


def diagnose(table: TrajectoryTable, params: Params, *, free=(), effects=None, parameters=None,
             alpha: float = ALPHA, model: str = "periodic", progress=None, workers: int = 1,
             scheduler: str | None = None, tie_design: bool = True, **fit_options) -> Diagnosis:
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
    model : {'periodic', 'transient'}
        The base model of the walk (:func:`toywalk.sysid.fit.periodicity_test` says which).
    progress : callable, optional
        Called with one line of text at each stage.
    workers, scheduler
        The candidates' fits and the held-out folds in ``workers`` local processes or on a Dask
        cluster (:func:`run_fits`).
    tie_design : bool
        When candidates are left tied (within :data:`SEPARATION`), weigh which further walk
        would tell them apart (:func:`toywalk.sysid.design.next_walk`, ``Diagnosis.next_walk``).
    **fit_options
        Passed to every fit (``offsets``, ``priors``, ``strikes``, ...).
    """
    with FitPool(workers, scheduler) as pool:
        return _diagnose(table, params, free=free, effects=effects, parameters=parameters, alpha=alpha,
                         model=model, progress=progress, pool=pool, tie_design=tie_design,
                         **fit_options)


def _diagnose(table: TrajectoryTable, params: Params, *, free, effects, parameters, alpha: float,
              model: str, progress, pool: FitPool, tie_design: bool, **fit_options) -> Diagnosis:
    say = progress or (lambda _msg: None)
    clock = time.perf_counter()
    seconds: dict = {}
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
                        "linear_se": s["se"]})
    ranking.sort(key=lambda r: r["score_log_p"])
    seconds["screening"] = time.perf_counter() - lap
    level = alpha / k
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
    extended = {}
    by_name = {c.name: c for c in cands}
    say(f"extended fits: {', '.join(r['effect'] for r in to_fit)}")
    tasks = [dict(table=table, params=base.params, free=free + [row["effect"]], check_jacobian=False,
                  warm=base, **candidate_options, **noise_opt) for row in to_fit]
    for row, ext in zip(to_fit, run_fits(tasks, pool), strict=True):
        name = row["effect"]
        if isinstance(ext, str):
            row.update(fitted=False, reason=ext)
            continue
        extended[name] = ext
        seconds[name] = ext.seconds
        lr = base.chi2 - ext.chi2
        est, se = ext.estimates[name], ext.std[name]
        row.update(fitted=bool(ext.success), status=ext.status, lr=lr,
                   lr_p=lr_p_value(lr, bool(by_name[name].side)), score=lr,
                   estimate={name: est}, interval={name: [est - 1.96 * se, est + 1.96 * se]},
                   std=se, log_bayes_factor=_savage_dickey(est, se, by_name[name]),
                   max_abs_eigenvalue=ext.gait.get("max_abs_eigenvalue"))
    fitted = sorted((r for r in to_fit if r.get("fitted")), key=lambda r: -r["lr"])
    passing = [r for r in fitted if r["lr_p"] < level]
    held = {}
    cause, causes, named = "unexplained", [], None
    if passing:
        best = passing[0]
        say(f"held-out prediction by stride: base and {best['effect']}")
        tasks = (held_out_tasks(table, base.params, free, noise, base, **options)
                 + held_out_tasks(table, extended[best["effect"]].params, free + [best["effect"]],
                                  noise, extended[best["effect"]], **options))
        lap = time.perf_counter()
        fits = held_out_fits(tasks, pool)
        seconds["held_out"] = time.perf_counter() - lap
        held["base"] = held_out_score(table, fits[:2], noise)
        held[best["effect"]] = held_out_score(table, fits[2:], noise)
        gain = held["base"]["chi2"] - held[best["effect"]]["chi2"]
        best["held_out_gain"] = gain
        runner = passing[1] if len(passing) > 1 else None
        separated = runner is None or best["lr"] - runner["lr"] >= SEPARATION
        if gain > 0 and separated:
            named = best
            causes = [best["effect"]]
            if runner is not None:
                say(f"pair fit: {best['effect']} + {runner['effect']}")
                pair = fit(table, extended[best["effect"]].params,
                           free + [best["effect"], runner["effect"]], check_jacobian=False,
                           warm=extended[best["effect"]], **candidate_options, **noise_opt)
                seconds["pair"] = pair.seconds
                lr_pair = extended[best["effect"]].chi2 - pair.chi2
                bounded = bool(by_name[runner["effect"]].side)
                if pair.success and lr_p_value(lr_pair, bounded) < alpha / max(k - 1, 1):
                    causes.append(runner["effect"])
                    extended["+".join(causes)] = pair
    res_ext, features_ext, gain_block = None, None, {}
    if named is not None:
        ext = extended["+".join(causes)] if len(causes) > 1 else extended[causes[0]]
        res_ext = residual_report(obs, ext.residuals, bins=res_base.bins, alpha=alpha)
        features_ext = feature_misfit(obs, obs.value, obs.value + ext.residuals, ext.model_durations,
                                      sigma=sigma, rng=0)
        h_base, h_ext = held["base"], held[named["effect"]]
        gain_block = {
            "metric": "held-out chi-square (two folds of alternate strides)",
            "base": h_base["chi2"], "extended": h_ext["chi2"],
            "held_out_rms": {"base": h_base["rms"], "extended": h_ext["rms"]},
            "chi2": {"base": base.chi2, "extended": ext.chi2},
            "max_abs_eigenvalue": {"base": base.gait.get("max_abs_eigenvalue"),
                                   "extended": ext.gait.get("max_abs_eigenvalue")},
            "stable": {"base": base.gait.get("stable"), "extended": ext.gait.get("stable")},
            "features": {key: {"base": features[key]["z"], "extended": features_ext[key]["z"]}
                         for key in features},
        }
        cause = causes[0]
        if res_ext.systematic:
            cause = "unexplained"
            evidence += (f"; {' and '.join(causes)} improve the fit but leave a pattern repeated every "
                         f"step in {', '.join(res_ext.systematic)}")
    elif passing:
        best = passing[0]
        gain = best.get("held_out_gain", math.nan)
        if math.isnan(gain):  # a fold's fit failed: held-out prediction could not be scored
            reasons = "; ".join(h["reason"] for h in held.values() if h.get("reason"))
            evidence += (f"; {best['effect']} fits better but its held-out prediction could not be "
                         f"scored ({reasons or 'no held-out chi-square'})")
        elif gain <= 0:
            evidence += f"; {best['effect']} fits better but does not predict held-out strides better"
        else:
            evidence += (f"; {best['effect']} and {passing[1]['effect']} explain the data about "
                         f"equally well (chi-square {best['lr']:.1f} against {passing[1]['lr']:.1f})")
    else:
        evidence += "; no candidate's likelihood ratio is significant"
    further = None
    close = tied(fitted, level) if named is None and tie_design else []
    if close:
        lap = time.perf_counter()
        further = weigh_ties([table], [base], cands, close, pool=pool, alpha=alpha, say=say,
                             **fit_options)
        seconds["next_walk"] = time.perf_counter() - lap
        evidence += _further_evidence(further)
    complete_rows(ranking)
    ranking.sort(key=lambda r: (-r["lr"] if "lr" in r else math.inf, r["score_log_p"]))
    named_causes = causes if cause != "unexplained" else []
    return Diagnosis("discrepancy", cause if causes else "unexplained", named_causes, ranking,
                     gain_block, evidence, base, extended, res_base, res_ext, features,
                     features_ext, RULE, alpha, dict(seconds, total=time.perf_counter() - clock),
                     further)


def tied(ranking: list[dict], level: float) -> list[dict]:
    """The candidates a walk leaves tied: the fitted ones significant at ``level`` whose
    likelihood ratios come within :data:`SEPARATION` of the best one's, best first (empty when
    the best stands alone or none is significant)."""
    passing = sorted((r for r in ranking if r.get("fitted") and r.get("lr_p", 1.0) < level),
                     key=lambda r: -r["lr"])
    if len(passing) < 2:
        return []
    close = [r for r in passing if passing[0]["lr"] - r["lr"] < SEPARATION]
    return close if len(close) > 1 else []


def weigh_ties(tables: list, bases: list, cands: list, close: list[dict], *, pool: FitPool,
               alpha: float, say, **fit_options) -> dict:
    """Which further walk would tell apart the candidates ``close`` (:func:`tied`) left by the
    analysis of ``tables`` with base fits ``bases``: each hidden at its fitted change from its
    base value (:func:`toywalk.sysid.design.next_walk`); ``tied`` and ``reason`` where the walks
    cannot be weighed."""
    from .design import DesignError, next_walk  # the design builds on this module's rule

    say(f"which further walk would tell apart {' and '.join(r['effect'] for r in close)}")
    by_name = {c.name: c for c in cands}
    hidden = {r["effect"]: r["estimate"][r["effect"]] - by_name[r["effect"]].base for r in close}
    try:
        return next_walk(tables, bases, cands, hidden, pool=pool, alpha=alpha, **fit_options)
    except (DesignError, FitError) as err:
        return {"tied": list(hidden), "reason": str(err)}


def _further_evidence(further: dict) -> str:
    """The evidence's clause on the further walk that would break a tie (:func:`_diagnose`)."""
    if "reason" in further:
        return f"; which further walk would tell them apart could not be weighed ({further['reason']})"
    if further["suggestion"] is None:
        return ("; no further walk weighed (a steeper or flatter ramp, the masses moved) would tell "
                "them apart")
    row = next(r for r in further["conditions"] if r["label"] == further["suggestion"])
    return (f"; a further walk with {row['label']} would tell them apart (first order: "
            f"{row['gap']:.0f} in chi-square, named in {100 * row['named_rate']:.0f} % of noise draws; "
            f"the same walk again: {further['same_again']['gap']:.1f})")


def complete_rows(ranking: list) -> list:
    """The keys every ranking row of a report has (pipeline.md: ``effect``, ``score``,
    ``estimate``, ``interval``), in place, where a candidate was not fitted: its score the
    likelihood ratio where there is one, else the score statistic ``z^2`` (None without either),
    and empty estimate and interval. Returns ``ranking``."""
    for row in ranking:
        if "score" not in row:
            row["score"] = row["lr"] if "lr" in row else (row["score_z"] ** 2 if "score_z" in row else None)
        row.setdefault("estimate", {})
        row.setdefault("interval", {})
    return ranking


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
    (:data:`_NOISE_GROUPS`: lean, steer, the pitches) is judged on its own: a fast pitch's
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
    groups = [[n for n in group if n in ratio] for group in _NOISE_GROUPS]
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
