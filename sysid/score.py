"""Rao's score tests of held parameters at a fit, without refitting (:func:`score_tests`): the
screening of the diagnosis (:mod:`toywalk.sysid.discrepancy`), the missing force's search
(:mod:`toywalk.sysid.missing_force`) and the design of a further walk
(:mod:`toywalk.sysid.design`) read them."""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from toywalk.model.trajectory import TrajectoryTable

from .fitresult import FitResult
from .problem import ALONE, continued, setup, whitened_loads
from .residuals import shared_errors

__all__ = ["held_jacobian", "score_statistics", "score_tests"]


def score_tests(table: TrajectoryTable, result: FitResult, names) -> dict:
    """Rao's score test of each held parameter in ``names`` at the fit ``result``.

    Without refitting: the whitened residuals ``r`` and their Jacobian at the fit, the fitted
    unknowns' columns ``J_b`` (free parameters, a transient's start, offsets, origin, time
    offset) and a held parameter's column ``j`` (implicit-function theorem through the BVP, as
    for the fitted ones). With ``j_perp`` the part of ``j`` that the fitted unknowns cannot mimic
    (``j`` less its projection on ``J_b``), one Gauss-Newton step in the held parameter alone is
    ``step = -(j_perp . r) / |j_perp|^2`` with standard error ``1 / |j_perp|``, and ``z = step /
    se`` is the signed root of the score statistic: ``z^2`` is chi-square on one degree of freedom
    when the held value is right (Rao 1948, Proc. Camb. Phil. Soc. 44:50), and to first order the
    likelihood-ratio statistic of freeing it.

    Where the samples share errors by phase (the file's ``*_phase_sd``, a tracker's bias repeated
    in every step: :func:`toywalk.sysid.residuals.shared_errors`), ``j_perp . r`` has the
    variance ``j_perp^T Omega j_perp`` of the whitened errors' covariance Omega, not
    ``|j_perp|^2``, and the standard error is widened by the square root of their ratio,
    ``inflation`` (:func:`score_statistics`).

    Returns
    -------
    dict of str to dict
        Per name: ``z``, ``step`` (the parameter's change, its units), ``se``, ``inflation``.
    """
    names = list(names)
    if not names:
        return {}
    jac, r, shared = held_jacobian(table, result, names, shared=True)
    held = [len(result.free) + k for k in range(len(names))]
    return dict(zip(names, score_statistics(jac, r, held, shared), strict=True))


def held_jacobian(table: TrajectoryTable, result: FitResult, names, shared: bool = False) -> tuple:
    """The whitened residuals' Jacobian at the fit ``result`` in its unknowns and in the held
    parameters ``names`` (the implicit-function theorem through the BVP, as for the fitted ones),
    and the whitened residuals; with ``shared``, also the whitened loadings of the errors the
    residuals share by phase.

    Returns
    -------
    jac : ndarray, shape (n_residuals, n_free + n_names + n_nuisances)
        Columns: ``result.free``, then ``names``, then the fit's other unknowns (a transient's
        free start, offsets, the contacts' origin, time offset:
        :meth:`toywalk.sysid.problem.FitProblem.jacobian`).
    r : ndarray, shape (n_residuals,)
    q : scipy.sparse matrix, shape (n_residuals, cells)
        With ``shared`` only: :func:`toywalk.sysid.problem.whitened_loads` of the file's shared
        errors, zero rows beyond the angles (no cells where the file has no ``*_phase_sd``).

    The compliant heel strike (``effects.soft_heel``) models the seed's walker, so a fit refuses
    it beside other effects: its column comes from a problem of its own (at the fit, with every
    held parameter at its value, each column is the same in either).
    """
    names = list(names)
    alone = [n for n in names if n == ALONE] if len(names) > 1 else []
    problem, x = _held_problem(table, result, [n for n in names if n not in alone])
    jac, r = problem.jacobian(x, result.sigma), problem.whitened(x, result.sigma)
    if alone:
        own, x_own = _held_problem(table, result, alone)
        n_f = len(result.free)
        at = n_f + names.index(ALONE)
        jac = np.insert(jac, at, own.jacobian(x_own, result.sigma)[:, n_f], axis=1)
    if not shared:
        return jac, r
    return jac, r, whitened_loads(shared_errors(problem.obs), result.sigma, rows=len(r))


def _held_problem(table: TrajectoryTable, result: FitResult, names: list):
    """The fit's problem with ``names`` free too, and its unknowns at the fit."""
    problem, w0 = setup(table, result.params, list(result.free) + names, z_guess=None,
                        check_jacobian=False, priors=result.priors, **result.options)
    return problem, continued(problem, w0, result)


def score_statistics(jac: np.ndarray, r: np.ndarray, held, shared: sp.spmatrix | None = None) -> list[dict]:
    """Rao's score statistic of each held column of ``jac`` (shape (n_residuals, n_unknowns)) at
    the whitened residuals ``r``, the other columns being the fitted unknowns
    (:func:`score_tests`): per held column ``z``, ``step``, ``se`` and ``inflation``. By the
    Frisch-Waugh-Lovell theorem ``step`` is the coefficient of that column in the least-squares
    regression of ``-r`` on it and the fitted columns together, ``se`` its standard error.

    ``shared`` (shape (n_residuals, cells), :func:`toywalk.sysid.problem.whitened_loads`) are
    errors the residuals share: their covariance is then ``Omega = diag(1 - q^2) + Q Q^T`` rather
    than the identity (``q`` the rows' norms), and ``j_perp . r`` has the variance ``j_perp^T
    Omega j_perp``. Its ratio to ``|j_perp|^2``, ``inflation``, is a design effect (Kish 1965,
    *Survey Sampling*): ``se`` is widened by its square root, and a likelihood-ratio statistic of
    freeing the column, first order ``(j_perp . r)^2 / |j_perp|^2``, is chi-square on one degree
    of freedom once divided by it (the first-order correction of Rao & Scott 1981, JASA 76:221,
    exact for one degree of freedom to that order). ``inflation`` is 1 with nothing shared."""
    held = list(held)
    if shared is not None and shared.nnz:
        shared = sp.csr_matrix(shared)
        own = np.asarray(shared.multiply(shared).sum(axis=1)).ravel()  # q^2, each row's shared part
    else:
        shared = None
    out = []
    # The fitted unknowns' columns are the same for every held one: one orthonormal basis of
    # their span (SVD, rank-revealing like a least-squares solve) serves them all.
    others = np.delete(jac, held, axis=1)
    u, sv, _ = np.linalg.svd(others, full_matrices=False)
    basis = u[:, sv > sv[0] * max(others.shape) * np.finfo(float).eps] if len(sv) else u
    for col in held:
        j = jac[:, col]
        perp = j - basis @ (basis.T @ j)
        norm2 = float(perp @ perp)
        # Only an exactly mimicked column is untestable here: a column that the fitted unknowns
        # nearly mimic can keep a small, real remainder (the sample video's cross slope, largely
        # a lean offset, has z = 28.5: tests/sysid/test_demo.py). A remainder at round-off shows
        # as a huge standard error.
        if norm2 <= 1e-300:
            out.append({"z": 0.0, "step": 0.0, "se": math.inf, "inflation": 1.0})
            continue
        inflation = 1.0
        if shared is not None:
            through = shared.T @ perp
            inflation = max((norm2 - float(own @ perp**2) + float(through @ through)) / norm2, 1e-12)
        step = -float(perp @ r) / norm2
        se = math.sqrt(inflation / norm2)
        out.append({"z": step / se, "step": step, "se": se, "inflation": inflation})
    return out

