"""Which further walks would tell apart the causes that one walk cannot: first-order separation.

A walk on its cycle can leave candidate causes tied: they move the gait along nearly one direction
beyond what the base model's free parameters and the nuisances mimic, so their fits come within
:data:`toywalk.sysid.naming.SEPARATION` in chi-square and the analysis rightly says
``unexplained``. A second walk of the same walker under a changed, known condition (another
slope, a balance mass moved) sees the same causes along other directions. This module measures,
before anyone films it, how far apart a set of walks analysed jointly would bring them.

**Method** (linear least squares about the base fit, the score tests' first order:
:func:`toywalk.sysid.score.score_tests`). For each walk, the base model is fitted and the whitened
residuals' Jacobian taken through the BVP in the free parameters, every candidate and the walk's
nuisances (:func:`walk_columns`). The walks' Jacobians are stacked: a shared unknown's column (the
free parameters and the candidates: properties of the walker) is the walks' columns one above the
other, a nuisance's (offsets, clock) sits in its own walk's rows. With ``P`` the projection off
the free parameters' and every nuisance's columns, the change that a hidden cause A of strength
``s`` makes to the data beyond the base is ``y = P j_A s``, and freeing a candidate B recovers
the likelihood ratio ``LR_B = (P j_B . d)^2 / |P j_B|^2`` from the data ``d = y + e`` (``e``
white, unit variance: the residuals are whitened); a candidate whose base value sits on a bound
(a damper at zero) gets 0 when its estimate would leave the bound, as its one-sided test does.
Without noise ``LR_A = |y|^2`` and the gap ``LR_A - LR_B = |y|^2 (1 - cos^2)``, ``cos`` the angle
between ``P j_A`` and ``P j_B``; with noise, the share of draws of ``e`` in which A is significant
and beats every other candidate by the rule's margin is the rate at which the analysis's rule
would name A (its held-out check aside).

It is a linearisation: on the stable toy's walk its gaps agree with the fitted ones within the
noise (docs/diagnosis.md, "Which second walk breaks the ties"; ``tests/sysid/test_design.py``
compares it with nonlinear fits).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from toywalk.model.parameters import Params
from toywalk.model.trajectory import TrajectoryTable
from toywalk.model.walker import STATE_NAMES

from .fit import FitError, FitResult, fit, held_jacobian
from .heldout import FitPool, run_fits
from .naming import ALPHA, SEPARATION, Candidate, lr_p_value
from .problem import stacked

__all__ = ["CONDITIONS", "Condition", "DesignError", "WalkColumns", "next_walk", "separation",
           "walk_columns"]


class DesignError(ValueError):
    """A walk cannot be used (its base fit fails, its columns do not match); the message says why."""


@dataclasses.dataclass
class WalkColumns:
    """One walk's whitened Jacobian at its base fit (:func:`walk_columns`).

    Attributes
    ----------
    shared : ndarray, shape (n_residuals, n_free + n_candidates)
        Columns of the walker's own unknowns: the free parameters, then the candidates.
    nuisance : ndarray, shape (n_residuals, n_nuisances)
        Columns of the walk's own unknowns (offsets, clock, a transient's start).
    names : list of str
        The shared columns' names.
    n_free : int
    label : str
    """

    shared: np.ndarray
    nuisance: np.ndarray
    names: list
    n_free: int
    label: str = ""


def walk_columns(table: TrajectoryTable, params: Params, free: Sequence[str],
                 candidates: Sequence[str], *, label: str = "", **fit_options) -> WalkColumns:
    """Fit the base model (``params``, ``free``) to ``table`` and take the whitened Jacobian in
    the free parameters, the ``candidates`` (parameter-file names) and the walk's nuisances.

    ``fit_options`` go to :func:`toywalk.sysid.fit.fit` (give ``noise_sd`` for an expected
    statistic: a noise-free walk's residual RMS is no noise SD). Raises :class:`DesignError` when
    the base fit fails.
    """
    free, candidates = list(free), list(candidates)
    base = fit(table, params, free, check_jacobian=False, **fit_options)
    if not base.success:
        raise DesignError(f"the base fit of walk {label or '(unnamed)'} failed: {base.status}")
    jac, _ = held_jacobian(table, base, candidates)
    k = len(free) + len(candidates)
    return WalkColumns(jac[:, :k], jac[:, k:], free + candidates, len(free), label)


def separation(walks: Sequence[WalkColumns], candidates: Sequence[Candidate], hidden: dict, *,
               draws: int = 2000, alpha: float = ALPHA, rng=None) -> list[dict]:
    """How far apart the walks, analysed together, bring each hidden cause and the other
    candidates (module docstring).

    Parameters
    ----------
    walks : sequence of WalkColumns
        One or more walks of the same walker, their shared columns named alike.
    candidates : sequence of Candidate
        The analysis's candidates (:func:`toywalk.sysid.naming.candidates`), each a shared
        column of every walk.
    hidden : dict of str to float
        Hidden cause (a candidate's name) -> its change from the base value (its units).
    draws : int
        Noise draws for the rate at which the rule names the hidden cause.
    alpha : float
        The rule's family-wise false-alarm rate (significance at ``alpha / K``).
    rng : seed or Generator

    Returns
    -------
    list of dict
        Per hidden cause: ``hidden``, ``change``, ``lr`` (its expected likelihood ratio,
        ``|y|^2``), ``gaps`` (candidate -> expected ``LR_hidden - LR_candidate`` without noise),
        ``nearest`` (the candidate of the smallest gap) and ``gap``, and ``named_rate`` (the
        share of ``draws`` in which the hidden cause is significant and ahead of every other
        candidate by :data:`toywalk.sysid.naming.SEPARATION`).
    """
    if not walks:
        raise DesignError("no walks given")
    names = walks[0].names
    if any(w.names != names or w.n_free != walks[0].n_free for w in walks):
        raise DesignError("every walk needs the same free parameters and candidates, in one order")
    by_name = {c.name: c for c in candidates}
    unknown = [n for n in list(by_name) + list(hidden) if n not in names[walks[0].n_free:]]
    if unknown:
        raise DesignError(f"not among the walks' candidates: {', '.join(unknown)}")
    shared, nuisance = stacked([w.shared for w in walks], [w.nuisance for w in walks])
    fitted = np.hstack([shared[:, :walks[0].n_free], nuisance])
    u, sv, _ = np.linalg.svd(fitted, full_matrices=False)
    basis = u[:, sv > sv[0] * max(fitted.shape) * np.finfo(float).eps] if len(sv) else u
    order = list(by_name)
    perp = np.array([shared[:, names.index(n)] - basis @ (basis.T @ shared[:, names.index(n)])
                     for n in order]).T
    # Everything the likelihood ratios see lies in the span of the candidates' remainders: an
    # orthonormal basis of it carries the noise as k unit normals (the rest of e is irrelevant).
    q, sq, _ = np.linalg.svd(perp, full_matrices=False)
    q = q[:, sq > sq[0] * max(perp.shape) * np.finfo(float).eps]
    cols = q.T @ perp  # (k, n_candidates)
    norms2 = np.sum(cols**2, axis=0)
    sides = np.array([by_name[n].side for n in order])
    k_all = len(order)
    gen = np.random.default_rng(rng)

    def lrs(data: np.ndarray) -> np.ndarray:
        """Likelihood ratios (n_draws, n_candidates) of data (n_draws, k)."""
        dot = data @ cols
        lr = np.where(norms2 > 0, dot**2 / np.where(norms2 > 0, norms2, 1.0), 0.0)
        return np.where(sides * dot < 0, 0.0, lr)  # a bounded candidate cannot leave its bound

    out = []
    for name, change in hidden.items():
        a = order.index(name)
        y = cols[:, a] * change
        lr0 = lrs(y[None, :])[0]
        gaps = {n: float(lr0[a] - lr0[j]) for j, n in enumerate(order) if j != a}
        nearest = min(gaps, key=gaps.get) if gaps else None
        sample = lrs(y[None, :] + gen.standard_normal((draws, len(y))))
        others = np.delete(sample, a, axis=1)
        ahead = sample[:, a] - (others.max(axis=1) if others.shape[1] else 0.0) >= SEPARATION
        p = np.array([lr_p_value(v, by_name[name].side != 0) for v in sample[:, a]])
        named = ahead & (p < alpha / k_all)
        out.append({"hidden": name, "change": float(change), "lr": float(lr0[a]), "gaps": gaps,
                    "nearest": nearest, "gap": gaps[nearest] if nearest else math.inf,
                    "named_rate": float(np.mean(named)), "draws": draws})
    return out


@dataclasses.dataclass(frozen=True)
class Condition:
    """A known change to the walker under which a further walk is filmed: the parameter ``name``
    (a parameter-file name) multiplied by ``factor``; ``label`` says it in words."""

    label: str
    name: str
    factor: float


#: The further walks a tie's report weighs. On the stable toy a ramp at 0.8 of the slope separated
#: the hinge's dry from its viscous friction, and balance masses moved by 1 cm (5 % of its lateral
#: offset) pivot friction from both (docs/diagnosis.md, "Which second walk breaks the ties"); a
#: steeper ramp is there for walkers with no gait on a flatter one (the clearing toy folds 3 %
#: below its slope), and the masses move by 10 % so that a walker with a small lateral offset
#: still changes measurably.
CONDITIONS = (
    Condition("a ramp at 0.8 of the slope", "slope", 0.8),
    Condition("a ramp at 1.2 times the slope", "slope", 1.2),
    Condition("the legs' centres of mass 10 % further out (balance masses moved out)",
              "com_offset[1]", 1.1),
    Condition("the legs' centres of mass 10 % further in (balance masses moved in)",
              "com_offset[1]", 0.9),
)


def next_walk(tables: Sequence[TrajectoryTable], bases: Sequence[FitResult],
              candidates: Sequence[Candidate], hidden: dict, *,
              conditions: Sequence[Condition] = CONDITIONS, pool: FitPool | int = 1,
              draws: int = 2000, alpha: float = ALPHA, rng=0, **fit_options) -> dict:
    """Which further walk, analysed with the measured ones, would tell apart the tied causes
    ``hidden`` (first order about the base fit: :func:`separation`).

    For each condition the first walk's fitted walker (``bases[0].params``) is changed, its gait
    followed there from the base fit's by continuation, and a noise-free walk of it simulated
    with the first walk's steps, sample rate and signals; the base model is fitted to that walk
    with the first base fit's noise SDs (:func:`walk_columns`). Each tied cause is then hidden at
    its fitted change from its base value, in the measured walks and the further one alike, and
    the gaps to every other candidate and the rule's naming rate computed; one more walk like the
    first is the reference (as much data again, no new direction).

    Parameters
    ----------
    tables : sequence of TrajectoryTable
        The measured walks (one, or several analysed together); ``bases`` their base fits (of
        a joint fit, :attr:`toywalk.sysid.walks.WalksFit.walks`).
    candidates : sequence of Candidate
        The analysis's candidates.
    hidden : dict of str to float
        Each tied cause (a candidate's name) -> its fitted change from the base value.
    conditions : sequence of Condition
    pool : FitPool or int
        Where the further walks' fits run (:func:`toywalk.sysid.heldout.run_fits`).
    draws, alpha, rng
        As :func:`separation`.
    **fit_options
        Passed to the further walks' base fits (``offsets``, ``priors``).

    Returns
    -------
    dict
        ``tied`` (the names), ``conditions`` (per condition: ``label``, ``parameter``, ``from``,
        ``to``, the further walk's gait ``max_abs_eigenvalue`` and ``stable``, ``results`` as
        :func:`separation` gives them without ``gaps`` beyond the ``nearest``, ``gap`` and
        ``named_rate`` the smallest over the tied causes, or ``reason`` where the walk could
        not be made or fitted), ``same_again`` (the reference row), ``suggestion`` (the label of
        the condition that names every tied cause most often, at least half the time, preferring
        one whose gait is stable when the measured walker's is; None when none does) and
        ``method``.
    """
    if not tables or len(tables) != len(bases):
        raise DesignError(f"need one base fit per walk, at least one walk: got {len(tables)} walks "
                          f"and {len(bases)} fits")
    table, base = tables[0], bases[0]
    free, names = list(base.free), [c.name for c in candidates]
    k = len(free) + len(names)
    own = []
    for i, (t, b) in enumerate(zip(tables, bases, strict=True)):
        jac, _ = held_jacobian(t, b, names)
        own.append(WalkColumns(jac[:, :k], jac[:, k:], free + names, len(free), f"measured {i + 1}"))
    steps = max(len([e for e in table.events if e.get("time") is not None]) - 1, 1)
    rate = 1.0 / float(np.median(np.diff(table.time)))
    signals = [n for n in ("lean", "steer", "pitch_left", "pitch_right", "contact_x", "contact_y")
               if n in table.signals]
    gait = base.gait or {}
    z_start = [gait["fixed_point"][n] for n in STATE_NAMES] if "fixed_point" in gait else None
    options = {k: v for k, v in fit_options.items() if k not in ("model", "strikes", "max_iter")}
    tasks = [dict(params=base.params, condition=c, z_start=z_start, planar=bool(gait.get("planar")),
                  steps=steps, rate=rate, signals=signals, free=free, names=names,
                  noise_sd={n: v for n, v in base.noise_sd.items() if n in signals}, options=options)
             for c in conditions]
    walks = run_fits(tasks, pool, runner=_further_walk) if tasks else []

    def summary(walk_list) -> dict:
        results = separation(walk_list, candidates, hidden, draws=draws, alpha=alpha, rng=rng)
        worst = min(results, key=lambda r: (r["named_rate"], r["gap"]))
        return {"results": [{key: r[key] for key in ("hidden", "change", "lr", "nearest", "gap",
                                                     "named_rate")} for r in results],
                "gap": min(r["gap"] for r in results), "named_rate": worst["named_rate"]}

    rows = []
    for c, walk in zip(conditions, walks, strict=True):
        row = {"label": c.label, "parameter": c.name, "from": base.params.get(c.name),
               "to": base.params.get(c.name) * c.factor}
        if isinstance(walk, str):
            row["reason"] = walk
        else:
            row.update(max_abs_eigenvalue=walk["max_abs_eigenvalue"], stable=walk["stable"],
                       **summary([*own, walk["columns"]]))
        rows.append(row)
    want_stable = bool(gait.get("stable", False))
    usable = [r for r in rows if "named_rate" in r and r["named_rate"] >= 0.5
              and r["gap"] >= SEPARATION and (r["stable"] or not want_stable)]
    best = max(usable, key=lambda r: (r["named_rate"], r["gap"])) if usable else None
    return {"tied": list(hidden), "conditions": rows, "same_again": summary([*own, own[0]]),
            "suggestion": best["label"] if best else None,
            "method": ("first order about the base fit (toywalk.sysid.design): the measured "
                       f"walk{'s' if len(tables) > 1 else ''} and one further walk analysed "
                       "together, each tied cause hidden at its fitted change, "
                       f"{draws} noise draws for the naming rate")}


def _further_walk(task: dict):
    """One condition's further walk and its columns (:func:`next_walk`), or why there is none (a
    string). Module level, so that worker processes can unpickle it."""
    from toywalk.model.gait import continue_gait, find_gait
    from toywalk.model.simulate import simulate

    params, c = task["params"], task["condition"]
    try:
        changed = params.replace(**{c.name: params.get(c.name) * c.factor})
    except ValueError as err:  # the changed value outside the parameter's bounds
        return f"the changed walker is not valid: {err}"
    try:
        if task["z_start"] is not None:
            gait = continue_gait(params, changed, np.asarray(task["z_start"]), planar=task["planar"])
        else:
            gait = find_gait(changed)
    except RuntimeError as err:  # GaitNotFound, or a CasADi failure inside the search
        return f"no gait of the changed walker: {err}"
    traj = simulate(changed, gait.fixed_point, task["steps"], sample_rate=task["rate"],
                    planar=gait.planar)
    if traj.status != "completed":
        return f"the changed walker's walk stopped: {traj.message}"
    series = {**traj.angles(), "contact_x": traj.contact[:, 0], "contact_y": traj.contact[:, 1]}
    events = [{"time": 0.0, "foot": "L"}] + [{"time": e.time, "foot": e.foot} for e in traj.events]
    walk = TrajectoryTable(traj.times, {n: series[n] for n in task["signals"]}, traj.stance, events, {})
    try:
        columns = walk_columns(walk, changed, task["free"], task["names"], label=c.label,
                               model="periodic", noise_sd=task["noise_sd"], **task["options"])
    except (DesignError, FitError) as err:
        return str(err)
    return {"columns": columns, "max_abs_eigenvalue": gait.max_abs_eigenvalue, "stable": gait.stable}
