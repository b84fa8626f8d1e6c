"""Forward simulation of many steps, in the physical (unmirrored) frame.

The step map works in a mirrored description in which the stance leg is always the left leg
(docs/model.md section 4). :func:`simulate` undoes the mirror: on steps where the right leg is in stance,
steer, lean and the lateral contact position change sign, and the pitches are assigned to the
physical legs. Samples are taken on a uniform time grid by cubic Hermite interpolation of the
integration grid (states and their exact derivatives at the nodes; the interpolation error is
O(dt^4), far below any measurement noise), and each heel strike is an exact event.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from tqdm.auto import tqdm

from .compliant import phase_path
from .effects import CONTINUOUS
from .parameters import Params
from .walker import StepFailure, Walker

__all__ = ["HeelStrike", "Trajectory", "gait_walk", "simulate"]


@dataclasses.dataclass(frozen=True)
class HeelStrike:
    """One heel strike: time (s), the landing foot ('L' or 'R'), contact position (m, ramp frame)."""

    time: float
    foot: str
    x: float
    y: float


@dataclasses.dataclass
class Trajectory:
    """A simulated walk, sampled uniformly.

    Attributes
    ----------
    times : ndarray, shape (n,)
        (s)
    states : ndarray, shape (n, 8)
        Physical (unmirrored) state in the public order, with theta_st/theta_sw the pitches of the
        leg in stance / in swing at that sample.
    stance : ndarray of str, shape (n,)
        'L' or 'R'.
    contact : ndarray, shape (n, 2)
        Stance contact point on the ramp (m).
    events : list of HeelStrike
    scuffs : int
        Swing-foot touches of the ramp while the legs passed (ignored by the model, counted).
    min_clearance : float
        Smallest swing-foot height between the legs passing and heel strike, over all steps (m).
    swing_clearance : float
        Smallest clearance of the swing foot over its whole swing, over all steps (m;
        :class:`~toywalk.model.walker.SwingClearance`): negative when it went below the ramp
        between heel strikes.
    status : str
        ``"completed"``, ``"fell"``, ``"no_heel_strike"`` or ``"inadmissible_impact"``.
    message : str
    collision_losses : ndarray, shape (n_steps,)
        Kinetic energy lost at each heel strike (J).
    dissipated : dict of str to float
        Energy dissipated between collisions by each continuous effect over the walk (J).
    """

    times: np.ndarray
    states: np.ndarray
    stance: np.ndarray
    contact: np.ndarray
    events: list[HeelStrike]
    scuffs: int
    min_clearance: float
    status: str
    message: str
    collision_losses: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    dissipated: dict = dataclasses.field(default_factory=dict)
    swing_clearance: float = np.inf

    @property
    def lean(self) -> np.ndarray:
        return self.states[:, 2]

    @property
    def steer(self) -> np.ndarray:
        return self.states[:, 0]

    def pitches(self) -> tuple[np.ndarray, np.ndarray]:
        """(pitch_left, pitch_right) (rad), shape (n,) each."""
        left = np.where(self.stance == "L", self.states[:, 4], self.states[:, 6])
        right = np.where(self.stance == "R", self.states[:, 4], self.states[:, 6])
        return left, right

    def angles(self) -> dict[str, np.ndarray]:
        """The four angles a trajectory file holds, by their column names (``lean``, ``steer``,
        ``pitch_left``, ``pitch_right``; rad, shape (n,) each)."""
        left, right = self.pitches()
        return {"lean": self.lean, "steer": self.steer, "pitch_left": left, "pitch_right": right}


def simulate(params: Params, z0: np.ndarray, steps: int, sample_rate: float | None = None,
             planar: bool = False, first_stance: str = "L", progress: bool = False,
             steps_per_time_unit: int = 16) -> Trajectory:
    """Simulate ``steps`` steps from ``z0`` (public state just after a heel strike).

    Parameters
    ----------
    params : Params
    z0 : ndarray, shape (8,)
        Physical state just after a heel strike with ``first_stance`` in stance.
    steps : int
        Number of steps (heel strikes) to simulate.
    sample_rate : float, optional
        Output samples per second; default 20 per sqrt(l/g).
    planar : bool
        Use the planar reduction.
    first_stance : {'L', 'R'}
    progress : bool
        Show a progress bar.

    Returns
    -------
    Trajectory
        Stops early, with ``status`` saying why, if the walker falls.
    """
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    if first_stance not in ("L", "R"):
        raise ValueError(f"first_stance must be 'L' or 'R', got {first_stance!r}")
    walker = Walker(params, planar=planar, steps_per_time_unit=steps_per_time_unit)
    rate = sample_rate if sample_rate is not None else 20.0 / params.time_scale
    if not rate > 0:
        raise ValueError(f"sample_rate must be > 0, got {sample_rate!r}")
    sample_dt = 1.0 / rate
    sign = 1.0 if first_stance == "L" else -1.0
    z = _mirror(np.asarray(z0, dtype=float), sign)  # the mirrored (internal) description
    t0, origin = 0.0, np.zeros(2)
    chunks_t, chunks_x, chunks_s, chunks_c = [], [], [], []
    events: list[HeelStrike] = []
    scuffs, clearance, status, message = 0, np.inf, "completed", f"{steps} steps"
    swing_clearance = np.inf
    next_sample = 0.0
    losses: list[float] = []
    dissipated = np.zeros(len(CONTINUOUS))
    for k in tqdm(range(steps), disable=not progress, desc="steps", unit="step"):
        stance = "L" if sign > 0 else "R"
        side = 1 if sign > 0 else -1
        try:
            step = walker.step(z, record=True, side=side)
            times, states = step.times, step.states
        except StepFailure as err:
            status, message = err.status, f"step {k + 1}: {err}"
            if err.trajectory is not None:
                times, states = err.trajectory
            else:
                break
            step = None
        sample_times = np.arange(next_sample, t0 + times[-1] + 1e-15, sample_dt)
        if len(times) >= 2 and len(sample_times):
            local = sample_times - t0
            derivs = np.array([walker.rhs(x, side) for x in states])
            spline = CubicHermiteSpline(times, states, derivs, axis=0)
            xs = spline(np.clip(local, 0.0, times[-1]))
            pub = np.array([_mirror(walker.to_public(x), sign) for x in xs])
            travel = xs[:, walker.lay.n_dyn:]
            contact = np.zeros((len(xs), 2))
            contact[:, 0] = origin[0] + travel[:, 0]
            if travel.shape[1] > 1:
                contact[:, 1] = origin[1] + sign * travel[:, 1]
            else:
                contact[:, 1] = origin[1]
            chunks_t.append(sample_times)
            chunks_x.append(pub)
            chunks_s.append(np.full(len(xs), stance))
            chunks_c.append(contact)
            next_sample = sample_times[-1] + sample_dt
        if step is None:
            break
        scuffs += step.scuffs
        clearance = min(clearance, step.clearance)
        swing_clearance = min(swing_clearance, step.swing.minimum)
        losses.append(step.collision_loss)
        dissipated += step.dissipated[-1]
        # The heel strike is the landing foot's touchdown: with a compliant strike
        # (effects.soft_heel) its phase follows it, and the samples inside the phase take the
        # walker's angles and rates through it (toywalk.model.compliant.phase_path), the landing
        # foot their stance (its pitch the stance pitch) as the heel strike's event says.
        touchdown = t0 + (step.step_time - step.strike_phase)
        origin = origin + np.array([step.contact[0], sign * step.contact[1]])
        landing = "R" if stance == "L" else "L"
        if step.strike_phase > 0:
            inside = np.arange(next_sample, t0 + step.step_time - 1e-12, sample_dt)
            if len(inside):
                path_t, path_x = phase_path(params, walker.full_state(step.z_minus), planar, side)
                xs = np.column_stack([np.interp(inside - touchdown, path_t, col) for col in path_x.T])
                chunks_t.append(inside)
                pub = np.array([_mirror(walker.to_public(x), sign) for x in xs])
                chunks_x.append(pub[:, [0, 1, 2, 3, 6, 7, 4, 5]])  # the landing leg's pitch first
                chunks_s.append(np.full(len(inside), landing))
                chunks_c.append(np.tile(origin, (len(inside), 1)))
                next_sample = inside[-1] + sample_dt
        t0 += step.step_time
        events.append(HeelStrike(time=touchdown, foot=landing, x=float(origin[0]), y=float(origin[1])))
        sign = -sign
        z = step.z_plus
    if chunks_t:
        times_all = np.concatenate(chunks_t)
        states_all = np.concatenate(chunks_x)
        stance_all = np.concatenate(chunks_s)
        contact_all = np.concatenate(chunks_c)
    else:
        times_all, states_all = np.zeros(0), np.zeros((0, 8))
        stance_all, contact_all = np.zeros(0, dtype="<U1"), np.zeros((0, 2))
    return Trajectory(times=times_all, states=states_all, stance=stance_all, contact=contact_all,
                      events=events, scuffs=scuffs, min_clearance=float(clearance), status=status,
                      message=message, collision_losses=np.array(losses),
                      dissipated=dict(zip(CONTINUOUS, dissipated.tolist(), strict=True)),
                      swing_clearance=float(swing_clearance))


def _mirror(z: np.ndarray, sign: float) -> np.ndarray:
    """Reflect y -> -y when ``sign`` is -1: steer and lean (and their rates) change sign."""
    out = z.copy()
    out[:4] *= sign
    return out


def gait_walk(params: Params, steps: int, *, noise: float = 0.0, position_noise: float = 0.0, seed=None,
              source: str = "", progress: bool = False, z_guess=None):
    """The walker's gait walked ``steps`` steps from its fixed point
    (:func:`toywalk.model.gait.find_gait`) as a trajectory file holds it (``toywalk simulate``):
    a :class:`toywalk.model.trajectory.TrajectoryTable` with the contacts, the heel strikes (the
    first at the start is not one of them) and the metadata (the parameters, ``source`` naming
    their file, the seed, scuffs, clearance).

    ``noise`` (rad) adds white noise of that SD to the angles and ``*_sd`` columns saying so;
    ``position_noise`` (m) does so to the strikes' contact positions, as a tracker would measure
    them; both drawn from ``seed``. ``z_guess`` is a start near the gait (a nearby walker's fixed
    point), else the gait search's own. Raises :class:`toywalk.model.gait.GaitNotFound` where the
    walker has no gait.
    """
    import math

    from .files import software_version
    from .gait import find_gait
    from .parameters import PARAMETER_NAMES
    from .trajectory import TrajectoryTable

    gait = find_gait(params, z_guess=z_guess)
    traj = simulate(params, gait.fixed_point, steps, planar=gait.planar, progress=progress)
    rng = np.random.default_rng(seed)
    signals = traj.angles()
    if noise > 0:
        signals = {k: v + rng.normal(0.0, noise, size=v.shape) for k, v in signals.items()}
        signals.update({f"{k}_sd": np.full(v.shape, noise) for k, v in list(signals.items())})
    signals["contact_x"] = traj.contact[:, 0]
    signals["contact_y"] = traj.contact[:, 1]
    metadata = {
        "source": {"kind": "simulation", "parameters": source,
                   "parameter_values": dict(zip(PARAMETER_NAMES, params.vector().tolist(), strict=True)),
                   "effects": dict(params.effects), "seed": seed, "steps": steps,
                   "start": "gait fixed point", "planar": gait.planar},
        "units": {"time": "s", "angles": "rad", "contact": "m"},
        "noise_sd": noise,
        "position_noise_sd": position_noise,
        "timestamps": "exact simulation times, uniform sampling",
        "status": traj.status, "message": traj.message,
        "scuffs": traj.scuffs, "min_clearance_m": traj.min_clearance,
        "swing_clearance_m": traj.swing_clearance if math.isfinite(traj.swing_clearance) else None,
        "software": software_version(),
    }
    events = [{"time": e.time, "foot": e.foot, "x": e.x, "y": e.y} for e in traj.events]
    if position_noise > 0:  # heel-strike positions as a tracker would measure them
        for event in events:
            event["x"] += rng.normal(0.0, position_noise)
            event["y"] += rng.normal(0.0, position_noise)
            event["x_sd"] = event["y_sd"] = position_noise
    return TrajectoryTable(traj.times, signals, traj.stance, events, metadata)

