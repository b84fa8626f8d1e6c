"""Several walks of one walker fitted together: shared parameters, each walk its own gait.

The same toy filmed on two ramps, or with a balance mass moved by a known amount, is one walker
under known, different conditions. Its unknown properties (a foot radius, a hinge's friction) are
the same in every walk; each walk has its own gait, its own nuisances (offsets of lean, steer and
pitch, its clock) and its own noise. :func:`fit_walks` fits them as one problem: each walk's
collocation NLP (:func:`toywalk.sysid.fit.fit`'s), joined into one IPOPT problem whose free
parameters are tied across the walks by equalities. What is shared is each free parameter's
**change** from its value in the walk's own parameter file, so a walk's known condition (its
slope, its moved mass) stays as given and an error common to all (a slope misread by the same
amount, a mass offset the builder got wrong) is estimated once.

Why: a walk on its cycle can leave candidate causes tied (docs/diagnosis.md, "What a walk on its
cycle cannot tell apart"); walks under other conditions see them along other directions
(:mod:`toywalk.sysid.design` says which walks to film).

Procedure: the joint problem starts from each walk's gait at its file's parameters and is
solved as a single walk's fit is: aligned on the measured strikes first, then on the model's
strikes. (Started from each walk's own fit instead, the base model of the stable toy with hip dry
friction hidden had wandered to a lateral mass offset of -0.12 and -0.67 m, against 0.19, in
single fits of two walks that it fits nearly as well that way, and the joint problem from there
did not converge.) The noise of each walk is its file's SDs, the given ``noise_sd``, or its
samples' own scatter: never a residual RMS, which a base model's misfit inflates. The covariance of
the shared changes is the inverse information of the walks' Jacobians stacked: shared columns one
above the other, each walk's nuisances in its own rows (:meth:`toywalk.sysid.problem.FitProblem.jacobian`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence

import casadi as ca
import numpy as np
from toywalk.model.parameters import Params
from toywalk.model.trajectory import SIGNALS, TrajectoryTable

from .discrepancy import EXPLAINS, chosen_model
from .fitresult import FitResult
from .heldout import FitPool, held_out_fits, held_out_score, masked, run_fits, strides
from .measurement import observations
from .naming import (
    ALPHA,
    MAX_EXTENDED,
    Candidate,
    DiagnoseError,
    Explanation,
    Verdict,
    candidates,
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
from .problem import (
    CONTACT_KEYS,
    STAGE_PATH,
    FitError,
    contact_sigma,
    continued,
    ipopt_options,
    setup,
    sigma_from,
    stacked,
)
from .residuals import ResidualReport, feature_misfit, missed_features, residual_report, scatter_noise
from .score import held_jacobian, score_statistics
from .ties import further_walk_clause, weigh_ties

__all__ = ["WALKS_RULE", "WalksDiagnosis", "WalksFit", "diagnose_walks", "fit_walks", "held_out_walks",
           "stacked", "without_unweighed_contacts"]


@dataclasses.dataclass
class WalksFit:
    """The joint fit of several walks (:func:`fit_walks`).

    Attributes
    ----------
    free : list of str
        The shared parameters.
    change, std : dict of str to float
        Each shared parameter's change from the walks' files, and its standard error.
    estimates : dict of str to float
        The first walk's parameters (its file's values plus the changes).
    covariance : ndarray, shape (n_free, n_free)
        Of the changes.
    chi2 : float
        Summed over the walks; ``n_residuals`` in all.
    walks : list of FitResult
        Each walk at the joint solution (its gait, residuals, nuisances, chi-square).
    success : bool
    status : str
        IPOPT's return status of the joint problem.
    seconds : float
    warnings : list of str
        What the fit's caller should know (a held-out fold's refit, for one).
    """

    free: list
    change: dict
    std: dict
    estimates: dict
    covariance: np.ndarray
    chi2: float
    n_residuals: int
    walks: list
    success: bool
    status: str
    seconds: float = 0.0
    warnings: list = dataclasses.field(default_factory=list)

    def interval(self, name: str, z: float = 1.959964) -> tuple[float, float]:
        """The 95 % (``z``) interval of ``name``'s value in the first walk's terms."""
        return (self.estimates[name] - z * self.std[name], self.estimates[name] + z * self.std[name])


def without_unweighed_contacts(table: TrajectoryTable, noise_sd: dict | None = None) -> TrajectoryTable:
    """``table`` without its heel strikes' contact positions when they have no SDs (the events
    file's ``x_sd, y_sd``) and ``noise_sd`` gives none (:data:`toywalk.sysid.problem.CONTACT_KEYS`):
    their noise would have to come from the residuals, which a base model's misfit inflates
    (a simulation's contacts are exact). Otherwise ``table`` itself."""
    located = [e for e in table.events
               if all(isinstance(e.get(c), (int, float)) and math.isfinite(e[c]) for c in ("x", "y"))]
    known = all(all(isinstance(e.get(c), (int, float)) and math.isfinite(e[c]) for c in ("x_sd", "y_sd"))
                for e in located)
    given = noise_sd is not None and all(k in noise_sd for k in CONTACT_KEYS)
    if not located or known or given:
        return table
    events = [{k: v for k, v in e.items() if k not in ("x", "y", "x_sd", "y_sd")} for e in table.events]
    return TrajectoryTable(table.time, table.signals, table.stance, events, table.metadata)


def fit_walks(tables: Sequence[TrajectoryTable], params: Sequence[Params], free, *,
              noise_sd: dict | None = None, warm: WalksFit | None = None, max_iter: int = 500,
              model: str = "periodic", offsets: bool = True, strikes: str = "model") -> WalksFit:
    """Fit ``free`` parameters shared by the walks ``tables``, walk ``i`` of the walker
    ``params[i]`` (module docstring).

    Parameters
    ----------
    tables : sequence of TrajectoryTable
        The walks (at least one).
    params : sequence of Params
        Each walk's walker: the same walker under that walk's known condition.
    free : sequence of str
        Parameter-file names whose change is shared (``foot_radius``, ``effects.hip_damping``).
    noise_sd : dict, optional
        Noise SD per signal (rad) for every walk. Without it, a walk's file SDs (the tracker's
        ``*_sd`` columns) weigh it, else its samples' own scatter within each step
        (:func:`toywalk.sysid.residuals.scatter_noise`: no model's misfit inflates it).
    warm : WalksFit, optional
        A joint fit of the same walks with fewer free parameters (the base, for a candidate):
        the start, with the new parameters at their files' values.
    max_iter : int
        IPOPT's iteration cap.
    model, offsets, strikes
        As :func:`toywalk.sysid.fit.fit`'s, for every walk.

    Raises
    ------
    FitError
        Bad input, or a walk whose noise cannot be had (the message says which).
    """
    clock = time.perf_counter()
    tables, params, free = list(tables), list(params), list(free)
    if not tables or len(tables) != len(params):
        raise FitError(f"need one parameter set per walk, at least one walk: got {len(tables)} walks "
                       f"and {len(params)} parameter sets")
    if warm is not None and len(warm.walks) != len(tables):
        raise FitError(f"warm must be a joint fit of the same {len(tables)} walks, got {len(warm.walks)}")
    problems, starts, sigmas, sources = [], [], [], []
    tables = [without_unweighed_contacts(t, noise_sd) for t in tables]
    for k, (table, walker) in enumerate(zip(tables, params, strict=True)):
        walk_setup = {"model": model, "offsets": offsets, "n_intervals": None, "degree": None,
                 "max_iter": max_iter, "check_jacobian": False, "priors": {}, "strikes": strikes}
        try:
            problem, w0 = setup(table, walker, free, z_guess=None, **walk_setup)
        except FitError:
            # The walker's gait under this walk's condition, from the last walk's: its own search
            # from the planar reduction can stall where Newton from a nearby condition's gait
            # converges.
            if not problems:
                raise
            last = problems[-1]
            z_last = last.walker.to_public(np.r_[starts[-1][1:1 + last.prob.n_dyn],
                                                 np.zeros(last.walker.lay.nx - last.prob.n_dyn)])
            problem, w0 = setup(table, walker, free, z_guess=z_last, **walk_setup)
        obs = problem.obs
        if noise_sd is not None:
            sigma, source = sigma_from(noise_sd, obs), "given"
        elif obs.sd_known:
            sigma, source = obs.sd.copy(), "file"
        else:
            scatter = {n: v["sd"] for n, v in scatter_noise(obs).items()}
            if not all(math.isfinite(v) and v > 0 for v in scatter.values()):
                raise FitError(f"walk {k + 1}: too few samples within its steps to measure its noise; "
                               "give noise_sd")
            sigma, source = sigma_from(scatter, obs), "scatter within steps"
        sigma_c, source_c = contact_sigma(problem.path, noise_sd)
        x = problem.start(w0)
        if warm is not None:
            done = warm.walks[k]
            x = continued(problem, w0, done)
            n_w = problem.n_w
            for j, name in enumerate(free):
                if name in done.estimates:
                    x[n_w + j] = (done.estimates[name] - problem.theta0[j]) / problem.scale[j]
        problems.append(problem)
        starts.append(x)
        sigmas.append(np.r_[sigma, sigma_c])
        sources.append((source, source_c))
    sizes = [len(x) for x in starts]
    at = np.r_[0, np.cumsum(sizes)]
    xs = ca.MX.sym("x", int(at[-1]))
    p_sizes = [pr.nlp_fn.size1_in(1) for pr in problems]
    p_at = np.r_[0, np.cumsum(p_sizes)]
    ps = ca.MX.sym("p", int(p_at[-1]))
    f, gs, lbg, ubg = 0, [], [], []
    for k, pr in enumerate(problems):
        fk, gk = pr.nlp_fn(xs[int(at[k]):int(at[k + 1])], ps[int(p_at[k]):int(p_at[k + 1])])
        f += fk
        gs.append(gk)
        lbg.append(pr.lbg)
        ubg.append(pr.ubg)
    # The shared changes: walk k's scaled unknown times its scale equals walk 0's.
    first = problems[0]
    for k, pr in enumerate(problems[1:], start=1):
        for j in range(len(free)):
            gs.append(pr.scale[j] * xs[int(at[k]) + pr.n_w + j] - first.scale[j] * xs[first.n_w + j])
            lbg.append([0.0])
            ubg.append([0.0])
    solver = ca.nlpsol("walks", "ipopt", {"x": xs, "p": ps, "f": f, "g": ca.vertcat(*gs)},
                       ipopt_options(max_iter))
    lbx, ubx = np.concatenate([pr.lbx for pr in problems]), np.concatenate([pr.ubx for pr in problems])
    lbg, ubg = np.concatenate(lbg), np.concatenate(ubg)
    # As each walk's fit: first aligned on the measured strikes (clocks held), then, where the
    # fit reads the walk between the model's strikes, on those from there: in one jump, and
    # through the blends of problem.STAGE_PATH where the jump fails or ends far above the aligned
    # solution (_JUMP_LIMIT); the better of the two. From a warm start the last stage only.
    def solve(x0: np.ndarray, stage: float):
        p_value = np.concatenate([np.r_[1.0 / sg, stage] for sg in sigmas])
        lo, hi = lbx.copy(), ubx.copy()
        if stage == 0.0:
            clocks = at[1:] - 1  # each walk's last unknown: its time offset
            lo[clocks] = hi[clocks] = 0.0
        sol = solver(x0=x0, p=p_value, lbx=lo, ubx=hi, lbg=lbg, ubg=ubg)
        return np.array(sol["x"]).ravel(), float(sol["f"]), solver.stats()

    x_all = np.concatenate(starts)
    if warm is not None and strikes == "model":
        x_all, _, stats = solve(x_all, 1.0)
    else:
        x_all, f_aligned, stats = solve(x_all, 0.0)
        if strikes == "model" and stats["success"]:
            aligned = x_all
            x_all, f_jump, stats = solve(aligned, 1.0)
            if not stats["success"] or f_jump > _JUMP_LIMIT * f_aligned:
                x_path, f_path, s_path = aligned, math.inf, stats
                for stage in STAGE_PATH:
                    x_path, f_path, s_path = solve(x_path, stage)
                    if not s_path["success"]:
                        break
                if s_path["success"] and (not stats["success"] or f_path < f_jump):
                    x_all, stats = x_path, s_path
    walks, shared, nuisances = [], [], []
    for k, (pr, sigma, (source, source_c)) in enumerate(zip(problems, sigmas, sources, strict=True)):
        xk = x_all[int(at[k]):int(at[k + 1])]
        walks.append(pr.result(xk, stats, sigma, source, source_c))
        jac = pr.jacobian(xk, sigma)
        shared.append(jac[:, :len(free)])
        nuisances.append(jac[:, len(free):])
    jac = np.hstack(stacked(shared, nuisances))
    cov = np.linalg.pinv(jac.T @ jac)[:len(free), :len(free)]
    theta = first.theta(x_all[:int(at[1])])
    change = {n: float(theta[j] - first.theta0[j]) for j, n in enumerate(free)}
    std = {n: float(math.sqrt(max(cov[j, j], 0.0))) for j, n in enumerate(free)}
    return WalksFit(free=free, change=change, std=std,
                    estimates={n: float(theta[j]) for j, n in enumerate(free)}, covariance=cov,
                    chi2=float(sum(w.chi2 for w in walks)),
                    n_residuals=int(sum(w.n_residuals for w in walks)),
                    walks=walks, success=bool(stats["success"]), status=str(stats["return_status"]),
                    seconds=time.perf_counter() - clock)


@dataclasses.dataclass
class WalksDiagnosis(Verdict):
    """The analysis of several walks together (:func:`diagnose_walks`).

    Attributes
    ----------
    verdict, cause, causes, ranking, gain, evidence
        As in :class:`toywalk.sysid.discrepancy.Verdict`; ``ranking`` holds for each candidate its
        score test (when the base fit allowed one), likelihood ratio, p-value, estimate and 95 %
        interval.
    base : WalksFit
    extended : dict of str to WalksFit
    rule : str
    alpha : float
    seconds : float
    residuals : list of ResidualReport
        Each walk's base residuals tested for a pattern repeated every step
        (:func:`toywalk.sysid.residuals.residual_report`, at alpha over the walks).
    residuals_extended : list of ResidualReport or None
        The same for the fit of the cause the rule picked (None when none was picked; kept when
        its pattern left the cause ``unexplained``, the evidence naming it).
    features, features_extended : list of dict, or None
        Each walk's gait-feature misfits (:func:`toywalk.sysid.residuals.feature_misfit`) at the
        base fit and at the picked cause's (None as ``residuals_extended``).
    next_walk : dict or None
        Where candidates are left tied: which further walk would tell them apart
        (:func:`toywalk.sysid.design.next_walk`); None otherwise.
    """

    base: WalksFit
    extended: dict
    rule: str
    alpha: float
    seconds: float = 0.0
    residuals: list = dataclasses.field(default_factory=list)
    residuals_extended: list | None = None
    features: list = dataclasses.field(default_factory=list)
    features_extended: list | None = None
    next_walk: dict | None = None

    def to_json(self) -> dict:
        """``report.json`` (the fields of docs/formats.md, "Reports", and each walk's base fit)."""
        def walk_json(w: FitResult) -> dict:
            return {"estimates": w.estimates, "chi2": w.chi2, "n_residuals": w.n_residuals,
                    "noise_sd": w.noise_sd, "noise_source": w.noise_source, "status": w.status,
                    "max_abs_eigenvalue": w.gait.get("max_abs_eigenvalue")}

        def fit_json(f: WalksFit) -> dict:
            return {"free": f.free, "change": f.change, "std": f.std, "estimates": f.estimates,
                    "chi2": f.chi2, "n_residuals": f.n_residuals, "success": f.success,
                    "status": f.status, "walks": [walk_json(w) for w in f.walks]}

        return {"verdict": self.verdict, "cause": self.cause, "causes": self.causes,
                "ranking": self.ranking, "gain": self.gain, "evidence": self.evidence,
                "rule": self.rule, "alpha": self.alpha, "seconds": self.seconds,
                "walks": len(self.base.walks), "base": fit_json(self.base),
                "extended": {n: fit_json(f) for n, f in self.extended.items()},
                "residuals": [r.to_json() for r in self.residuals],
                "residuals_extended": None if self.residuals_extended is None else
                [r.to_json() for r in self.residuals_extended],
                "features": self.features, "features_extended": self.features_extended,
                "next_walk": self.next_walk, "effective": self.effective}


#: A joint fit's jump from the measured strikes to the model's is redone through the blends of
#: problem.STAGE_PATH where it ends above this many times the aligned solution's misfit. Both read
#: the same samples with the same model, the clock aligned on other strikes; a jump far above
#: went into another minimum (two walks of compass-3d on slopes 0.03 and 0.024, hip damping
#: hidden: 342 times, the lateral offset 0.179 m for 0.02; through the path 8113 in chi-square:
#: tests/sysid/test_walks.py). Where it is fine it ends near (three walks of the stable toy,
#: hip dry friction hidden: 1.04 times), and the path can fail where the jump does not (those
#: walks: a restoration failure at the first blend after 160 iterations).
_JUMP_LIMIT = 2.0

#: Chi-square by which the base refitted from a candidate's fit must undercut the first base
#: for the screening and the candidates' fits to be redone from it: the solver's tolerance moves
#: a converged base by far less (measured: within 3e-9 in the four analyses of the tests that
#: refit it), a base stuck in another minimum by thousands (tests/sysid/test_walks.py).
_BASE_MOVED = 1.0

WALKS_RULE = ("adequate: no candidate's score test below alpha/K and no walk with a pattern repeated "
              "every step (alpha over the walks and their signals); the likelihood ratios of all walks "
              "together; "
              + rule_text(held_out=("held-out strides (alternate strides of every walk in two folds, all "
                                    "walks fitted together on each)"),
                          explains=f"in every walk: {EXPLAINS}"))


def held_out_walks(tables: Sequence[TrajectoryTable], params: Sequence[Params], fit: WalksFit,
                   workers: int = 1, scheduler: str | None = None, **fit_options) -> dict:
    """Held-out prediction grouped by stride for several walks fitted together: the alternate
    strides of every walk form two folds (:func:`toywalk.sysid.heldout.held_out_tasks`, walk
    by walk); the walks are fitted together on one fold (the other's samples kept with a huge SD,
    so the model is read at them without their weighing in) and predict the other's angles, both
    ways round, each walk's residuals weighed by its noise in ``fit``. Each fold's fit starts from
    ``fit`` (the same free parameters, on all the samples); one that fails is refitted from the
    other fold's, or from the walks' files when neither converged (the single walk's rule,
    :func:`toywalk.sysid.heldout.held_out_fits`; the two folds in ``workers`` processes or on
    a Dask cluster, ``scheduler``), and a fold that still fails leaves the chi-square NaN with the
    reason.

    Returns
    -------
    dict
        ``chi2`` (held-out, all walks), ``by_walk`` (each walk's), ``scores`` (each walk's
        :func:`toywalk.sysid.heldout.held_out_score`), ``success``, ``reason``.
    """
    tasks = _held_out_walk_tasks(tables, params, fit, **fit_options)
    return _held_out_walk_score(tables, fit, held_out_fits(tasks, workers, scheduler, _fit_walks_or_reason))


def _held_out_walk_tasks(tables, params, fit: WalksFit, **fit_options) -> list[dict]:
    """The two folds' joint fits of :func:`held_out_walks`, as keyword arguments of :func:`fit_walks`."""
    # the noise is in the folds' SD columns (a given noise_sd would unmask them)
    fit_options.pop("noise_sd", None)
    obs = [observations(t) for t in tables]
    tasks = []
    for fold in (0, 1):
        folds = []
        for table, o, walk in zip(tables, obs, fit.walks, strict=True):
            sd = {n: float(walk.noise_sd[n]) for n in SIGNALS if n in walk.noise_sd}
            folds.append(masked(table, o, np.flatnonzero(strides(o.n_steps) == fold), sd))
        tasks.append(dict(tables=folds, params=list(params), free=list(fit.free), warm=fit, **fit_options))
    return tasks


def _held_out_walk_score(tables, fit: WalksFit, fits: list) -> dict:
    """:func:`held_out_walks`' result from its two folds' fits (a string where one could not be set up)."""
    failed = [f"fold {k}: {f if isinstance(f, str) else f.status}" for k, f in enumerate(fits)
              if isinstance(f, str) or not f.success]
    if failed:
        return {"chi2": math.nan, "by_walk": [], "scores": [], "success": False,
                "reason": "; ".join(failed)}
    scores = [held_out_score(table, [fits[0].walks[i], fits[1].walks[i]], walk.noise_sd)
              for i, (table, walk) in enumerate(zip(tables, fit.walks, strict=True))]
    by_walk = [h["chi2"] for h in scores]
    return {"chi2": float(sum(by_walk)), "by_walk": by_walk, "scores": scores, "success": True,
            "reason": ""}


def _scores(tables, base: WalksFit, free: list, cands: list) -> dict:
    """Each candidate's score statistic at the joint base fit, all walks together (the walks'
    Jacobians stacked, each walk's nuisances its own)."""
    k = len(cands)
    shared, nuisance, residuals = [], [], []
    for table, walk in zip(tables, base.walks, strict=True):
        jac, r = held_jacobian(table, walk, [c.name for c in cands])
        shared.append(jac[:, :len(free) + k])
        nuisance.append(jac[:, len(free) + k:])
        residuals.append(r)
    s, n = stacked(shared, nuisance)
    jac = np.hstack([s[:, :len(free)], n, s[:, len(free):]])
    held = list(range(len(free) + n.shape[1], jac.shape[1]))
    return dict(zip([c.name for c in cands], score_statistics(jac, np.concatenate(residuals), held),
                    strict=True))


def _fit_walks_or_reason(task: dict):
    """:func:`fit_walks` of a task's keyword arguments, or why it could not be set up (a string)."""
    try:
        return fit_walks(**task)
    except FitError as err:
        return str(err)


def _patterns(obs: list, fit: WalksFit, alpha: float) -> list[ResidualReport]:
    """Each walk's residuals at the joint fit (``obs`` its observations) tested for a pattern
    repeated every step, at ``alpha`` over the walks (Bonferroni; each report splits its share
    over the signals)."""
    return [residual_report(o, w.residuals, alpha=alpha / len(obs))
            for o, w in zip(obs, fit.walks, strict=True)]


def _features(obs: list, fit: WalksFit) -> list[dict]:
    """Each walk's gait-feature misfits at the joint fit (the model's features measured through
    simulated noise of the walk's SDs, as the single walk's analysis does)."""
    return [feature_misfit(o, o.value, o.value + w.residuals, w.model_durations,
                           sigma=w.sigma[:len(o.value)], rng=0) for o, w in zip(obs, fit.walks, strict=True)]


def _feature_note(features: list[dict], limit: float = 3.0) -> str:
    """The features each walk misses by more than ``limit`` standard errors, largest first
    (``walk 1: lean_range -7.6 SE``); empty when none does."""
    return "; ".join(f"walk {i + 1}: " + ", ".join(f"{k} {f[k]['z']:+.1f} SE" for k in missed[:3])
                     for i, f in enumerate(features) for missed in [missed_features(f, limit)] if missed)


def _pattern_note(reports: list[ResidualReport]) -> str:
    """The walks whose residuals repeat a pattern every step, and in which signals
    (``walk 2: steer, pitch_st``); empty when none does."""
    return "; ".join(f"walk {i + 1}: {', '.join(r.systematic)}"
                     for i, r in enumerate(reports) if r.systematic)


def diagnose_walks(tables: Sequence[TrajectoryTable], params: Sequence[Params], *, free=(),
                   effects=None, parameters=None, alpha: float = ALPHA, noise_sd: dict | None = None,
                   model: str = "auto", progress=None, workers: int = 1, scheduler: str | None = None,
                   tie_design: bool = True, **fit_options) -> WalksDiagnosis:
    """What the base model lacks, from several walks of one walker under known conditions
    (:func:`fit_walks`); the single walk's analysis is :func:`toywalk.sysid.discrepancy.diagnose`.

    1. The base fit of all walks. It can fail where the base model misses the walks in different
       ways (measured: IPOPT's restoration failed, stable toy, hip dry friction hidden in three
       walks); each candidate's fit is then also the start of a base fit with that candidate
       held at its null value, and the lowest converged chi-square is the base's.
    2. Screening by score tests (:func:`toywalk.sysid.score.held_jacobian` of each walk at the base
       fit, stacked as in :func:`stacked`) when the base converged; every candidate is fitted
       when it did not.
    3. The best :data:`toywalk.sysid.discrepancy.MAX_EXTENDED` fitted (all walks together), each
       scored by its likelihood ratio against the base; none when the screening finds no
       candidate significant (the base is then adequate, as in the single walk's analysis).
    4. The rule (:data:`WALKS_RULE`): the single walk's, its held-out check made on the walks
       together (:func:`held_out_walks`: alternate strides of every walk in two folds; four more
       joint fits, made only for a candidate that leads by the separation); each walk's residuals
       are tested for a pattern repeated every step, at the base fit and at the picked cause's.

    5. Where candidates are left tied, which further walk would tell them apart
       (:func:`toywalk.sysid.design.next_walk`, unless ``tie_design`` is False).

    Parameters are those of :func:`toywalk.sysid.discrepancy.diagnose` (``params`` one per walk;
    ``workers`` processes or a Dask ``scheduler`` run the candidates' fits side by side, and the
    held-out folds' four; ``model`` 'auto', the default as in ``toywalk diagnose``, is the
    transient model when any walk's periodicity test finds it off its cycle,
    :func:`toywalk.sysid.discrepancy.chosen_model`); ``fit_options`` go to :func:`fit_walks`.
    """
    if not candidates(params[0], free, effects, parameters):
        raise DiagnoseError("no candidate causes to test: give some effects or parameters")
    started = time.perf_counter()  # the model's choice is part of the analysis's time
    if model == "auto":
        model = chosen_model(tables, params, free, progress=progress, noise_sd=noise_sd, **fit_options)
    fit_options["model"] = model
    with FitPool(workers, scheduler) as pool:
        return _diagnose_walks(tables, params, free=free, effects=effects, parameters=parameters,
                               alpha=alpha, noise_sd=noise_sd, progress=progress, pool=pool,
                               tie_design=tie_design, started=started, **fit_options)


def _diagnose_walks(tables: Sequence[TrajectoryTable], params: Sequence[Params], *, free, effects,
                    parameters, alpha: float, noise_sd: dict | None, progress, pool: FitPool,
                    tie_design: bool, started: float | None = None, **fit_options) -> WalksDiagnosis:
    say = progress or (lambda _msg: None)
    clock = time.perf_counter() if started is None else started
    if not 0 < alpha < 1:
        raise DiagnoseError(f"alpha must be in (0, 1), got {alpha!r}")
    free = list(free)
    cands = candidates(params[0], free, effects, parameters)
    k = len(cands)
    stripped = [without_unweighed_contacts(t, noise_sd) for t in tables]
    dropped = [i + 1 for i, (a, b) in enumerate(zip(tables, stripped, strict=True)) if a is not b]
    tables = stripped
    if dropped:
        say(f"walks {dropped}: contact positions without SDs, not used")
    say(f"base fit of {len(tables)} walks ({', '.join(free) or 'no free parameters'})")
    base = fit_walks(tables, params, free, noise_sd=noise_sd, **fit_options)
    obs = [observations(t) for t in tables]
    patterns = _patterns(obs, base, alpha) if base.success else []
    scores: dict = {}
    if base.success:
        say(f"screening {k} candidates by score tests")
        scores = _scores(tables, base, free, cands)

    def screened(c: Candidate) -> float:
        z = scores[c.name]["z"]
        one_sided = c.side != 0
        return -(z * c.side if one_sided else abs(z))  # the larger the evidence, the earlier

    # a one-sided candidate's score counts only in the direction it can move
    any_score = any(lr_p_value(v["z"] ** 2 if c.side * v["z"] >= 0 else 0.0, c.side != 0) < alpha / k
                    for c in cands for v in [scores.get(c.name)] if v is not None)
    order = sorted(cands, key=screened) if scores else cands
    # as the single walk's analysis: no candidate fitted when the screening finds nothing
    quiet = bool(scores) and not any_score and not any(r.systematic for r in patterns)
    chosen = [] if quiet else order[:MAX_EXTENDED] if scores else order
    extended: dict = {}
    if chosen:
        say(f"fitting {', '.join(c.name for c in chosen)} on all walks")
    tasks = [dict(tables=tables, params=list(params), free=free + [c.name], noise_sd=noise_sd,
                  warm=base if base.success else None, **fit_options) for c in chosen]
    for c, f in zip(chosen, run_fits(tasks, pool, runner=_fit_walks_or_reason), strict=True):
        if isinstance(f, str):
            say(f"{c.name}: {f}")
        else:
            extended[c.name] = f
    fitted = {n: f for n, f in extended.items() if f.success}
    base_chi2 = base.chi2 if base.success else math.inf
    if fitted:  # the base's nearby minimum, from the best candidate held at its null value
        best_name = min(fitted, key=lambda n: fitted[n].chi2)
        again = fit_walks(tables, params, free, noise_sd=noise_sd, warm=fitted[best_name], **fit_options)
        if again.success and again.chi2 < base_chi2:
            moved = base_chi2 - again.chi2 > _BASE_MOVED
            base, base_chi2 = again, again.chi2
            patterns = _patterns(obs, base, alpha)
            if moved:  # the first base was not its minimum: score at this one, refit from it
                say("the base refitted from a candidate's fit is lower: screening and fits again")
                scores = _scores(tables, base, free, cands)
                behind = [c for c in chosen if c.name in extended and extended[c.name].chi2 > base_chi2]
                tasks = [dict(tables=tables, params=list(params), free=free + [c.name],
                              noise_sd=noise_sd, warm=base, **fit_options) for c in behind]
                for c, f in zip(behind, run_fits(tasks, pool, runner=_fit_walks_or_reason), strict=True):
                    if not isinstance(f, str) and f.success and f.chi2 < extended[c.name].chi2:
                        extended[c.name] = f
    if not math.isfinite(base_chi2):
        raise DiagnoseError(f"the base model could not be fitted to the {len(tables)} walks: {base.status}")
    ranking = []
    for c in cands:
        row = {"effect": c.name}
        if c.name in scores:
            row["score_z"] = scores[c.name]["z"]
        f = extended.get(c.name)
        if f is not None:
            row.update(fitted=True, status=f.status)
        if f is not None and f.success:
            lr = max(base_chi2 - f.chi2, 0.0)
            low, high = f.interval(c.name)
            row.update(lr=lr, lr_p=lr_p_value(lr, c.side != 0), estimate={c.name: f.estimates[c.name]},
                       interval={c.name: [low, high]})
        ranking.append(row)
    complete_rows(ranking)
    ranking.sort(key=lambda r: -r.get("lr", -math.inf))
    significant = [r for r in ranking if "lr" in r and r["lr_p"] < alpha / k]
    held: dict = {}
    further = None
    named = patterns_named = features_named = None
    decision = None
    if not significant and quiet:
        verdict, cause, evidence = "adequate", None, ("no candidate's score test is significant and no "
                                                      "walk's residuals repeat a pattern every step")
    elif not significant:
        verdict, cause, evidence = "discrepancy", "unexplained", "no fitted candidate is significant"
    else:
        references = [noise_reference(o, w.noise_sd, w.noise_source)
                      for o, w in zip(obs, base.walks, strict=True)]

        def held_out_gain(row: dict) -> tuple[float, str]:
            say(f"held-out prediction by stride: base and {row['effect']}")
            tasks = (_held_out_walk_tasks(tables, params, base, **fit_options)
                     + _held_out_walk_tasks(tables, params, extended[row["effect"]], **fit_options))
            fits = held_out_fits(tasks, pool, runner=_fit_walks_or_reason)
            held.update({"base": _held_out_walk_score(tables, base, fits[:2]),
                         row["effect"]: _held_out_walk_score(tables, extended[row["effect"]], fits[2:])})
            reasons = "; ".join(h["reason"] for h in held.values() if h["reason"])
            return held["base"]["chi2"] - held[row["effect"]]["chi2"], reasons

        def explain(names: list) -> Explanation:
            model = extended[names[0]]
            reports, misfits = _patterns(obs, model, alpha), _features(obs, model)
            labels = [f" (walk {i + 1})" for i in range(len(tables))]
            walks = [(label, {"rms": m["rms"], "rms_base": b["rms"], "n": m["n_by_signal"]}, ref)
                     for label, b, m, ref in zip(labels, held["base"]["scores"], held[names[0]]["scores"],
                                                 references, strict=True)]
            whiteness = {f"{c}{label}": p
                         for label, ref, rep, w in zip(labels, references, reports, model.walks, strict=True)
                         for c, p in white_components(ref, rep, w.noise_source).items()}
            explained.update(residuals=reports, features=misfits)
            return judge(names, held=walks, patterns=list(zip(labels, reports, strict=True)),
                         features=list(zip(labels, misfits, strict=True)), whiteness=whiteness,
                         alpha=alpha)

        explained: dict = {}
        decision = decide(significant, alpha / k, explain=explain, held_out=held_out_gain)
        verdict, cause = decision.verdict, decision.cause
        lead = decision.lead
        if cause != "unexplained":
            gap = lead["lr"] - significant[1]["lr"] if len(significant) > 1 else math.inf
            evidence = (f"{lead['effect']} explains the {len(tables)} walks together {gap:.1f} better in "
                        "chi-square than the next significant candidate" if math.isfinite(gap) else
                        f"{lead['effect']} is the only significant candidate")
            evidence += (f", and predicts their held-out strides {lead['held_out_gain']:.1f} better than "
                         "the base")
            named = extended[cause]
            note = parameter_note(lead, next(c for c in cands if c.name == cause))
            evidence += f"; {note}" if note else ""
        else:
            evidence = decision.reason
        if decision.explanation is not None:
            patterns_named, features_named = explained["residuals"], explained["features"]
        close = tied(ranking, alpha / k) if decision.tied and tie_design else []
        if close:
            further = weigh_ties(tables, base.walks, cands, close, pool=pool, alpha=alpha, say=say,
                                 **fit_options)
            evidence += further_walk_clause(further)
    note = _pattern_note(patterns)
    if note:
        evidence += f"; the base model leaves a pattern repeated every step ({note})"
    features = _features(obs, base)
    note = _feature_note(features)
    if note:
        evidence += f"; gait features the base misses ({note})"
    if dropped:
        evidence += f"; the contact positions of walk(s) {dropped} were not used: they have no SDs"
    # the model judged (the named cause's, or the effective description's)
    shown = extended[decision.lead["effect"]] if decision and decision.explanation else None
    gain = {"metric": "chi-square, all walks", "base": base_chi2,
            "extended": shown.chi2 if shown is not None else None}
    if held:
        name = next(n for n in held if n != "base")
        gain["held_out"] = {"metric": "held-out chi-square (two folds of alternate strides, all walks)",
                            "base": held["base"]["chi2"], "extended": held[name]["chi2"],
                            "by_walk": {"base": held["base"]["by_walk"], "extended": held[name]["by_walk"]},
                            "candidate": name}
    return WalksDiagnosis(verdict=verdict, cause=cause, causes=[cause] if named is not None else [],
                          effective=(decision.explanation.to_json()
                                     if decision and decision.explanation else None),
                          ranking=ranking, gain=gain, evidence=evidence, base=base, extended=extended,
                          rule=WALKS_RULE, alpha=alpha, seconds=time.perf_counter() - clock,
                          residuals=patterns, residuals_extended=patterns_named, features=features,
                          features_extended=features_named, next_walk=further)
