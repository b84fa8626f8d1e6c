"""Which further walks would tell apart the causes that one walk cannot: first-order separation.

A walk on its cycle can leave candidate causes tied: they move the gait along nearly one direction
beyond what the base model's free parameters and the nuisances mimic, so their fits come within
:data:`toywalk.sysid.discrepancy.SEPARATION` in chi-square and the analysis rightly says
``unexplained``. A second walk of the same walker under a changed, known condition (another
slope, a balance mass moved) sees the same causes along other directions. This module measures,
before anyone films it, how far apart a set of walks analysed jointly would bring them.

**Method** (linear least squares about the base fit, the score tests' first order:
:func:`toywalk.sysid.fit.score_tests`). For each walk, the base model is fitted and the whitened
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

from .discrepancy import ALPHA, SEPARATION, Candidate, lr_p_value
from .fit import fit, held_jacobian
from .walks import stacked

__all__ = ["DesignError", "WalkColumns", "separation", "walk_columns"]


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
        The analysis's candidates (:func:`toywalk.sysid.discrepancy.candidates`), each a shared
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
        candidate by :data:`toywalk.sysid.discrepancy.SEPARATION`).
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
