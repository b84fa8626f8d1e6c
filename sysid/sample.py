"""Posterior sampling of a fit's free parameters with emcee: resumable, parallel, diagnosed.

Several **independent ensembles** (emcee's affine-invariant ensemble sampler, Foreman-Mackey et
al. 2013, PASP 125:306) run one after another, each in its own group of one HDF5 file (emcee's
``HDFBackend``, written after every step). Walkers of one ensemble are not independent chains, so
R-hat compares ensembles, not walkers. Each ensemble starts in a small ball about the fit's
estimates drawn from its covariance (inside the prior), and its random state comes from the seed
and its index, so a run is reproducible. A run that is killed resumes where the file ends: every
stored step is kept and the run continues to the requested length, from the stored state. Ctrl-C
or SIGTERM finishes the step under way, stores it and stops. A file at the chain path that is not
a chain file of this module is refused and left as it is; a new file in which no step was stored
is removed when the run fails.

The log-posterior (:class:`toywalk.sysid.likelihood.LogPosterior`) returns a blob per sample: the
gait's max |eigenvalue| and a status (found, outside the prior, no gait). ``--workers K``
evaluates it in K local processes (one BLAS/OpenMP thread each; compiled functions are loaded
once per process), ``--scheduler ADDR`` on a Dask distributed cluster through its executor.

Stop rule: a chain is long enough when it is longer than 50 integrated autocorrelation times
(emcee's ``integrated_time`` with ``tol=50``) in every parameter; the summary says whether it is.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import warnings
from pathlib import Path

import numpy as np
from toywalk.model.files import strict_json
from toywalk.model.parameters import Params
from toywalk.model.trajectory import SIGNALS, TrajectoryTable
from toywalk.model.walker import STATE_NAMES

from .likelihood import NO_GAIT, OK, OUTSIDE_PRIOR, LogPosterior
from .measurement import observations
from .measurement import path as contact_path
from .problem import CONTACT_KEYS, gait_period, parameter_bounds

__all__ = ["SampleError", "SampleSummary", "diagnose_chains", "posterior_from_fit", "sample", "worker_pool"]

#: Integrated autocorrelation times a chain must exceed (emcee's recommendation).
TAU_FACTOR = 50
_BLOBS = [("max_abs_eigenvalue", float), ("status", int)]


class SampleError(ValueError):
    """The sampling run cannot start or continue (bad fit file, mismatched chain file)."""


@dataclasses.dataclass
class SampleSummary:
    """Diagnostics of a sampling run (JSON-ready through :meth:`to_json`)."""

    names: list
    ensembles: int
    walkers: int
    steps: int
    data: dict

    def to_json(self) -> dict:
        return {"names": self.names, "ensembles": self.ensembles, "walkers": self.walkers,
                "steps": self.steps, **self.data}


def posterior_from_fit(report: dict, table: TrajectoryTable) -> tuple[LogPosterior, np.ndarray,
                                                                     np.ndarray]:
    """The log-posterior of a fit file's free parameters, their estimates and covariance.

    Noise SDs: the file's ``*_sd`` columns where the fit used them, else the fit's estimates (or
    the SDs it was given). The likelihood follows the periodic gait by shooting: a fit of the
    transient model is refused.
    """
    try:
        if not report["success"] or not report["gait"]:
            notes = "; ".join(report.get("warnings", [])) or "no gait at the estimates"
            raise SampleError(f"the fit did not succeed ({report['status']}: {notes}): sample from "
                              "a fit that did")
        if "time_offset" not in report["estimates"]:
            raise SampleError("the fit was aligned on the measured heel strikes (--strikes "
                              "measured): the posterior reads the model's strikes; fit with the "
                              "default --strikes model to sample it")
        if report.get("model", "periodic") != "periodic":
            raise SampleError("the fit is of the transient model (the walk is not on its limit "
                              "cycle): the posterior is sampled for the periodic model only; fit "
                              "with --model periodic to sample it")
        params = Params.from_dict(report["params"])
        free = list(report["free"])
        lost = [n for n in report.get("undetermined", []) if n in free]
        if lost:
            raise SampleError(f"the fit does not determine {', '.join(lost)} (its information is "
                              "singular): free fewer parameters, or fit a walk that determines them")
        estimates = np.array([report["estimates"][n] for n in free], dtype=float)
        names = list(report["names"])
        cov_all = np.array(report["covariance"], dtype=float)
        index = [names.index(n) for n in free]
        cov = cov_all[np.ix_(index, index)]
        z_start = np.array([report["gait"]["fixed_point"][n] for n in STATE_NAMES], dtype=float)
        planar = bool(report["gait"].get("planar", False))
        noise = dict(report["noise_sd"])
        source = report["noise_source"]
        offsets = "lean_offset" in report["estimates"]
    except SampleError:
        raise
    except (KeyError, TypeError, ValueError, IndexError) as err:
        raise SampleError(f"not a fit file from `toywalk fit` ({type(err).__name__}: {err})") from err
    if not np.all(np.isfinite(estimates)):
        raise SampleError("not a usable fit file: its estimates of the free parameters are not all "
                          "finite numbers")
    if cov_all.shape != (len(names), len(names)):
        raise SampleError(f"not a usable fit file: its covariance must be a {len(names)} x "
                          f"{len(names)} matrix (one row per name), got shape {cov_all.shape}")
    if not np.all(np.isfinite(cov)):
        raise SampleError("not a usable fit file: the covariance of its free parameters is not all "
                          "finite numbers")
    if not free:
        raise SampleError("the fit has no free parameters to sample")
    obs = observations(table)
    if source == "file":
        sigma = obs.sd.copy()
    else:
        sigma = np.array([noise[SIGNALS[s]] for s in obs.signal], dtype=float)
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise SampleError("the noise SDs are not all positive and finite")
    located = contact_path(obs, 1)
    contact_sd = None
    if located.n:
        source_c = report.get("contact_source", "none")
        if source_c == "file":
            contact_sd = np.r_[located.sd[:, 0], located.sd[:, 1]]
        elif all(k in noise for k in CONTACT_KEYS):
            contact_sd = np.repeat([float(noise[k]) for k in CONTACT_KEYS], located.n)
        else:
            raise SampleError("the walk has contact positions that the fit did not use: fit it "
                              "again with this toolkit's fit")
        if not np.all(np.isfinite(contact_sd) & (contact_sd > 0)):
            raise SampleError("the contact positions' SDs are not all positive and finite")
    bounds = [parameter_bounds(params, n) for n in free]
    priors = {n: tuple(v) for n, v in report.get("priors", {}).items()}
    post = LogPosterior(params, free, bounds, obs, sigma, offsets, z_start, planar,
                        gait_period(params, free), priors,
                        time_offset=float(report["estimates"].get("time_offset", 0.0)),
                        contact_sd=contact_sd)
    return post, estimates, cov


def _initial_ball(estimates, cov, bounds, walkers, rng, post, stopped=lambda: False) -> np.ndarray:
    """Walkers about the estimates (0.1 of the fit's SEs), each inside the prior with a gait.
    ``stopped()`` true (Ctrl-C) ends the search with KeyboardInterrupt."""
    scale = np.sqrt(np.maximum(np.diag(cov), 0.0))
    scale = np.where(scale > 0, scale, 1e-6 * np.maximum(np.abs(estimates), 1e-12))
    out = []
    tries = 0
    while len(out) < walkers:
        if stopped():
            raise KeyboardInterrupt
        tries += 1
        if tries > 100 * walkers:
            raise SampleError("cannot place walkers about the fit's estimates: no gait there")
        x = estimates + 0.1 * scale * rng.standard_normal(len(estimates))
        if all(lo <= v <= hi for v, (lo, hi) in zip(x, bounds, strict=True)) and \
                post(x)[2] == OK:
            out.append(x)
    return np.array(out)


def _ignore_interrupt() -> None:
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def _stop_between_steps():
    """Ctrl-C (SIGINT) or a polite kill (SIGTERM) while sampling: the step under way is finished
    and stored whole, then the run stops with KeyboardInterrupt (one line from the command; the
    file resumes). Yields a function telling whether such a signal came; a second one stops at
    once.

    Without this, KeyboardInterrupt is raised inside the log-posterior, where emcee's wrapper
    prints a traceback and the walker's parameters before passing it on, and SIGTERM ends the
    process wherever it is, possibly inside a write to the chain file.
    """
    import signal
    import threading

    came = []
    if threading.current_thread() is not threading.main_thread():  # signals reach the main thread
        yield lambda: False
        return
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def handler(signum, frame):
        if came:
            for sig, old in previous.items():
                signal.signal(sig, old)
            raise KeyboardInterrupt
        came.append(signum)

    for sig in previous:
        signal.signal(sig, handler)
    try:
        yield lambda: bool(came)
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextlib.contextmanager
def worker_pool(workers: int, scheduler: str | None):
    """A ``map`` provider: None (serial), local processes, or a Dask cluster's executor."""
    if scheduler:
        from distributed import Client

        client = Client(scheduler, timeout="20s")
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    if workers <= 1:
        yield None
        return
    import multiprocessing

    # One BLAS/OpenMP thread per worker: spawned processes read these at import.
    saved = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    os.environ.update({k: "1" for k in saved})
    try:
        # Workers ignore Ctrl-C (sent to the whole process group): the parent stops the run
        # between steps (_stop_between_steps).
        pool = multiprocessing.get_context("spawn").Pool(workers, initializer=_ignore_interrupt)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    try:
        yield pool
    finally:
        pool.terminate()
        pool.join()


def sample(report: dict, table: TrajectoryTable, out: str | Path, *, walkers: int = 32,
           steps: int = 1000, ensembles: int = 3, workers: int = 1, scheduler: str | None = None,
           seed: int | None = 0, progress: bool = False, log=None) -> SampleSummary:
    """Sample the posterior of a fit's free parameters into ``out`` (HDF5), resuming it if present.

    Parameters
    ----------
    report : dict
        A fit file (``toywalk fit``'s JSON).
    table : TrajectoryTable
        The measured walk the fit used.
    out : path
        The chain file; one group ``ensemble_K`` per ensemble.
    walkers, steps, ensembles : int
        Walkers per ensemble (at least twice the number of free parameters), steps per walker,
        independent ensembles.
    workers : int
        Local processes evaluating the log-posterior.
    scheduler : str, optional
        Address of a Dask distributed scheduler (instead of local processes).
    seed : int, optional
        Makes the run reproducible.
    progress : bool
        Show emcee's progress bar.
    log : callable, optional
        ``log(line)`` receives one line of progress at every tenth of each ensemble's steps (how
        far, how long so far, and about how long is left at the rate so far): for a log file,
        where a progress bar is noise and nothing at all looks like a hang (the defaults take
        tens of minutes on one core).
    """
    out = Path(out)
    existed = _check_chain_file(out)
    post, estimates, cov = posterior_from_fit(report, table)
    ndim = len(estimates)
    if walkers < 2 * ndim:
        raise SampleError(f"--walkers must be at least twice the free parameters ({2 * ndim}), got {walkers}")
    if steps < 1 or ensembles < 1:
        raise SampleError("steps and ensembles must be >= 1")
    seeds = np.random.SeedSequence(seed).spawn(ensembles)
    try:
        _run_ensembles(out, post, estimates, cov, walkers, steps, ensembles, seeds, workers,
                       scheduler, progress, log)
    except BaseException:
        # A new chain file that holds no step yet is no result: remove it. Stored steps are kept
        # (an interrupted run resumes from them).
        if not existed and not any(_initialized(out, f"ensemble_{e}") for e in range(ensembles)):
            out.unlink(missing_ok=True)
        raise
    summary = diagnose_chains(out, post.free, ensembles, n_steps=post.obs.n_steps, period=post.period)
    return summary


def _run_ensembles(out: Path, post, estimates, cov, walkers: int, steps: int, ensembles: int, seeds,
                   workers: int, scheduler: str | None, progress: bool, log=None) -> None:
    import time

    import emcee

    ndim = len(estimates)
    start, todo = time.perf_counter(), None  # steps this run has to take, over every ensemble
    taken = 0
    with worker_pool(workers, scheduler) as pool, _stop_between_steps() as stopped:
        for e in range(ensembles):
            backend = emcee.backends.HDFBackend(str(out), name=f"ensemble_{e}")
            rng = np.random.default_rng(seeds[e])
            done = backend.iteration if _initialized(out, f"ensemble_{e}") else 0
            if done:
                shape = tuple(int(v) for v in backend.shape)
                if shape != (walkers, ndim):
                    raise SampleError(
                        f"{out} holds ensemble {e} with (walkers, parameters) {shape}, "
                        f"not {(walkers, ndim)}: use another --out or the same --walkers"
                    )
            else:
                backend.reset(walkers, ndim)
            sampler = emcee.EnsembleSampler(walkers, ndim, post, pool=pool, backend=backend,
                                            blobs_dtype=_BLOBS, parameter_names=None)
            if done >= steps:
                continue
            if done:
                state = backend.get_last_sample()
            else:
                state = emcee.State(_initial_ball(estimates, cov, post.bounds, walkers, rng, post,
                                                  stopped),
                                    random_state=np.random.RandomState(
                                        rng.integers(2**32 - 1)).get_state())
            if todo is None:
                todo = steps - done + (ensembles - 1 - e) * steps
            every = max(1, steps // 10)
            for k, _ in enumerate(sampler.sample(state, iterations=steps - done, progress=progress),
                                  start=done + 1):
                if stopped():  # this step is stored; stop before the next
                    raise KeyboardInterrupt
                taken += 1
                if log is not None and (k % every == 0 or k == steps):
                    elapsed = time.perf_counter() - start
                    left = elapsed / taken * (todo - taken)
                    log(f"ensemble {e + 1} of {ensembles}: step {k} of {steps}, {_minutes(elapsed)} so "
                        f"far, about {_minutes(left)} left")


def _minutes(seconds: float) -> str:
    """A duration for a progress line: seconds under two minutes, else minutes."""
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


def _initialized(path: Path, name: str) -> bool:
    import h5py

    if not path.exists():
        return False
    try:
        with h5py.File(path, "r") as f:
            return name in f and f[name].attrs.get("iteration", 0) > 0
    except OSError:  # not (or no longer) a readable HDF5 file
        return False


#: What an ensemble's group of a chain file holds (emcee's HDFBackend layout).
_EMCEE_DATASETS = {"chain", "log_prob", "accepted"}
_EMCEE_ATTRS = {"nwalkers", "ndim", "iteration"}


def _check_chain_file(path: Path) -> bool:
    """Whether ``path`` exists, after checking that it is a chain file this module wrote (to be
    resumed); :class:`SampleError` otherwise, leaving the file as it is."""
    import re

    import h5py

    if not path.exists():
        return False
    where = "choose another --out, or move the file away to start afresh"
    if not path.is_file():
        raise SampleError(f"{path} is not a file: {where}")
    try:
        with h5py.File(path, "r") as f:
            foreign = sorted(k for k in f if not re.fullmatch(r"ensemble_\d+", k))
            if foreign:
                raise SampleError(f"{path} is an HDF5 file but not a chain file of `toywalk sample` "
                                  f"(it holds {foreign[0]!r}): {where}")
            for name in f:
                group = f[name]
                if not (isinstance(group, h5py.Group) and _EMCEE_ATTRS <= set(group.attrs)
                        and _EMCEE_DATASETS <= set(group)):
                    raise SampleError(f"{path}: {name} is not an emcee chain (a damaged chain "
                                      f"file?): {where}")
                iteration = int(group.attrs["iteration"])
                if not 0 <= iteration <= group["chain"].shape[0]:
                    raise SampleError(f"{path}: {name} says {iteration} steps but stores "
                                      f"{group['chain'].shape[0]} (a damaged chain file): {where}")
    except OSError as err:
        reason = (str(err).splitlines() or [type(err).__name__])[0]
        raise SampleError(f"{path} is not a readable HDF5 chain file ({reason}): {where}") from err
    return True


def diagnose_chains(path: str | Path, names, ensembles: int, n_steps: int = 0,
                    period: int = 1) -> SampleSummary:
    """Autocorrelation times, acceptance, R-hat and ESS (ArviZ), statuses and the stability
    posterior of a chain file's ensembles."""
    import emcee

    chains, logps, blobs, acceptance, taus = [], [], [], [], []
    for e in range(ensembles):
        backend = emcee.backends.HDFBackend(str(path), name=f"ensemble_{e}", read_only=True)
        chains.append(backend.get_chain())
        logps.append(backend.get_log_prob())
        blobs.append(backend.get_blobs())
        acceptance.append(float(np.mean(backend.accepted / max(backend.iteration, 1))))
        # A parameter that no walker ever moved (every proposal refused, as in a very short run)
        # has no autocorrelation time: emcee divides by its zero variance. Taken as infinite: the
        # chain is not long enough.
        with np.errstate(divide="ignore", invalid="ignore"):
            tau_e = emcee.autocorr.integrated_time(chains[-1], tol=0, quiet=True)
        taus.append(np.where(np.isfinite(tau_e), tau_e, np.inf))
    length = min(c.shape[0] for c in chains)
    tau = np.max(taus, axis=0)
    tau_max = float(np.max(tau))
    converged = bool(length > TAU_FACTOR * tau_max)
    burn = min(int(math.ceil(2 * tau_max)), length // 2) if math.isfinite(tau_max) else length // 2
    thin = max(1, int(tau_max // 2)) if math.isfinite(tau_max) else 1
    kept = [c[burn::thin].reshape(-1, c.shape[-1]) for c in chains]
    per_chain = min(len(k) for k in kept)
    stacked = np.stack([k[:per_chain] for k in kept])  # (ensembles, draws, parameters)
    statuses = np.concatenate([b["status"].ravel() for b in blobs])
    eig = np.concatenate([b["max_abs_eigenvalue"][burn::thin].ravel() for b in blobs])
    eig = eig[np.isfinite(eig)]
    data = {
        "length": int(length), "burn_in": burn, "thin": thin,
        # null (not JSON's non-standard Infinity) for a parameter no walker ever moved
        "autocorrelation_time": {n: _finite(t) for n, t in zip(names, tau, strict=True)},
        "long_enough": converged,
        "stop_rule": f"chain length > {TAU_FACTOR} integrated autocorrelation times",
        "acceptance_fraction": acceptance,
        "fraction_no_gait": float(np.mean(statuses == NO_GAIT)),
        "fraction_outside_prior": float(np.mean(statuses == OUTSIDE_PRIOR)),
        "mean": dict(zip(names, map(float, stacked.reshape(-1, len(names)).mean(axis=0)), strict=True)),
        "std": dict(zip(names, map(float, stacked.reshape(-1, len(names)).std(axis=0)), strict=True)),
        "quantiles_5_50_95": {n: np.percentile(stacked[..., i], [5, 50, 95]).tolist()
                              for i, n in enumerate(names)},
        "probability_stable": float(np.mean(eig < 1.0)) if len(eig) else None,
        "period": period,
        "growth_factor_over_observed_steps_median": (
            float(np.median(eig ** (n_steps / period))) if len(eig) and n_steps else None),
    }
    if ensembles >= 2 and per_chain >= 4:
        rhat, ess = _arviz_stats(stacked, names)
        data["rhat"], data["ess_bulk"] = rhat, ess
    else:
        data["rhat"] = data["ess_bulk"] = None
        data["rhat_note"] = "R-hat needs at least two ensembles with kept draws"
    return SampleSummary(names=list(names), ensembles=ensembles, walkers=chains[0].shape[1],
                         steps=int(length), data=data)


def _arviz_stats(stacked: np.ndarray, names) -> tuple[dict, dict]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # ArviZ 0.x announces its 1.0 refactor
        import arviz as az

        data = az.convert_to_inference_data({n: stacked[..., i] for i, n in enumerate(names)})
        rhat = az.rhat(data)
        ess = az.ess(data, method="bulk")
    return ({n: _finite(rhat[n]) for n in names}, {n: _finite(ess[n]) for n in names})


def _finite(value) -> float | None:
    """``value`` as a float, or None where it is not finite (a statistic of a chain that never
    moved): the summary file is strict JSON, which has no Infinity or NaN."""
    return strict_json(float(value))
