"""The measurement model: what a model gait or walk predicts for each measured sample.

A measured walk (a trajectory file, docs/formats.md) is cut into steps at its heel strikes. Within a
step, a sample's measured **phase** is ``(t - t_strike) / (t_next_strike - t_strike)`` in [0, 1).
The step's stance leg is the foot that landed at its first strike. :func:`operator` reads the
model at the measured phases (each step aligned on its measured strikes, taken as exact);
:class:`Timing` reads it between the model's own strikes (below), which is what the fit does.

The model describes a step in the mirrored description of docs/model.md section 4 (the stance leg as
the left one). A step with the physical right leg in stance is mirrored back: lean and steer
change sign. The stance leg's pitch is ``theta_st`` and the swing leg's ``theta_sw``. A
step-periodic gait (one model step) serves every measured step; a stride-periodic one (effects that
break the mirror symmetry) has two model steps, the first with the left leg in stance. A transient
model (a walk from a free start, the recorded steps one after the other: ``bvp(...,
periodic=False)``) has one model step per measured step.

Model values at a phase come from the collocation polynomials of the gait BVP
(:class:`toywalk.model.collocation.BVP`): each is a fixed linear combination of the BVP's
unknowns (Lagrange weights in the mesh interval holding that phase), so the whole operator is one
sparse matrix, built once per walk.

The heel strikes are measurements too (a tracker finds them to a fraction of a frame, with a
``time_sd``), not the model's clock: a strike-time error of 0.3 ms shifts a whole step's angles
by up to 2.5 mrad where the legs swing at 8.5 rad/s, more than a tracker's noise (measured through
rendered video: the fit aligned on the tracker's strikes was biased by 4 to 12 SE). So the fit
predicts the strike times from the model, ``tau_k = t_0 + time_offset + (sum of the model's step
durations before step k)``, compares them with the measured ones (residuals ``(tau_k - t_k) /
time_sd_k``), and reads each sample at its phase between the *model's* strikes,
``(t - tau_k) / T_k`` (:class:`Timing`: a sample's mesh interval is fixed by its measured phase,
the Lagrange weights within it follow the unknowns). The one new unknown is ``time_offset``, the
model's first strike against the measured one.

Nuisance parameters: an orientation error of the ramp frame (the camera's pose of the ramp) shows,
to first order, as constant offsets of lean (roll), steer (yaw) and both pitches (pitch); they
enter as three offsets.

Stride length: where the events file gives the contact position of heel strikes (``x, y``, with
``x_sd, y_sd`` where measured), each step's advance is data too. The model's contacts follow from
each step's displacement (:class:`Path`); the measured positions' unknown origin (two nuisances,
:data:`POSITION_NUISANCES`) and the ramp frame's yaw (the steer offset) enter linearly.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp
from toywalk.model.collocation import BVP
from toywalk.model.trajectory import SIGNALS, TrajectoryTable

__all__ = ["OFFSETS", "POSITION_NUISANCES", "MeasurementError", "Observations", "Path", "Timing",
           "complete_steps", "components", "first_side", "lagrange_weights", "model_steps", "observations",
           "offsets_design", "operator", "path", "shutter_reads", "step_counts", "timing"]

#: Nuisance offsets (rad), one per group of signals: lean, steer, and both pitches.
OFFSETS = ("lean_offset", "steer_offset", "pitch_offset")
_OFFSET_OF = {"lean": 0, "steer": 1, "pitch_left": 2, "pitch_right": 2}
#: Nuisance unknowns of measured contact positions (m): where the first measured contact lies.
POSITION_NUISANCES = ("origin_x", "origin_y")


#: A step (strike to strike) lasting this many times the walk's median step holds missed strikes:
#: two missed in a row leave an interval of about three steps with the feet still alternating (one
#: missed leaves the same foot twice in a row). A walk's steps vary far less, even off its cycle:
#: the stable toy released with 1.3 and 2 times its lean rate (tests/sysid/test_transient.py)
#: steps 0.80-1.09 times its median step over 12 steps.
MISSED_STEP_RATIO = 2.0


class MeasurementError(ValueError):
    """The measurements cannot be fitted as given; the message says why."""


@dataclasses.dataclass
class Observations:
    """A measured walk arranged for fitting.

    Attributes
    ----------
    step_start, step_end : ndarray, shape (n_steps,)
        Heel-strike times that begin and end each complete measured step (s).
    stance : ndarray of str, shape (n_steps,)
        'L' or 'R', the physical leg in stance.
    duration_sd : ndarray, shape (n_steps,)
        Standard deviation of each measured step duration (s).
    step : ndarray of int, shape (n_obs,)
        The measured step each observation belongs to.
    phase : ndarray, shape (n_obs,)
        Phase within its step, in [0, 1).
    signal : ndarray of int, shape (n_obs,)
        Index into :data:`toywalk.model.trajectory.SIGNALS`.
    value, sd : ndarray, shape (n_obs,)
        Measured angle (rad) and its standard deviation (rad; NaN where the file gives none).
    time : ndarray, shape (n_obs,)
        Sample time (s).
    strike_sd : ndarray, shape (n_steps + 1,)
        Standard deviation of each measured heel-strike time (s).
    contact, contact_sd : ndarray, shape (n_steps + 1, 2)
        Each heel strike's contact position on the ramp (m, ramp frame: down the fall line, to
        the left) and its standard deviation (m); NaN where the file gives none.
    note : str or None
        What was set aside, and why, where heel strikes are missing (:func:`complete_steps`).
    strike_sd_measured : bool
        Whether the events file gave every strike's ``time_sd`` (else :attr:`strike_sd` is the
        sampling's, one sample interval over sqrt(12)).
    exposure : float
        How long the camera's shutter was open for each sample, centred on its time (s; the
        metadata's ``exposure_s``, 0 for instantaneous samples): each sample is then the
        angles' mean over it (:func:`shutter_reads`).
    phase_sd : ndarray, shape (n_obs,)
        SD of an error the sample shares with every step's sample at the same phase (rad; the
        ``*_phase_sd`` columns: what a tracker's calibrated bias by phase leaves uncertain,
        tracking/accuracy_phase.py); 0 where the file gives none.
    """

    step_start: np.ndarray
    step_end: np.ndarray
    stance: np.ndarray
    duration_sd: np.ndarray
    step: np.ndarray
    phase: np.ndarray
    signal: np.ndarray
    value: np.ndarray
    sd: np.ndarray
    time: np.ndarray
    strike_sd: np.ndarray
    contact: np.ndarray = None
    contact_sd: np.ndarray = None
    note: str | None = None
    strike_sd_measured: bool = False
    exposure: float = 0.0
    phase_sd: np.ndarray = None

    def __post_init__(self):
        self.phase_sd = np.zeros(self.value.shape) if self.phase_sd is None else self.phase_sd
        unknown = np.full((len(self.strike_sd), 2), np.nan)
        self.contact = unknown if self.contact is None else self.contact
        self.contact_sd = unknown.copy() if self.contact_sd is None else self.contact_sd

    @property
    def durations(self) -> np.ndarray:
        return self.step_end - self.step_start

    @property
    def strikes(self) -> np.ndarray:
        """The measured heel-strike times that bound the complete steps (s), shape (n_steps + 1,)."""
        return np.r_[self.step_start, self.step_end[-1:]]

    @property
    def n_steps(self) -> int:
        return len(self.step_start)

    @property
    def sd_known(self) -> bool:
        """True when every observation has a standard deviation from the file."""
        return bool(np.all(np.isfinite(self.sd)))

    @property
    def located(self) -> np.ndarray:
        """Indices of the heel strikes (into :attr:`strikes`) with a measured contact position."""
        return np.flatnonzero(np.all(np.isfinite(self.contact), axis=1))

    @property
    def contact_sd_known(self) -> bool:
        """True when every measured contact position has its standard deviations from the file."""
        return bool(np.all(np.isfinite(self.contact_sd[self.located])))


def complete_steps(times, feet) -> tuple[int, int, list[str]]:
    """The longest run of consecutive heel strikes each pair of which bounds one step, where
    strikes are missing (a tracker loses one to blur or an occluder).

    Between two strikes by the same foot, or two more than :data:`MISSED_STEP_RATIO` median steps
    apart, a strike is missing: that interval is not a step, and a walk read across it would
    compare several steps with one model step. The measurement model's steps follow one another
    (the transient model's are one walk), so the longest run of single steps is kept.

    Parameters
    ----------
    times : array_like, shape (n,)
        Heel-strike times (s), increasing.
    feet : sequence of str, shape (n,)
        'L' or 'R'.

    Returns
    -------
    first, last : int
        The run's first and last strike (indices into ``times``).
    gaps : list of str
        Each interval that is not a step, described (empty when every one is).
    """
    times = np.asarray(times, float)
    steps = np.diff(times)
    alternate = np.array([a != b for a, b in zip(feet[:-1], feet[1:], strict=True)])
    typical = float(np.median(steps[alternate])) if alternate.any() else float(np.median(steps))
    gaps, good = [], np.ones(len(steps), bool)
    for k, (dt, alt) in enumerate(zip(steps, alternate, strict=True)):
        if not alt:
            gaps.append(f"{feet[k]} at {times[k]:.4g} s and again at {times[k + 1]:.4g} s")
        elif dt > MISSED_STEP_RATIO * typical:
            gaps.append(f"{times[k]:.4g} to {times[k + 1]:.4g} s, {dt / typical:.1f} median steps")
        else:
            continue
        good[k] = False
    best, first, start = 0, 0, 0
    for k in range(len(steps) + 1):
        if k == len(steps) or not good[k]:
            if k - start > best:
                best, first = k - start, start
            start = k + 1
    return first, first + best, gaps


def observations(table: TrajectoryTable, signals=SIGNALS) -> Observations:
    """Arrange a measured trajectory for fitting (complete steps between heel strikes only).

    Where heel strikes are missing, the longest run of complete steps (:func:`complete_steps`);
    :attr:`Observations.note` says what was set aside.

    Raises
    ------
    MeasurementError
        Fewer than two complete steps (in a row), heel strikes out of order, or no usable samples.
    """
    events = sorted(table.events, key=lambda e: e["time"])
    times = np.array([e["time"] for e in events], dtype=float)
    if len(events) < 3:
        raise MeasurementError(
            f"the walk has {len(events)} heel strike(s): fitting needs at least 3 (two complete steps)"
        )
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise MeasurementError("heel-strike times must be finite and increasing")
    feet = [e["foot"] for e in events]
    if any(f not in ("L", "R") for f in feet):
        raise MeasurementError("every heel strike needs its foot, 'L' or 'R'")
    first, last, gaps = complete_steps(times, feet)
    note = None
    if gaps:
        missing = "; ".join(gaps)
        if last - first < 2:
            raise MeasurementError(f"heel strikes are missing ({missing}): no two complete steps in a row "
                                   f"to fit")
        aside = len(times) - 1 - (last - first)
        note = (f"heel strikes are missing ({missing}): the {last - first} complete steps from "
                f"{times[first]:.4g} to {times[last]:.4g} s are used, the other {aside} intervals set aside")
        events, times, feet = events[first:last + 1], times[first:last + 1], feet[first:last + 1]
    sd_t = np.array([e.get("time_sd", math.nan) for e in events], dtype=float)
    measured = bool(np.all(np.isfinite(sd_t)))
    dt = float(np.median(np.diff(table.time))) if len(table.time) > 1 else 0.0
    if not measured:
        # Strike times known only to the sampling: each uniform within one sample interval.
        sd_t = np.full(len(events), dt / math.sqrt(12.0))
    sd_t = np.maximum(sd_t, 1e-9 * max(dt, 1e-3))
    exposure = table.metadata.get("exposure_s", 0.0)
    if isinstance(exposure, bool) or not isinstance(exposure, (int, float)) or not 0 <= exposure <= dt:
        raise MeasurementError(f"exposure_s (the metadata's shutter time) must be a number of seconds "
                               f"from 0 to the sample interval {dt:.4g} s, got {exposure!r}")
    start, end = times[:-1], times[1:]
    stance = np.array(feet[:-1])
    rows = {k: [] for k in ("step", "phase", "signal", "value", "sd", "time", "phase_sd")}
    index = np.searchsorted(times, table.time, side="right") - 1
    for s_i, name in enumerate(SIGNALS):
        if name not in signals:
            continue
        values = table.signals[name]
        sds = table.signals.get(f"{name}_sd", np.full(len(values), np.nan))
        if np.any(np.isinf(values)):
            raise MeasurementError(f"column {name} holds infinite values (missing samples are empty)")
        ok = (index >= 0) & (index < len(start)) & np.isfinite(values)
        k = index[ok]
        rows["step"].append(k)
        rows["phase"].append((table.time[ok] - start[k]) / (end[k] - start[k]))
        rows["signal"].append(np.full(len(k), s_i))
        rows["value"].append(values[ok])
        rows["sd"].append(sds[ok])
        rows["time"].append(table.time[ok])
        shared = table.signals.get(f"{name}_phase_sd", np.zeros(len(values)))
        rows["phase_sd"].append(np.nan_to_num(shared[ok], nan=0.0))
    data = {k: np.concatenate(v) for k, v in rows.items()}
    if len(data["value"]) == 0:
        raise MeasurementError("no measured sample lies within a complete step")
    bad_sd = np.isfinite(data["sd"]) & (data["sd"] <= 0)
    if np.any(bad_sd):
        raise MeasurementError("standard deviations (*_sd columns) must be positive")
    contact = np.array([[e.get(c, math.nan) for c in ("x", "y")] for e in events], dtype=float)
    contact_sd = np.array([[e.get(c, math.nan) for c in ("x_sd", "y_sd")] for e in events], dtype=float)
    if np.any(np.isinf(contact)) or np.any(np.isinf(contact_sd)):
        raise MeasurementError("heel-strike positions (x, y, x_sd, y_sd) must be finite or empty")
    if np.any(contact_sd <= 0):
        raise MeasurementError("heel-strike position standard deviations (x_sd, y_sd) must be positive")
    return Observations(step_start=start, step_end=end, stance=stance,
                        duration_sd=np.hypot(sd_t[:-1], sd_t[1:]), step=data["step"].astype(int),
                        phase=np.clip(data["phase"], 0.0, 1.0), signal=data["signal"].astype(int),
                        value=data["value"], sd=data["sd"], time=data["time"], strike_sd=sd_t,
                        contact=contact, contact_sd=contact_sd, note=note, strike_sd_measured=measured,
                        exposure=float(exposure), phase_sd=data["phase_sd"])


#: Simpson's rule over the open shutter (or each part of it on either side of a heel strike):
#: reads at the part's start, middle and end, weighted 1/6, 4/6, 1/6 of the part's share.
_SIMPSON = ((0.0, 1.0 / 6.0), (0.5, 4.0 / 6.0), (1.0, 1.0 / 6.0))


def shutter_reads(obs: Observations) -> tuple[Observations, sp.csr_matrix | None]:
    """Where to read the model for samples taken with the shutter open (:attr:`Observations.exposure`).

    A camera's frame is the scene averaged over its exposure, so a sample is the mean of the
    angles over ``[t - e/2, t + e/2]``, not their value at ``t``: by ``e^2 f''(t) / 24``, which for
    a leg swinging through a step in 6.4 frames at 60 frames/s, shutter 0.4 of a frame, is up to
    0.14 degree and the same at every step, so a fit reads it as physics (measured: the base model
    of a rendered stable-toy walk with rolling resistance 2e-4 fitted as 2.15e-4 +- 0.024e-4 from
    the shutter-averaged true angles, 2.03e-4 from the angles at t). The mean is taken by
    Simpson's rule, three reads of the model, each a virtual observation at its own time; a
    shutter open across a measured heel strike is split there (the angles' rates jump, which
    one Simpson's rule over the kink would miss by up to 1e-3 rad), each part read in its own
    step, with that step's stance leg. The shutter is clipped to the walk's first and last
    strikes.

    Returns
    -------
    reads : Observations
        ``obs`` itself where the exposure is 0; else the reads (three per sample, six where a
        strike splits its shutter; ``value`` and ``sd`` those of the sample each reads for).
    average : scipy.sparse.csr_matrix, shape (n_obs, n_reads), or None
        The model's samples from its values at the reads (None: the reads are the samples).
    """
    if obs.exposure <= 0:
        return obs, None
    strikes = obs.strikes
    lo = np.clip(obs.time - 0.5 * obs.exposure, strikes[0], strikes[-1])
    hi = np.clip(obs.time + 0.5 * obs.exposure, strikes[0], strikes[-1])
    first = np.clip(np.searchsorted(strikes, lo, side="right") - 1, 0, obs.n_steps - 1)
    last = np.clip(np.searchsorted(strikes, hi, side="left") - 1, 0, obs.n_steps - 1)
    cut = np.where(last > first, strikes[np.minimum(first + 1, obs.n_steps)], hi)
    width = np.maximum(hi - lo, 1e-300)
    # the parts: (sample, step, start, end), the second empty where no strike splits the shutter
    split = np.flatnonzero(last > first)
    sample = np.r_[np.arange(len(lo)), split]
    step = np.r_[first, last[split]]
    a, b = np.r_[lo, cut[split]], np.r_[cut, hi[split]]
    times = np.concatenate([a + f * (b - a) for f, _ in _SIMPSON])
    steps = np.tile(step, len(_SIMPSON))
    rows = np.tile(sample, len(_SIMPSON))
    weights = np.concatenate([w * (b - a) / width[sample] for _, w in _SIMPSON])
    phase = np.clip((times - obs.step_start[steps]) / obs.durations[steps], 0.0, 1.0)
    average = sp.csr_matrix((weights, (rows, np.arange(len(rows)))), shape=(len(lo), len(rows)))
    reads = dataclasses.replace(obs, step=steps, phase=phase, time=times, signal=obs.signal[rows],
                                value=obs.value[rows], sd=obs.sd[rows], exposure=0.0,
                                phase_sd=obs.phase_sd[rows])
    return reads, average


def lagrange_weights(points, s) -> list:
    """Lagrange basis polynomials through ``points`` evaluated at ``s`` (a number, a NumPy array or
    a CasADi expression: arithmetic only), one per point."""
    out = []
    for r, pr in enumerate(points):
        weight = 1.0
        for q, pq in enumerate(points):
            if q != r:
                weight = weight * ((s - pq) / (pr - pq))
        out.append(weight)
    return out


def model_steps(obs: Observations, phases: int, periodic: bool = True) -> np.ndarray:
    """The model step (phase of the period) each measured step is compared with, shape (n_steps,):
    always 0 for a step-periodic gait; 0 for the left leg's steps and 1 for the right leg's in a
    stride-periodic one; the measured step's own index in a transient model."""
    if not periodic:
        if phases != obs.n_steps:
            raise MeasurementError(f"a transient model of {phases} steps for a walk of {obs.n_steps}")
        return np.arange(obs.n_steps)
    return np.zeros(obs.n_steps, dtype=int) if phases == 1 else np.where(obs.stance == "L", 0, 1)


def first_side(obs: Observations) -> int:
    """The side input of the first measured step: +1 with the left leg in stance, -1 the right."""
    return 1 if obs.stance[0] == "L" else -1


def components(obs: Observations, phases: int, planar: bool,
               periodic: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which model quantity each observation measures.

    Returns ``(model_step, component, sign)``, each shape (n_obs,): the model step (phase of the
    period) of the observation's measured step, the internal state component it reads ((phi, psi,
    theta_st, theta_sw) in 3D, (theta_st, theta_sw) planar; -1 where the model predicts zero, as
    for lean and steer in the planar reduction) and its sign (-1 for the lean and steer of a step
    with the right leg in stance, mirrored back).
    """
    step_of = model_steps(obs, phases, periodic)
    side = np.where(obs.stance == "L", 1.0, -1.0)
    comp = {"steer": 0, "lean": 1, "st": 2, "sw": 3} if not planar else {"st": 0, "sw": 1}
    n_obs = len(obs.value)
    component, sign = np.full(n_obs, -1), np.ones(n_obs)
    for i in range(n_obs):
        k = obs.step[i]
        name = SIGNALS[obs.signal[i]]
        if name in ("lean", "steer"):
            if not planar:
                component[i], sign[i] = comp[name], side[k]
        else:
            own = "L" if name == "pitch_left" else "R"
            component[i] = comp["st" if obs.stance[k] == own else "sw"]
    return step_of[obs.step], component, sign


def offsets_design(obs: Observations) -> np.ndarray:
    """The nuisance offsets' design, shape (n_obs, 3): one column per :data:`OFFSETS` group."""
    b = np.zeros((len(obs.value), len(OFFSETS)))
    for s_i, name in enumerate(SIGNALS):
        b[obs.signal == s_i, _OFFSET_OF[name]] = 1.0
    return b


def step_counts(obs: Observations, phases: int, periodic: bool = True) -> tuple[np.ndarray, ...]:
    """How the model's clock runs over the measured steps.

    Returns ``(before, own, strikes_before)``: ``before`` (n_obs, phases), how many steps of each
    model step precede the observation's step; ``own`` (n_obs, phases), one-hot, the
    observation's own model step; ``strikes_before`` (n_steps + 1, phases), how many of each
    precede each measured strike. With ``T`` the model's step durations (phases,), the model's
    strike ``k`` is at ``t_0 + time_offset + strikes_before[k] @ T``.
    """
    steps = model_steps(obs, phases, periodic)
    strikes_before = np.zeros((obs.n_steps + 1, phases))
    for k, j in enumerate(steps):
        strikes_before[k + 1:, j] += 1.0
    own = np.zeros((len(obs.value), phases))
    own[np.arange(len(obs.value)), steps[obs.step]] = 1.0
    return strikes_before[obs.step], own, strikes_before


@dataclasses.dataclass
class Path:
    """The model's contact positions at the measured heel strikes that have one.

    The stance contact advances by each step's displacement ``D`` (shape (2, phases), the step's
    own mirrored frame: :func:`toywalk.model.collocation.step_displacements`); a step with the
    right leg in stance has its sideways component negated. From the first measured strike, the
    model's contact at strike ``k`` is ``(X_k, Y_k) = (along[k] @ D[0], across[k] @ D[1])``.
    Measured in a ramp frame yawed by the steer offset ``o`` (the camera's error, the one that
    shifts the measured steer, :data:`OFFSETS`) and with its first contact at ``origin``, it is
    ``origin + (X - o Y, Y + o X)`` (to first order in ``o``: a few mrad, so the neglected term is
    below a micrometre over a metre of walk).

    Attributes
    ----------
    index : ndarray of int, shape (n_pos,)
        The heel strikes (into ``Observations.strikes``) with a measured contact position.
    value, sd : ndarray, shape (n_pos, 2)
        Measured positions (m) and their standard deviations (m; NaN where the file gives none).
    along, across : ndarray, shape (n_pos, phases)
        How many of each model step precede the strike, and the same counted with the stance
        sign (+1 left, -1 right).
    """

    index: np.ndarray
    value: np.ndarray
    sd: np.ndarray
    along: np.ndarray
    across: np.ndarray

    @property
    def n(self) -> int:
        return len(self.index)

    def relative(self, displacements):
        """``(X, Y)``, each shape (n_pos,), from the first measured strike (NumPy or CasADi)."""
        return _dot(self.along, displacements[0, :].T), _dot(self.across, displacements[1, :].T)


def path(obs: Observations, phases: int, periodic: bool = True) -> Path:
    """The contact-position part of the measurement model (:class:`Path`)."""
    steps = model_steps(obs, phases, periodic)
    along = step_counts(obs, phases, periodic)[2]
    across = np.zeros_like(along)
    for k, (j, stance) in enumerate(zip(steps, obs.stance, strict=True)):
        across[k + 1:, j] += 1.0 if stance == "L" else -1.0
    index = obs.located
    return Path(index=index, value=obs.contact[index], sd=obs.contact_sd[index],
                along=along[index], across=across[index])


@dataclasses.dataclass
class Timing:
    """The model's values of the observations as functions of the BVP's unknowns ``w`` and the
    time offset (module docstring). Shapes: ``n_obs`` observations, ``n_w`` BVP unknowns, ``n_r``
    reads of the model (``n_obs``; with the shutter open three a sample, six where a heel strike
    splits its shutter: :func:`shutter_reads`).

    Attributes
    ----------
    basis : list of scipy.sparse.csr_matrix, each shape (n_r, n_w)
        One per node of a mesh interval's polynomial (its start, then the collocation points):
        ``basis[r] @ w`` is the (mirrored) state component each read takes at node ``r``
        of its mesh interval.
    interval : ndarray of int, shape (n_r,)
        Each read's mesh interval, from its measured phase.
    step : ndarray of int, shape (n_r,)
        Each read's measured step (its start is strike ``step`` of :attr:`strike_rel`).
    before, own, strikes_before : ndarray
        :func:`step_counts` (of the reads).
    t_rel : ndarray, shape (n_r,)
        Read times from the first measured strike (s).
    strike_rel : ndarray, shape (n_steps + 1,)
        Measured strike times from the first (s).
    nodes : ndarray, shape (degree + 1,)
        The interval polynomial's nodes in [0, 1].
    n_int : int
    phase : ndarray, shape (n_r,)
        Each read's measured phase in its step.
    average : scipy.sparse.csr_matrix, shape (n_obs, n_r), or None
        The samples from the reads (:func:`shutter_reads`); None where they are the samples.
    """

    basis: list
    interval: np.ndarray
    step: np.ndarray
    before: np.ndarray
    own: np.ndarray
    strikes_before: np.ndarray
    t_rel: np.ndarray
    strike_rel: np.ndarray
    nodes: np.ndarray
    n_int: int
    phase: np.ndarray
    average: sp.csr_matrix | None = None

    def _samples(self, reads):
        """The samples' values from the reads' (NumPy or CasADi; SciPy sparse for a matrix)."""
        return reads if self.average is None else (self.average @ reads if sp.issparse(reads)
                                                   else _dot(self.average, reads))

    def local(self, durations, time_offset, clock=None, lead=0.0):
        """Each observation's position within its mesh interval (0 to 1 inside it), given the
        model's step durations (phases,) and the time offset (s), or the model's strike times
        ``clock`` (:meth:`values`): NumPy or CasADi. ``lead`` (s): each step's flow starts that
        long after its heel strike (a compliant strike's phase,
        :func:`toywalk.model.collocation.strike_phase`); a read inside the phase takes the
        flow's polynomial continued back to it."""
        start = (time_offset + _dot(self.before, durations) if clock is None
                 else _dot(self.step_select(), clock))
        return (self.t_rel - start - lead) / (_dot(self.own, durations) - lead) * self.n_int - self.interval

    def values(self, w, durations, time_offset, clock=None, lead=0.0):
        """The model's angle at every observation (without the ramp-frame offsets); ``lead`` as
        for :meth:`local`.

        ``clock`` (shape (n_steps + 1,), s), when given, holds the model's strike times
        (:meth:`strikes`) as unknowns of their own, tied to the durations by :meth:`clock_links`:
        each read then depends on its own step's strike and duration, not on every duration
        before it, and the misfit's Hessian stays sparse over a long walk of many model steps (a
        transient fit; measured on 20 steps of stable-toy: the misfit's Hessian took 17 s to
        build, with 2.0e5 non-zeros, and 0.5 s with 5.4e4 through the clock).
        """
        weights = lagrange_weights(self.nodes, self.local(durations, time_offset, clock, lead))
        return self._samples(sum(weight * _dot(b, w) for weight, b in zip(weights, self.basis, strict=True)))

    def step_select(self) -> sp.csr_matrix:
        """The reads' selection (n_r, n_steps + 1) of their own step's start from the strikes."""
        n = len(self.step)
        return sp.csr_matrix((np.ones(n), (np.arange(n), self.step)), shape=(n, len(self.strike_rel)))

    def clock_links(self, clock, durations, time_offset):
        """The equalities (n_steps + 1,), zero where ``clock`` holds the model's strike times
        (:meth:`strikes`): the first at the time offset, each next a model step's duration after
        the last. CasADi arguments."""
        n = len(self.strike_rel)
        after_last = sp.eye(n, format="csr") - sp.eye(n, k=-1, format="csr")
        jumps = sp.csr_matrix(np.diff(self.strikes_before, axis=0, prepend=0.0))
        first = sp.csr_matrix(([1.0], ([0], [0])), shape=(n, 1))
        return _dot(after_last, clock) - _dot(jumps, durations) - _dot(first, time_offset)

    def strikes(self, durations, time_offset):
        """The model's heel-strike times, from the first measured one (s)."""
        return time_offset + _dot(self.strikes_before, durations)

    def aligned(self, w, lead):
        """The model's angle at every observation read at its measured phase (as
        :meth:`at_phases`), each step's flow starting ``lead`` (s, a CasADi expression: a
        compliant strike's phase, :meth:`local`) after its measured strike: a read at the measured
        time ``t`` into a step of measured duration ``D`` takes the flow at ``(t - lead) / (D -
        lead)`` of its span (continued back inside the phase)."""
        span = self.strike_rel[self.step + 1] - self.strike_rel[self.step]
        local = (self.phase * span - lead) / (span - lead) * self.n_int - self.interval
        weights = lagrange_weights(self.nodes, local)
        return self._samples(sum(weight * _dot(b, w) for weight, b in zip(weights, self.basis, strict=True)))

    def at_phases(self) -> sp.csr_matrix:
        """The linear map (n_obs, n_w) reading each observation at its measured phase, the model's
        strikes on the measured ones (:func:`operator`)."""
        weights = lagrange_weights(self.nodes, self.phase * self.n_int - self.interval)
        reads = sum(sp.diags(weight) @ b for weight, b in zip(weights, self.basis, strict=True)).tocsr()
        return self._samples(reads).tocsr()


def _dot(matrix, vector):
    """``matrix @ vector`` for a NumPy or SciPy matrix and a NumPy or CasADi vector. CasADi is
    given the matrix sparse, its zeros structural: dense, every entry is a dependence (every
    read on every step's duration), which CasADi's derivatives carry as non-zeros."""
    if isinstance(vector, np.ndarray):
        return matrix @ vector
    import casadi as ca

    return ca.mtimes(ca.DM(sp.csc_matrix(matrix)), vector)


def timing(obs: Observations, prob: BVP, planar: bool) -> Timing:
    """The measurement model with the model's strike times (:class:`Timing`)."""
    reads, average = shutter_reads(obs)
    model_step, component, sign = components(reads, prob.phases, planar, prob.periodic)
    interval = np.minimum((reads.phase * prob.n_int).astype(int), prob.n_int - 1)
    n_w = prob.phases * prob.phase_size
    basis = []
    rows = np.flatnonzero(component >= 0)
    for r in range(prob.degree + 1):
        cols = [prob.state_index(model_step[i], interval[i], r) + component[i] for i in rows]
        basis.append(sp.csr_matrix((sign[rows], (rows, cols)), shape=(len(reads.value), n_w)))
    before, own, strikes_before = step_counts(reads, prob.phases, prob.periodic)
    t0 = obs.step_start[0]
    return Timing(basis=basis, interval=interval, step=reads.step, before=before, own=own,
                  strikes_before=strikes_before, t_rel=reads.time - t0, strike_rel=obs.strikes - t0,
                  nodes=np.r_[0.0, prob.tau], n_int=prob.n_int, phase=reads.phase, average=average)


def operator(obs: Observations, prob: BVP, planar: bool) -> tuple[sp.csr_matrix, np.ndarray,
                                                                   np.ndarray]:
    """The linear map from the BVP's unknowns to the model's values of the observations, each
    read at its *measured* phase (the model's strikes on the measured ones).

    Returns ``(A, B, phase_of_step)``: ``A`` (n_obs, n_w) sparse, so that ``A @ w`` is the model's
    angle at each observation; ``B`` (n_obs, 3) the offsets' design (:data:`OFFSETS`); and the
    model step (phase of the period) each measured step is compared with.
    """
    a = timing(obs, prob, planar).at_phases()
    return a, offsets_design(obs), model_steps(obs, prob.phases, prob.periodic)
