"""Fit the walker's parameters to a measured walk: the gait BVP and the data in one IPOPT problem.

The problem itself (its unknowns, misfit and constraints; the gait a constraint, not a forward
simulation) is :mod:`toywalk.sysid.problem`'s; this module fits it, as the walk needs, and
chooses the model. What a fit returns is :class:`~toywalk.sysid.fitresult.FitResult`; the score
tests of parameters it holds are :mod:`toywalk.sysid.score`'s (both named here too).

Two models of the walk. **Periodic** (the default of :func:`fit`): every measured step is a step of
one gait (a step, or a stride when the mirror symmetry is broken), the walk on its limit cycle.
**Transient**: the recorded steps one after the other from a free start (``bvp(...,
periodic=False)``: a heel-strike state with ``n_dyn - 1`` free directions), for a walk released off
its cycle, still converging to it, or diverging from an unstable one. The periodic model is the
transient one with the start on the fixed point, so the two nest; :func:`periodicity_test` compares
them by the likelihood ratio (Wilks: ``chi2_periodic - chi2_transient`` is chi-square with ``n_dyn -
1`` degrees of freedom when the walk is on its cycle) and says when the periodic fit is not
appropriate.

Uncertainty: the Gauss-Newton covariance ``(J^T J)^-1`` of the whitened residuals, with ``J`` the
total derivative of the residuals in (theta, o) (and the free start of a transient) through the
BVP (implicit-function theorem on ``g``), cross-checked column by column against central
differences that re-solve the BVP. When the trajectory file gives no standard deviations, each
signal's is estimated from the residuals of a first fit and the fit is repeated (so the reduced
chi-square is one by construction).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from scipy import special
from toywalk.model.parameters import Params
from toywalk.model.trajectory import TrajectoryTable

from .fitresult import FitResult
from .measurement import observations
from .problem import (
    CONTACT_KEYS,
    MODELS,
    FitError,
    check_request,
    contact_sigma,
    continued,
    fit_bounds,
    fit_line,
    gait_period,
    parameter_bounds,
    setup,
    shared_covariance,
    sigma_from,
    tied,
    with_values,
)
from .residuals import step_dependence
from .score import held_jacobian, score_statistics, score_tests

__all__ = ["CONTACT_KEYS", "MODELS", "FitError", "FitResult", "PeriodicityTest", "fit", "fit_bounds",
           "gait_period", "held_jacobian", "parameter_bounds", "periodicity_test", "score_statistics",
           "score_tests", "shared_covariance", "tied", "with_values"]

#: The periodicity test's false-alarm rate: the periodic model is rejected when the likelihood
#: ratio's p-value is below it.
PERIODICITY_ALPHA = 0.01

#: Noise SD (rad) assumed for the first pass when the file gives none; the second pass uses the
#: per-signal RMS of the first pass's residuals.
_FIRST_PASS_SD = 0.01
#: Floor of an estimated contact-position SD (m): 10 micrometres, finer than any camera resolves
#: a walking toy (a simulated walk's exact positions would otherwise get weights of 1e16).
_CONTACT_SD_FLOOR = 1e-5


# ------------------------------------------------------------------------------------ fit
def fit(table: TrajectoryTable, params: Params, free, *, model: str = "periodic",
        offsets: bool = True, n_intervals: int | None = None, degree: int | None = None, z_guess=None,
        max_iter: int = 500, check_jacobian: bool = True, priors: dict | None = None,
        noise_sd: dict | None = None, strikes: str = "model",
        warm: FitResult | None = None, progress=None) -> FitResult:
    """Fit ``free`` parameters of ``params`` to the measured walk ``table``.

    Parameters
    ----------
    table : TrajectoryTable
        The measured walk (``toywalk track`` or ``toywalk simulate`` output, or any file in the
        trajectory format of docs/formats.md); a simulation's ``source`` metadata is never read.
    params : Params
        The walker: the starting point, and the values of everything not free.
    free : sequence of str
        Names to fit (``foot_radius``, ``com_offset[1]``, ``effects.impact_trailing_share``).
    model : {'periodic', 'transient', 'auto'}
        The walk on its limit cycle, or the recorded steps from a free start (module docstring);
        'auto' lets :func:`periodicity_test` say which the data need and returns its chosen fit,
        the test in its ``periodicity`` (what ``toywalk fit`` does by default).
    offsets : bool
        Fit the ramp-frame offsets of lean, steer and pitch (nuisance parameters).
    n_intervals, degree : int, optional
        Collocation mesh per step; by default (30, 4) for the periodic model (one step: the
        gait to 1e-11) and (12, 3) for the transient one (every recorded step is a mesh: its
        angles agree with an RK8 simulation to 4e-6 rad on stable-toy, 0.2 % of the tracker's
        noise, at a third of the cost).
    z_guess : ndarray, shape (8,), optional
        A start near the gait (default: :func:`toywalk.model.gait.find_gait`).
    max_iter : int
        IPOPT's iteration cap.
    check_jacobian : bool
        Cross-check the reduced Jacobian against central differences (two BVP solves per free
        parameter); the result's ``jacobian_check`` is empty without it.
    priors : dict of str to (float, float), optional
        Gaussian priors ``name -> (mean, sd)`` on free parameters, such as the slope as measured
        with its error; each adds the residual ``(theta - mean) / sd``.
    noise_sd : dict of str to float, optional
        Noise SD per signal (rad), used instead of the file's ``*_sd`` columns or an estimate from
        the residuals (one pass).
    strikes : {'model', 'measured'}
        Read each sample between the model's heel strikes, the measured strikes being data with
        their ``time_sd`` and the ``time_offset`` an unknown (default; module
        :mod:`toywalk.sysid.measurement`), or between the measured strikes taken as exact, with the
        step durations as data (robust to step-to-step variability the model does not have, but
        biased by strike-time errors: 4 to 12 SE through tracked video).
    warm : FitResult, optional
        A fit of the same walk and model to continue from (its gait, nuisances and free
        parameters; ``params`` should hold its estimates), with more free parameters perhaps:
        the solver starts there and skips the first, aligned stage.
    progress : callable, optional
        Called with one line of text before each stage (a long walk's stages take tens of
        seconds each: the 60-step transient fit of ``benchmarks/fit_speed.py`` takes about a
        minute): first the fit (its model, heel strikes and steps), once the request and the
        data have been checked, then each solve and the standard errors.

    Raises
    ------
    FitError
        Bad names, unusable measurements or no starting gait (the message says which).
    """
    if model == "auto":
        if warm is not None:
            raise FitError("a warm start continues one model's fit: give model 'periodic' or 'transient'")
        test = periodicity_test(table, params, free, offsets=offsets, n_intervals=n_intervals, degree=degree,
                                z_guess=z_guess, max_iter=max_iter, check_jacobian=check_jacobian,
                                priors=priors, noise_sd=noise_sd, strikes=strikes, progress=progress)
        return dataclasses.replace(test.chosen, periodicity=test)
    clock = time.perf_counter()
    say = progress or (lambda _msg: None)
    problem, w0 = setup(table, params, free, model=model, offsets=offsets, n_intervals=n_intervals,
                         degree=degree, z_guess=z_guess, max_iter=max_iter,
                         check_jacobian=check_jacobian, priors=priors, strikes=strikes, say=say)
    obs, pth = problem.obs, problem.path
    sigma, source, passes = obs.sd.copy(), "file", 1
    if noise_sd is not None:
        sigma, source = sigma_from(noise_sd, obs), "given"
    elif not obs.sd_known:
        sigma, source, passes = np.full(len(obs.value), _FIRST_PASS_SD), "estimated from residuals", 2
    sigma_c, source_c = contact_sigma(pth, noise_sd)
    passes = 2 if source_c == "estimated from residuals" else passes
    x0 = problem.start(w0) if warm is None else continued(problem, w0, warm)
    first_aligned, x_start, aligned = None, x0, warm is None
    for k in range(passes):
        solving = say if passes == 1 else (lambda msg, k=k: say(
            f"pass {k + 1} of {passes}{' (the noise SDs from the residuals)' if k else ''}: {msg}"))
        sol, stats, aligned_rms = problem.solve(x0, np.r_[sigma, sigma_c], aligned_first=aligned,
                                                progress=solving)
        if k > 0 and not stats["success"]:
            # A later pass (new noise weights) started from the converged earlier one can fail
            # where the same problem from the original start converges (measured: IPOPT's
            # restoration failed after 9 iterations from the first pass's solution of a
            # stable-toy walk with spin arrest 0.1, which converges in 9 from the start).
            solving(f"again from the start ({stats['return_status']} from the pass before)")
            sol, stats, aligned_rms = problem.solve(x_start, np.r_[sigma, sigma_c],
                                                    aligned_first=warm is None)
        x0 = sol
        if k == 0:  # from the start given, not from a first pass that may have left its basin
            first_aligned = aligned_rms
        # A converged pass already went from the measured strikes to the model's: the next pass
        # (new noise weights only) refines its solution on the model's strikes. Aligned again
        # first, the model's clock, off by the misfit's period error, drifts through the walk
        # and the second stage starts far up the misfit (measured: stable-toy, 10 steps, trailing
        # share 0.1 hidden, 0.002 rad noise, from the stable toy: the second pass ended at
        # chi-square 3.5e5 and com_offset[1] -0.11 m, where the first had ended at 4.0e3 and
        # 0.159 m).
        aligned = aligned and not stats["success"]
        if k < passes - 1 or source == "estimated from residuals":
            if source == "estimated from residuals":
                sigma = sigma_from(problem.residual_rms(sol), obs)
            if source_c == "estimated from residuals":
                sigma_c = contact_sigma(pth, problem.contact_rms(sol, floor=_CONTACT_SD_FLOOR))[0]
    checked = (f", checked by finite differences ({2 * len(problem.free)} re-solves of the walk)"
               if problem.check_jacobian and problem.free else "")
    say(f"standard errors{checked}, and the fitted walker's gait")
    result = problem.result(sol, stats, np.r_[sigma, sigma_c], source, source_c, first_aligned)
    result.seconds = time.perf_counter() - clock
    return result


@dataclasses.dataclass
class PeriodicityTest:
    """Is the walk on the model's limit cycle? The periodic fit against the transient one.

    Attributes
    ----------
    periodic, transient : FitResult
        Both fits; the chosen one (:attr:`chosen`) fitted as asked, the other as the test made it
        (aligned on the measured strikes).
    delta_chi2 : float
        ``chi2_periodic - chi2_transient`` (>= 0: the models nest) of the two models aligned on
        the measured strikes, with one noise model (the file's SDs, or the transient fit's
        residual RMS: it holds whichever model is true), each fit at its optimum under it (with
        the residual RMS, both fitted again with those SDs held: ``noise_source`` 'given').
    dof : int
        Free directions of the transient's start (``n_dyn - 1``).
    p_value : float
        Chi-square tail probability of ``delta_chi2`` on ``dof`` (Wilks' theorem).
    alpha : float
        The false-alarm rate: the periodic model is rejected when ``p_value < alpha``.
    appropriate : bool or None
        The periodic model explains the walk (None: the test could not be made).
    message : str
    step_dependence : dict or None
        Whether the periodic fit's residuals change from step to step
        (:func:`toywalk.sysid.residuals.step_dependence`: ``F``, ``dfn``, ``dfd``, ``p``), made
        when the likelihood ratio rejects the periodic model.
    fallback : bool
        The periodic model was rejected but the transient fit does not determine the free
        parameters (:attr:`FitResult.undetermined`): the periodic fit is the one chosen, and the
        message says so.
    chi2 : dict of str to float
        The chi-square of the test's ``periodic`` and ``transient`` fits (the fit chosen is then
        fitted again as asked, with a chi-square of its own).
    """

    periodic: FitResult
    transient: FitResult
    delta_chi2: float
    dof: int
    p_value: float
    alpha: float
    appropriate: bool | None
    message: str
    step_dependence: dict | None = None
    chi2: dict = dataclasses.field(default_factory=dict)
    fallback: bool = False

    @property
    def chosen(self) -> FitResult:
        """The fit to use: the periodic one unless it is rejected (and the transient one
        determines the free parameters: ``fallback``)."""
        return self.transient if self.appropriate is False and not self.fallback else self.periodic

    def to_json(self) -> dict:
        return {"delta_chi2": self.delta_chi2, "dof": self.dof, "p_value": self.p_value,
                "alpha": self.alpha, "periodic_appropriate": self.appropriate,
                "message": self.message, "chosen": self.chosen.model, "fallback": self.fallback,
                "chi2": dict(self.chi2),
                "step_dependence": None if self.step_dependence is None else
                {k: self.step_dependence[k] for k in ("F", "dfn", "dfd", "p")}}



def periodicity_test(table: TrajectoryTable, params: Params, free, *,
                     alpha: float = PERIODICITY_ALPHA, progress=None, **options) -> PeriodicityTest:
    """Fit the walk with both models and say whether the periodic one is appropriate.

    A walk released off its cycle (or leaving an unstable one) is not a repeated gait: fitting it
    as one biases the parameters. The transient model nests the periodic one (its start on the
    fixed point), so the likelihood ratio ``chi2_periodic - chi2_transient`` is, for a walk on its
    cycle, chi-square distributed with as many degrees of freedom as the start has free
    directions (Wilks 1938, Ann. Math. Stat. 9:60); ``alpha`` is the test's false-alarm rate.
    It assumes independent measurement errors: errors correlated in time (a smoothed track)
    raise the false-alarm rate.

    The likelihood ratio also grows with the periodic model's misfit: a free start bends the
    walk towards data the model cannot follow (measured: two walks of the stable toy on their
    cycle with rolling resistance 2e-4 N m s/rad hidden, both called off their cycle). So the
    periodic model is rejected only when, besides, its residuals change from step to step
    (:func:`toywalk.sysid.residuals.step_dependence`, at ``alpha``): a misfit repeats every
    step, a walk converging to its cycle does not.

    Parameters
    ----------
    table, params, free
        As :func:`fit`.
    alpha : float
        False-alarm rate, in (0, 1).
    progress : callable, optional
        Called with one line of text before each of its fits (a long walk's take minutes: the
        60-step walk of ``benchmarks/fit_speed.py``, off its cycle, one to one and a half minutes),
        once the request and the data have been checked.
    **options
        Passed to both fits (``offsets``, ``priors``, ``check_jacobian``, ...; not ``model``).
    """
    say = progress or (lambda _msg: None)
    if not 0 < alpha < 1:
        raise FitError(f"alpha must be in (0, 1), got {alpha!r}")
    if "model" in options:
        raise FitError("periodicity_test fits both models: do not pass model")
    check_request(table, params, free, options.get("priors"), options.get("strikes", "model"))
    # The test compares the models aligned on the measured strikes (the first stage of each
    # fit): a walk off its cycle has no regular strike times for the periodic model's clock,
    # and its fit on the model's strikes can take hundreds of iterations (measured: 500, 8
    # minutes, on a released 12-step walk). The chosen model is then fitted as asked.
    final = {k: v for k, v in options.items() if k != "strikes"}
    strikes = options.get("strikes", "model")
    quick = dict(final, strikes="measured", check_jacobian=False)
    say("periodicity test: the periodic model, aligned on the measured heel strikes")
    periodic = fit(table, params, free, model="periodic", **quick)
    say("periodicity test: the transient model (a free start), aligned on the measured heel strikes")
    transient = fit(table, periodic.params if periodic.success else params, free,
                    model="transient", **quick)
    if transient.noise_source == "estimated from residuals":
        # One noise model for both, the transient's, and each fit at its optimum under it: the
        # transient's last pass was weighted by the noise of the pass before, and the likelihood
        # ratio of a fit off its optimum can come out negative (measured: the 60-step walk of
        # benchmarks/diagnose_speed.py, chi-square 4275.9 against the periodic's 4261.3). Each
        # again with these SDs, from its own solution (only the weights change). The periodic
        # one from a fresh start at its estimates, the offsets and the contacts' origin at zero
        # under the tight contact SDs of exact positions, IPOPT diverged (measured: stable-toy,
        # 10 steps, trailing share 0.1 hidden, no noise: 500 iterations, 21 s, com_offset[1] at
        # 1.6e4 m, and no test).
        if transient.success:
            say("periodicity test: the transient model again, with its own noise")
            transient = fit(table, transient.params, free, model="transient",
                            **dict(quick, noise_sd=transient.noise_sd), warm=transient)
        say("periodicity test: the periodic model again, with the transient's noise")
        periodic = fit(table, periodic.params if periodic.success else params, free,
                       model="periodic", **dict(quick, noise_sd=transient.noise_sd),
                       warm=periodic if periodic.success else None)
    dof = transient.start_dof
    delta = max(periodic.chi2 - transient.chi2, 0.0)
    chi2 = {"periodic": periodic.chi2, "transient": transient.chi2}
    p_value = float(special.chdtrc(dof, delta))
    if not (periodic.success and transient.success):
        failed = [f"{r.model} ({r.status})" for r in (periodic, transient) if not r.success]
        return PeriodicityTest(periodic, transient, delta, dof, p_value, alpha, None,
                               f"no test: the {' and the '.join(failed)} fit did not converge",
                               chi2=chi2)
    appropriate = p_value >= alpha
    steps = None
    if not appropriate:
        obs = observations(table)
        steps = step_dependence(obs, periodic.residuals[:len(obs.value)])
        appropriate = bool(steps["p"] >= alpha)  # untestable (NaN): the likelihood ratio decides
    chosen = periodic if appropriate else transient
    say(fit_line(chosen.model, strikes))
    refit = fit(table, chosen.params, free, model=chosen.model, strikes=strikes, **final)
    shown = "" if steps is None else (f"F = {steps['F']:.3g} on {steps['dfn']} and {steps['dfd']} "
                                      f"degrees of freedom, p = {steps['p']:.2g}")
    repeated = "" if steps is None else (
        f"; its residuals change from step to step beyond the noise ({shown})"
        if math.isfinite(steps["p"]) else "; too few samples a step to test whether its residuals "
        "change from step to step")
    if appropriate and steps is None:
        periodic = refit
        message = (f"the walk is consistent with the model's limit cycle: a free start lowers "
                   f"chi-square by {delta:.3g} on {dof} degrees of freedom (p = {p_value:.3g})")
    elif appropriate:
        periodic = refit
        message = (f"the walk repeats itself: a free start lowers chi-square by {delta:.4g} on {dof} "
                   f"degrees of freedom (p = {p_value:.2g}), but the periodic fit's residuals repeat "
                   f"every step within the noise ({shown} >= {alpha:g}): the model's misfit, not a walk "
                   "off its cycle")
    else:
        transient = refit
        message = (f"the walk is not on the model's limit cycle: a free start lowers chi-square by "
                   f"{delta:.4g} on {dof} degrees of freedom (p = {p_value:.2g} < {alpha:g}){repeated}; "
                   "the periodic fit is not appropriate, use the transient one")
        lost = [n for n in free if n in refit.undetermined]
        if lost:
            # A free start that the walk cannot tell from the parameters (an unstable walker's
            # steps grow from the start by its eigenvalue, 6 a step for the toy-sized one) leaves
            # them undetermined: the transient fit gives no standard error, and the periodic one,
            # biased by the walk's departure from its cycle, is the fit that determines them.
            say(f"the transient model does not determine {', '.join(lost)}: "
                + fit_line("periodic", strikes) + " instead")
            periodic = fit(table, periodic.params, free, model="periodic", strikes=strikes, **final)
            message += (f"; but the transient fit does not determine {', '.join(lost)} (its "
                        "information is singular), so the periodic fit is used instead: its estimates "
                        "carry the bias of a walk off its cycle")
            return PeriodicityTest(periodic, transient, delta, dof, p_value, alpha, appropriate, message,
                                   steps, chi2, fallback=True)
    return PeriodicityTest(periodic, transient, delta, dof, p_value, alpha, appropriate, message, steps,
                           chi2)

