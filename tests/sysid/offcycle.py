"""A walk that starts off its cycle, for the default fit's tests and ``benchmarks/fit_speed.py``.

The stable toy (``data/params/stable-toy.toml``) with two quantities a builder measures least
well off the file's values (the walk's truth: foot radius 1.08 times, the balance masses'
sideways offset 0.95 times), released from its gait with its lean rate 0.002 rad/s off, filmed at
120 frames/s (a phone's slow motion: 12.8 samples a step) with 0.004 rad of white noise, and
fitted from the file's values with those two free. Its slowest eigenvalues (|lambda| = 0.965)
keep the release in view for the whole walk: the periodicity test rejects the periodic model
(p = 2e-52 at 20 steps, 9e-146 at 60). At 60 steps (30 strides, 769 samples) it is the walk on
which the default `toywalk fit` ran on, more than 15 minutes without a line on stderr, while its
Jacobian check re-solved the walk by IPOPT (docs/fitting.md, "A walk off its cycle, by
default").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from toywalk.model.gait import find_gait
from toywalk.model.parameters import Params, load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable, write_trajectory
from toywalk.model.walker import STATE_NAMES

__all__ = ["FREE", "KICK", "NOISE", "PARAMS", "RATE", "TRUTH_FACTORS", "offcycle_walk", "truth",
           "write_offcycle_walk"]

#: The walker's parameter file: the fit's start and fixed values.
PARAMS = Path(__file__).resolve().parents[2] / "data" / "params" / "stable-toy.toml"
#: The fitted parameters, and the walk's truth as factors of the file's values.
FREE = ["foot_radius", "com_offset[1]"]
TRUTH_FACTORS = {"foot_radius": 1.08, "com_offset[1]": 0.95}
#: The release: the lean rate (psi_dot) this much off the gait's, rad/s.
KICK = 0.002
#: Frames a second, and the angles' noise SD (rad).
RATE, NOISE = 120.0, 0.004


def truth(params: Params | None = None) -> Params:
    """The walk's walker: the file's with :data:`TRUTH_FACTORS` applied."""
    params = params or load_params(PARAMS)
    return params.replace(**{name: factor * params.get(name) for name, factor in TRUTH_FACTORS.items()})


def offcycle_walk(steps: int, *, seed: int = 1, sd_columns: bool = True) -> TrajectoryTable:
    """``steps`` steps of the walk as measured: the four angles with noise (and their ``*_sd``
    columns, as ``toywalk simulate --noise`` writes them, unless ``sd_columns`` is False), the heel
    strikes including the one the walk starts from."""
    walker = truth()
    z0 = find_gait(walker).fixed_point.copy()
    z0[STATE_NAMES.index("psi_dot")] += KICK
    traj = simulate(walker, z0, steps, sample_rate=RATE)
    if traj.status != "completed":
        raise RuntimeError(f"the off-cycle walk did not complete: {traj.message}")
    rng = np.random.default_rng(seed)
    signals = {k: v + rng.normal(0.0, NOISE, v.shape) for k, v in traj.angles().items()}
    if sd_columns:
        signals.update({f"{k}_sd": np.full(v.shape, NOISE) for k, v in list(signals.items())})
    events = [{"time": 0.0, "foot": "L"}] + [{"time": e.time, "foot": e.foot} for e in traj.events]
    return TrajectoryTable(traj.times, signals, traj.stance, events, {})


def write_offcycle_walk(path: str | Path, steps: int, **options) -> Path:
    """:func:`offcycle_walk` written as a trajectory file (its events file beside it); its path."""
    write_trajectory(offcycle_walk(steps, **options), path)
    return Path(path)
