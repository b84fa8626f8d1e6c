"""Inputs built for the sysid tests: simulated measured walks of a known truth, and synthetic
observations with made-up signals whose truth is known.

``simulated_walk`` is what most analyses in these tests start from (a walk of the model with noise on its
angles, as `toywalk simulate --noise` writes it); ``RECOVERED`` and ``start_off`` are the
recovery tests' free parameters and start; ``grid_observations`` and ``walk_signals`` build
observations without the model, for the residual and noise diagnostics.
"""

import numpy as np
from toywalk.model.gait import find_gait
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.measurement import Observations

__all__ = ["RECOVERED", "grid_observations", "simulated_walk", "start_off", "walk_signals"]


def simulated_walk(params, steps, noise, seed, gait=None, steps_per_time_unit=16, z0=None):
    """A simulated walk from the gait (or from ``z0``), as a measured trajectory (angles with
    noise, heel strikes including the one the walk starts from, except on soft feet), like
    `toywalk simulate --noise`.

    Parameters
    ----------
    params : Params
        The walker that walks.
    steps : int
        Heel strikes simulated.
    noise : float
        SD (rad) of the white noise added to every angle.
    seed : int
        Seed of the noise.
    gait : Gait, optional
        ``params``' gait, if already found (else :func:`find_gait` finds it).
    steps_per_time_unit : int
        The integration grid (model/simulate.py).
    z0 : array_like, optional
        A start other than the gait's fixed point (public state order).

    Returns
    -------
    (TrajectoryTable, Gait)
        The measured walk and the gait.
    """
    gait = gait or find_gait(params)
    z0 = gait.fixed_point if z0 is None else z0
    traj = simulate(params, z0, steps, steps_per_time_unit=steps_per_time_unit)
    rng = np.random.default_rng(seed)
    signals = {k: v + rng.normal(0.0, noise, v.shape) for k, v in traj.angles().items()}
    # The start is just after a heel strike: on soft feet (effects.soft_heel) the strike's phase
    # came before it, so the walk is read from its first touchdown, as `toywalk simulate` does.
    first = [] if params.effects.get("soft_heel", 0.0) else [{"time": 0.0, "foot": "L"}]
    events = first + [{"time": e.time, "foot": e.foot} for e in traj.events]
    return TrajectoryTable(traj.times, signals, traj.stance, events, {}), gait


#: The parameters the recovery tests fit: foot radius, lateral mass offset and an impact parameter.
RECOVERED = ["foot_radius", "com_offset[1]", "effects.impact_trailing_share"]


def start_off(truth):
    """The recovery tests' start: foot radius 10 % and lateral offset 3 % off, trailing share
    halfway to zero."""
    return truth.replace(**{"foot_radius": 1.1 * truth.foot_radius,
                            "com_offset[1]": 0.97 * truth.com_offset[1],
                            "effects.impact_trailing_share": 0.05})


def grid_observations(n_steps=16, per_step=40, rng=None):
    """Observations of ``n_steps`` steps of 0.1 s, ``per_step`` samples a signal a step, values 0."""
    rng = np.random.default_rng(rng)
    start = np.arange(n_steps) * 0.1
    rows = {k: [] for k in ("step", "phase", "signal", "time")}
    for k in range(n_steps):
        phase = (np.arange(per_step) + 0.5) / per_step
        for s in range(4):
            rows["step"].append(np.full(per_step, k))
            rows["phase"].append(phase)
            rows["signal"].append(np.full(per_step, s))
            rows["time"].append(start[k] + 0.1 * phase)
    data = {k: np.concatenate(v) for k, v in rows.items()}
    n = len(data["step"])
    return Observations(step_start=start, step_end=start + 0.1,
                        stance=np.array(["L", "R"] * (n_steps // 2)), duration_sd=np.full(n_steps, 1e-4),
                        step=data["step"], phase=data["phase"], signal=data["signal"],
                        value=np.zeros(n), sd=np.full(n, np.nan), time=data["time"],
                        strike_sd=np.full(n_steps + 1, 1e-4))


def walk_signals(obs, noise):
    """Smooth angles a walker might show (0.05-0.3 rad at 1.25-2.5 Hz, jumping at every step's
    start as a heel strike's rates do) plus ``noise`` (one value per observation)."""
    k, t = obs.step, obs.time
    w = 2 * np.pi * np.array([1.25, 1.25, 2.5, 2.5])[obs.signal]
    amp = np.array([0.05, 0.1, 0.3, 0.3])[obs.signal]
    return amp * np.sin(w * t + k) + 0.5 * (t - obs.step_start[k]) * (-1.0) ** k + noise
