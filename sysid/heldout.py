"""Batches of fits and held-out prediction, shared by the analyses of one walk and of several.

:class:`FitPool` runs an analysis's batches of fits (:func:`run_fits`) in this process, in local
processes or on a Dask cluster. Held-out prediction (:func:`held_out`) fits the walk on one fold
of alternate strides and scores the model on the other (:func:`held_out_tasks`,
:func:`held_out_fits`, :func:`held_out_score`): a candidate that explains the walk predicts
strides it was not fitted to.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
from toywalk.model.parameters import Params
from toywalk.model.trajectory import SIGNALS, TrajectoryTable

from .fit import FitError, FitResult, fit
from .measurement import observations
from .sample import worker_pool

__all__ = ["HELD_OUT_SD", "FitPool", "held_out", "held_out_fits", "held_out_score", "held_out_tasks",
           "masked", "run_fits", "strides"]

#: SD of a held-out fold's samples (rad, m): weight 1e-12 of a measured one, so that the fold's
#: fit ignores them while their residuals are still computed.
HELD_OUT_SD = 1e3


def strides(n_steps: int) -> np.ndarray:
    """Each measured step's fold: alternate strides (pairs of steps) go to folds 0 and 1."""
    return (np.arange(n_steps) // 2) % 2


def held_out_tasks(table: TrajectoryTable, params: Params, free, noise: dict,
                   warm: FitResult | None = None, **fit_options) -> list[dict]:
    """The two fits of held-out prediction grouped by stride (:func:`held_out`), as keyword
    arguments of :func:`toywalk.sysid.fit.fit`: alternate strides form two folds (:func:`strides`),
    each fit sees one fold. The held-out samples stay in the fit with a huge SD
    (:data:`HELD_OUT_SD`), so the model is read at them without their weighing in; heel strikes
    and contact positions of the whole walk remain data. ``warm``, a fit of the whole walk, is
    where each fold's fit starts."""
    obs = observations(table)
    fold_of_step = strides(obs.n_steps)
    sd = {name: float(noise[name]) for name in SIGNALS if name in noise}
    # The folds carry their noise in the table's SD columns (the held-out samples' huge SD among
    # them), so a noise SD given to the whole analysis is not passed on.
    options = {k: v for k, v in fit_options.items() if k != "noise_sd"}
    return [dict(table=masked(table, obs, np.flatnonzero(fold_of_step == fold), sd), params=params,
                 free=list(free), noise_sd=None, check_jacobian=False, warm=warm, **options)
            for fold in (0, 1)]


def held_out_score(table: TrajectoryTable, fits: list, noise: dict) -> dict:
    """Score the two fold fits of :func:`held_out_tasks`: the held-out chi-square (with ``noise``)
    overall and per signal, the held-out RMS and samples per signal (``n_by_signal``), and whether
    both fits converged. A fold
    whose fit could not be set up (a string) or did not converge leaves the chi-square NaN, with
    the ``reason``: a fit stopped on its way predicts nothing about the model."""
    obs = observations(table)
    fold_of_step = strides(obs.n_steps)
    failed = [f if isinstance(f, str) else f"fold {k}'s fit ended with {f.status}"
              for k, f in enumerate(fits) if isinstance(f, str) or not f.success]
    if failed:
        return {"chi2": math.nan, "chi2_by_signal": {}, "rms": {}, "success": False, "n": 0,
                "n_by_signal": {}, "reason": "; ".join(failed)}
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
            "success": all(f.success for f in fits), "n": int(sum(counts.values())), "n_by_signal": counts}


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


def masked(table: TrajectoryTable, obs, held_steps: np.ndarray, sd: dict) -> TrajectoryTable:
    """The walk with SD columns: the noise SD everywhere, :data:`HELD_OUT_SD` in the held-out
    steps."""
    bounds = np.r_[obs.step_start, obs.step_end[-1]]
    step = np.searchsorted(bounds, table.time, side="right") - 1
    held = np.isin(step, held_steps)
    signals = dict(table.signals)
    for name in SIGNALS:
        if name in signals:
            signals[f"{name}_sd"] = np.where(held, HELD_OUT_SD, sd[name])
    events = [dict(e) for e in table.events]
    return TrajectoryTable(table.time, signals, table.stance, events, dict(table.metadata))
