"""The walker: right-hand side, energy, one step (flow to the guard, collision, mirror) and its Jacobian.

:class:`Walker` joins a parameter set to the compiled kernels of :mod:`toywalk.model.engine`.
Public states use the seed's order (docs/model.md section 1)::

    z = (phi, phi_dot, psi, psi_dot, theta_st, theta_st_dot, theta_sw, theta_sw_dot)   shape (8,)

The step map P = mirror o collision o flow-to-guard (docs/model.md section 4) is evaluated by integrating
with a fixed step dt until the guard is crossed (the swing foot's lowest point reaches the ramp,
moving down, after it has passed in front of the stance foot), then solving for the length of the
last step by Newton's method. Its Jacobian is exact for the numerical flow: AD through the steps,
the implicit-function correction for the variable step time (the saltation term), and the collision.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .compliant import SPAN
from .effects import CONTINUOUS, EFFECTS
from .engine import SCAN, engine, soft_heel_kernels
from .parameters import N_PARAMS, PARAMETER_NAMES, Params

__all__ = ["CLEARANCE_RESOLUTION", "STATE_NAMES", "Cycle", "Step", "StepFailure", "SwingClearance",
           "Walker", "describe_scuffs"]

#: Public state order (docs/model.md section 1).
STATE_NAMES = (
    "phi", "phi_dot", "psi", "psi_dot", "theta_st", "theta_st_dot", "theta_sw", "theta_sw_dot",
)

# Public index -> internal index (3D internal state: phi, psi, th_st, th_sw, then the rates).
_PUB_TO_INT_3D = np.array([0, 4, 1, 5, 2, 6, 3, 7])
# Newton on the last step's length: |h| target (relative to the leg length) and iteration cap.
_GUARD_TOL = 1e-14
_GUARD_MAXIT = 30
# The instant the legs pass (for the clearance): |distance ahead| target, relative to the leg
# length. The clearance is then off by about this much times dh/d(ahead) (order 1): 1e-10 of a
# leg is far below any clearance worth reporting, and two or three iterations reach it.
_PASS_TOL = 1e-10
#: A clearance within this many leg lengths of 0 is a touch, not a clearance or a dip into the ramp:
#: ten times the passing instant's tolerance (_PASS_TOL), which bounds the clearance's error. The
#: seed's point feet (w = 0) pass through each other at h = -1.1e-14 m, round-off of 0.
CLEARANCE_RESOLUTION = 10 * _PASS_TOL
# The swing foot must start at least this far (relative to the leg length) behind the stance foot:
# legs together (a zero-length step) is a trivial fixed point of the step map, not a gait.
_START_GAP = 1e-6
# The contact time constant's place in the parameter vector (the phase's duration is SPAN times it).
_SOFT_HEEL = PARAMETER_NAMES.index("effects.soft_heel")
# Admissible collision: kinetic energy may not grow by more than round-off (relative to the
# kinetic energy before), and no normal impulse may pull (relative to the total).
_IMPACT_RTOL = 1e-12


@dataclasses.dataclass(frozen=True)
class SwingClearance:
    """How the swing foot clears the ramp over its whole swing, from lift-off to heel strike.

    The swing foot's height h(t) is the height of its lowest point over the ramp plane: for a
    convex foot over a plane, its distance from the ramp. It leaves the ramp at the heel strike that
    starts the step (h = 0) and lands at the next (h = 0), so its minimum over the closed swing is
    always 0 and says nothing. The clearance is the lower of

    - its height as the legs pass (the instant it comes level with the stance foot's contact
      point, ``ahead`` = 0), the one instant every swing has in its middle; and
    - every interior local minimum of h (a dip anywhere between lift-off and heel strike, before
      or after the legs pass), each solved on the flow (dh/dt = 0).

    It is negative exactly when the swing foot goes below the ramp somewhere between the two heel
    strikes: a foot that moves into the ramp at lift-off, or dips into it while passing, has a
    negative interior minimum. It extends :attr:`Step.clearance` (the same, after the legs pass
    only) to the whole swing.

    Why this is meaningful for feet offset sideways by the hip width w (docs/model.md section 2): the
    swing foot passes beside the stance foot, not through it, and the ramp is the only thing it can
    hit (torus feet of lateral radius rho never meet while w > 2 rho). With equal pitches its height
    as the legs pass is ``-w sin(psi)``: lean towards the stance foot (psi < 0) lifts it, as the
    toy's rocking does. A walker with w = 0 (the seed's, the compass walker) runs both feet on one
    line: its clearance is at most 0 (its feet pass through each other, which the model ignores).

    Attributes
    ----------
    minimum : float
        The clearance (m).
    time : float
        When it occurs (s after the heel strike that starts the step).
    phase : float
        ``time`` as a fraction of the step's duration.
    ahead : float
        Where it occurs: the swing foot's lowest point ahead of the stance contact along the heading
        (m; negative while it is behind, before the legs pass; 0 at the passing instant).
    beside : float
        The swing foot's lowest point's distance sideways from the stance contact there (m; about
        w when the legs are parallel).
    at_passing : float
        h as the legs pass (m).
    apex : float
        The highest h over the swing (m).
    lift_off_rate : float
        dh/dt just after the heel strike that starts the step (m/s): the trailing foot leaves the
        ramp there only if it is positive.
    dips : int
        Interior local minima of h (0: it rises once and falls once).
    where : str
        ``"legs passing"`` when the clearance is the height as the legs pass, ``"dip"`` when it is
        an interior minimum.
    """

    minimum: float
    time: float
    phase: float
    ahead: float
    beside: float
    at_passing: float
    apex: float
    lift_off_rate: float
    dips: int
    where: str

    def as_dict(self) -> dict:
        """JSON-ready copy (m, s, m/s)."""
        return dataclasses.asdict(self)


def describe_scuffs(scuffs: int, steps: int, lowest: float | None = None,
                    resolution: float = 0.0) -> str:
    """The one sentence that says the swing foot scuffed the ramp (:attr:`Step.scuffs`), as every
    command words it: a clause, in lower case and without a full stop, to print as it is or after a
    colon. "" when there are no scuffs.

    ``describe_scuffs(16, 16, -0.000536)``: "the swing foot scuffs the ramp before the legs pass,
    16 times in 16 steps, down to 0.536 mm below it (the model lets it through)".

    Parameters
    ----------
    scuffs : int
        Downward crossings of the ramp by the swing foot before the legs pass, over ``steps``.
    steps : int
        The steps they were counted over (>= 1; a gait's period, or a walk's heel strikes).
    lowest : float, optional
        The swing foot's lowest height over the ramp in those steps (m;
        :attr:`SwingClearance.minimum`): how far below the ramp it goes, said when it is below
        ``-resolution``.
    resolution : float
        Heights within this of 0 are round-off (m; :data:`CLEARANCE_RESOLUTION` leg lengths).
    """
    if isinstance(scuffs, bool) or not isinstance(scuffs, (int, np.integer)) or scuffs < 0:
        raise ValueError(f"scuffs must be a count >= 0, got {scuffs!r}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be a count >= 1, got {steps!r}")
    if scuffs == 0:
        return ""
    times = {1: "once", 2: "twice"}.get(int(scuffs), f"{scuffs} times")
    count = f"{times} a step" if steps == 1 else f"{times} in {steps} steps"
    depth = (f", down to {-1e3 * lowest:.3g} mm below it"
             if lowest is not None and math.isfinite(lowest) and lowest < -resolution else "")
    return f"the swing foot scuffs the ramp before the legs pass, {count}{depth} (the model lets it through)"


class StepFailure(RuntimeError):
    """A step did not end in a heel strike; ``status`` says why, ``trajectory`` holds what was done."""

    def __init__(self, status: str, message: str, trajectory: tuple[np.ndarray, np.ndarray] | None = None):
        super().__init__(message)
        self.status = status
        self.trajectory = trajectory


@dataclasses.dataclass
class Step:
    """One step from just after a heel strike to just after the next (mirrored).

    Attributes
    ----------
    z_plus : ndarray, shape (8,)
        State just after the next heel strike, relabelled and mirrored (public order).
    step_time : float
        Duration of the step (s): with ``effects.soft_heel`` on, the flow to the heel strike and
        the compliant strike's phase (toywalk.model.effects.soft).
    z_minus : ndarray, shape (8,)
        State just before the heel strike (not mirrored, old labels).
    contact : ndarray, shape (2,)
        New contact point relative to the old one (m), in the step's (unmirrored) ramp frame.
    scuffs : int
        Downward crossings of the ramp by the swing foot before it passed the stance foot.
    clearance : float
        How close the swing foot comes to the ramp after it has passed the stance foot (m): the
        lower of its height at the instant it passes and its interior minima of height after that
        (each solved on the flow), the final descent onto the ramp at heel strike excluded.
        Negative when it passes the stance foot while still below the ramp surface. NaN unless the
        step was recorded (``record``): the step map itself does not need it. See ``swing`` for
        the clearance over the whole swing.
    swing : SwingClearance or None
        The swing foot's clearance over its whole swing, from lift-off to heel strike, when the step
        was recorded.
    jacobian : ndarray, shape (8, 8) or None
        dz_plus / dz_0 when requested.
    jacobian_params : ndarray, shape (8, N_PARAMS) or None
        dz_plus / dp when requested (p in the order of ``PARAMETER_NAMES``).
    time_gradient : ndarray, shape (8,) or None
        d step_time / dz_0 when requested.
    time_gradient_params : ndarray, shape (N_PARAMS,) or None
        d step_time / dp when requested.
    times, states : ndarray, shapes (n,), (n, nx) or None
        Samples of the internal state on the integration grid, with the state at the heel strike
        (``z_minus``) last, when requested.
    side : int
        +1 when the physical left leg was in stance (z0 is the physical state), -1 for the right.
    collision_loss : float
        Kinetic energy lost in the heel strike (J, >= 0); with ``effects.soft_heel`` on, the
        rolling model's energy (kinetic and gravitational) lost over the compliant strike.
    impulses : ndarray, shape (2,)
        Normal impulses at the landing and the trailing foot (N s); with ``effects.soft_heel``
        on, integrated over the compliant strike (the landing foot's with the final projection's).
    strike_phase : float
        The compliant heel strike's duration (s), part of ``step_time``: 0 for the rigid collision
        (``effects.soft_heel`` = 0). The heel strike (touchdown) is at ``step_time - strike_phase``.
    dissipated : ndarray, shape (n, n_continuous) or None
        Energy dissipated since the start of the step by each continuous effect
        (:data:`toywalk.model.effects.CONTINUOUS`), at ``times``, when recorded (J).
    """

    z_plus: np.ndarray
    step_time: float
    z_minus: np.ndarray
    contact: np.ndarray
    scuffs: int
    clearance: float
    side: int = 1
    collision_loss: float = 0.0
    impulses: np.ndarray | None = None
    strike_phase: float = 0.0
    dissipated: np.ndarray | None = None
    jacobian: np.ndarray | None = None
    jacobian_params: np.ndarray | None = None
    time_gradient: np.ndarray | None = None
    time_gradient_params: np.ndarray | None = None
    times: np.ndarray | None = None
    states: np.ndarray | None = None
    swing: SwingClearance | None = None


@dataclasses.dataclass
class Cycle:
    """One period of the walker's motion: a step (symmetric walker) or a stride (two steps, left
    leg in stance first, for a walker whose effects break the mirror symmetry).

    Attributes
    ----------
    z_plus : ndarray, shape (8,)
        State after the period, in the description of its start.
    time : float
        Its duration (s).
    steps : list of Step
    jacobian, jacobian_params, time_gradient : ndarray or None
        dz_plus/dz0 (8, 8), dz_plus/dp (8, N_PARAMS), d time/dz0 (8,) when requested.
    """

    z_plus: np.ndarray
    time: float
    steps: list
    jacobian: np.ndarray | None = None
    jacobian_params: np.ndarray | None = None
    time_gradient: np.ndarray | None = None

    @property
    def displacement(self) -> np.ndarray:
        """Advance of the stance contact over the period (m, ramp frame of the start), shape (2,)."""
        total = np.zeros(2)
        for step in self.steps:
            total += step.contact * [1.0, step.side]
        return total


class Walker:
    """A parameter set with the compiled equations of the 3D (or planar) walker.

    Parameters
    ----------
    params : Params
        The walker.
    planar : bool
        Use the planar reduction (phi = psi = 0 held; docs/model.md section 7). Only valid when the
        walker is planar-symmetric (d_y = 0, I_xy = I_yz = 0, w = 0); required for point-mass
        limits whose 3D mass matrix is singular in the lateral directions.
    steps_per_time_unit : int
        Integration steps per sqrt(l/g) time unit. The default (16) gives a step map accurate to
        about 1e-12 for the bundled walkers (tests/model/test_stepmap.py checks convergence).
    max_step_time : float
        A step that has not ended after this many sqrt(l/g) time units is a failure.
    period : int, optional
        Steps in the map whose fixed points are gaits (:meth:`cycle`): 1 (the step map) or 2 (the
        stride map). Default: 2 when the walker's effects break the mirror symmetry, else 1.
    effects : bool
        Use the equations with the effect library (default); False runs the seed's model alone
        and refuses a parameter set with effects (benchmarks and null checks).
    compiled : bool
        Use compiled kernels (default) or CasADi's virtual machine.
    soft_steps_per_tau : int, optional
        RK4 steps per contact time constant of the compliant heel strike (``effects.soft_heel``
        > 0; default :data:`toywalk.model.compliant.STEPS_PER_TAU`): a resolution check.
    """

    def __init__(self, params: Params, planar: bool = False, steps_per_time_unit: int = 16,
                 max_step_time: float = 20.0, period: int | None = None, effects: bool = True,
                 compiled: bool = True, soft_steps_per_tau: int | None = None):
        if not isinstance(params, Params):
            raise TypeError(f"params must be a Params, got {type(params).__name__}")
        if planar and not is_planar_symmetric(params):
            raise ValueError(
                "planar=True needs a planar-symmetric walker (com_offset[1] = 0, inertia xy = yz = 0, "
                "hip_width = 0, no cross_slope)"
            )
        if not effects and params.active_effects:
            raise ValueError("effects=False runs the seed's model: the parameter set has effects on")
        if period is None:
            period = 2 if params.breaks_symmetry else 1
        if period not in (1, 2):
            raise ValueError(f"period must be 1 (step map) or 2 (stride map), got {period!r}")
        if steps_per_time_unit < 1:
            raise ValueError(f"steps_per_time_unit must be >= 1, got {steps_per_time_unit!r}")
        self.params = params
        self.planar = planar
        self.period = period
        self._inputs = {1: params.input_vector(1.0), -1: params.input_vector(-1.0)}
        self.p = self._inputs[1]
        self.eng = engine(planar, effects, compiled)
        # Admissibility of the collision is checked where an effect changes the collision law.
        self._check_impact = any(EFFECTS[k].enters == "collision law" for k in params.active_effects)
        self._dissipative = any(k in CONTINUOUS for k in params.active_effects)
        # The compliant heel strike (effects.soft_heel > 0, toywalk.model.effects.soft) replaces
        # the collision kernel; at 0 the rigid path below runs, untouched.
        self._soft = None
        if params.effects.get("soft_heel", 0.0) > 0.0:
            others = [name for name in params.active_effects if name != "soft_heel"]
            if others:
                raise ValueError(f"the soft heel strike (effects.soft_heel) models the seed's walker: "
                                 f"set {', '.join(others)} to their null values")
            if soft_steps_per_tau is not None and soft_steps_per_tau < 1:
                raise ValueError(f"soft_steps_per_tau must be >= 1, got {soft_steps_per_tau!r}")
            self._soft = soft_heel_kernels(planar, compiled, soft_steps_per_tau)
        self.lay = self.eng.lay
        self.dt = params.time_scale / steps_per_time_unit
        self.max_step_time = max_step_time * params.time_scale

    @property
    def soft_kernels(self) -> dict | None:
        """The compliant heel strike's kernels (``soft_strike``, ``soft_strike_jac``;
        :func:`toywalk.model.engine.soft_heel_kernels`) with ``effects.soft_heel`` on, else None."""
        return self._soft

    # --------------------------------------------------------------------------- state layout
    def to_internal(self, z: np.ndarray) -> np.ndarray:
        """Internal dynamic state (q, u) from a public state z, shape (8,)."""
        z = _checked_state(z)
        if self.planar:
            return z[[4, 6, 5, 7]]
        out = np.empty(8)
        out[_PUB_TO_INT_3D] = z
        return out

    def to_public(self, xi: np.ndarray) -> np.ndarray:
        """Public state z, shape (8,), from an internal dynamic state (q, u)."""
        xi = np.asarray(xi, dtype=float)
        if self.planar:
            z = np.zeros(8)
            z[[4, 6, 5, 7]] = xi[:4]
            return z
        return xi[:8][_PUB_TO_INT_3D]

    def _jac_to_public(self, jac: np.ndarray) -> np.ndarray:
        """Map a Jacobian of internal dynamic states (rows and columns) to public order."""
        if self.planar:
            out = np.zeros((8, 8))
            idx = [4, 6, 5, 7]
            out[np.ix_(idx, idx)] = jac
            return out
        return jac[np.ix_(_PUB_TO_INT_3D, _PUB_TO_INT_3D)]

    def _rows_to_public(self, rows: np.ndarray) -> np.ndarray:
        if self.planar:
            out = np.zeros((8,) + rows.shape[1:])
            out[[4, 6, 5, 7]] = rows
            return out
        return rows[_PUB_TO_INT_3D]

    def _cols_to_public(self, cols: np.ndarray) -> np.ndarray:
        if self.planar:
            out = np.zeros(cols.shape[:-1] + (8,))
            out[..., [4, 6, 5, 7]] = cols
            return out
        return cols[..., _PUB_TO_INT_3D]

    def full_state(self, z: np.ndarray, contact=(0.0, 0.0)) -> np.ndarray:
        """Internal state (q, u, contact travel), shape (nx,)."""
        xi = self.to_internal(z)
        travel = np.asarray(contact, dtype=float)[: self.lay.nx - self.lay.n_dyn]
        return np.concatenate([xi, travel])

    # --------------------------------------------------------------------------- pointwise
    def rhs(self, x: np.ndarray, side: int = 1) -> np.ndarray:
        """Internal state derivative, shape (nx,), at internal state x (``side``: see :meth:`step`)."""
        return self.eng.k["rhs"](x, self._inputs[side])[0].ravel().copy()

    def energy(self, x: np.ndarray, side: int = 1) -> float:
        """Total energy (J): kinetic plus gravitational, with the contact travel, at internal state x."""
        return float(self.eng.k["energy"](x, self._inputs[side])[0][0, 0])

    def dissipation(self, x: np.ndarray, side: int = 1) -> np.ndarray:
        """Power (W) dissipated by each continuous effect (:data:`~toywalk.model.effects.CONTINUOUS`)."""
        return self.eng.k["dissipation"](x, self._inputs[side])[0].ravel().copy()

    def guard(self, x: np.ndarray, side: int = 1) -> tuple[float, float]:
        """(swing-foot height over the ramp, its distance ahead of the stance contact) (m)."""
        g = self.eng.k["guard"](x, self._inputs[side])[0].ravel()
        return float(g[0]), float(g[1])

    def points(self, x: np.ndarray, side: int = 1) -> np.ndarray:
        """The walker's points relative to the stance contact, shape (9, 3) (m).

        Rows: stance contact C, stance foot centre O1, stance hip H1, axle, swing hip H2, swing foot
        centre O2, swing foot's lowest point C2, stance-leg COM G1, swing-leg COM G2.
        """
        return self.eng.k["points"](x, self._inputs[side])[0].T.copy()

    def collide(self, z_minus: np.ndarray, side: int = 1) -> np.ndarray:
        """Collision (or the compliant heel strike, with ``effects.soft_heel`` on), relabel and
        mirror of a public state just before heel strike; shape (8,)."""
        x = self.full_state(z_minus)
        kernel = self.eng.k["collision"] if self._soft is None else self._soft["soft_strike"]
        return self.to_public(kernel(x, self._inputs[side])[0].ravel())

    # --------------------------------------------------------------------------- one step
    def step(self, z0: np.ndarray, jacobian: bool = False, params_jacobian: bool = False,
             record: bool = False, side: int = 1) -> Step:
        """Integrate from just after a heel strike to just after the next one (the step map).

        Parameters
        ----------
        z0 : ndarray, shape (8,)
            Public state just after a heel strike (stance leg = left, after mirroring).
        jacobian : bool
            Also compute dz_plus/dz0 and d step_time/dz0 by AD.
        params_jacobian : bool
            Also compute dz_plus/dp (p in the order of ``PARAMETER_NAMES``); implies ``jacobian``.
        record : bool
            Also return the samples of the internal state on the integration grid, the energy
            each continuous effect has dissipated at them, and the swing foot's clearance.
        side : {1, -1}
            The physical leg in stance: +1 the left (z0 is the physical state), -1 the right (z0
            is the mirrored description). Only symmetry-breaking effects tell them apart.

        Raises
        ------
        StepFailure
            ``status`` is ``"fell"`` (a hip, a leg's or the walker's centre of mass reached the ramp),
            ``"no_heel_strike"`` (no heel strike within ``max_step_time``) or ``"inadmissible_impact"``
            (an effect of the collision law would gain energy or pull on a foot).
        """
        x0 = self.full_state(z0)
        return self._step_internal(x0, jacobian or params_jacobian, params_jacobian, record, side)

    def cycle(self, z0: np.ndarray, jacobian: bool = False, params_jacobian: bool = False,
              record: bool = False, steps: int | None = None) -> Cycle:
        """The map whose fixed points are gaits: the step map, or the stride map P_R o P_L (left
        leg in stance first) when ``period`` is 2 (or ``steps`` says so). Mirroring twice restores
        the description, so a stride's end state is in the frame of z0."""
        n_steps = self.period if steps is None else steps
        done, z = [], np.asarray(z0, dtype=float)
        for i in range(n_steps):
            done.append(self.step(z, jacobian, params_jacobian, record, side=1 if i % 2 == 0 else -1))
            z = done[-1].z_plus
        out = Cycle(z_plus=z, time=sum(s.step_time for s in done), steps=done)
        if jacobian or params_jacobian:
            jac, grad = np.eye(8), np.zeros(8)
            jac_p = np.zeros((8, N_PARAMS)) if params_jacobian else None
            for s in done:
                grad = grad + s.time_gradient @ jac
                if params_jacobian:
                    jac_p = s.jacobian @ jac_p + s.jacobian_params
                jac = s.jacobian @ jac
            out.jacobian, out.time_gradient, out.jacobian_params = jac, grad, jac_p
        return out

    def _step_internal(self, x0: np.ndarray, jacobian: bool = False, params_jacobian: bool = False,
                       record: bool = False, side: int = 1) -> Step:
        if side not in (1, -1):
            raise ValueError(f"side must be +1 (left leg in stance) or -1 (right), got {side!r}")
        k, p, dt, lay = self.eng.k, self._inputs[side], self.dt, self.lay
        g_prev = k["probe"](x0, p)[0].ravel().copy()
        x = x0.copy()
        n_done = 0
        scuffs = 0
        # A heel strike needs the swing foot to come from behind the stance foot: a state whose
        # swing foot is not behind at the start (legs together) cannot start a step.
        if not g_prev[1] < -_START_GAP * self.params.leg_length:
            raise StepFailure(
                "no_heel_strike",
                f"the swing foot must start behind the stance foot (it is {g_prev[1]:.3g} m ahead)",
            )
        # Clearance (see Step and SwingClearance; only when recording): the grid sample before the
        # legs pass, from which the passing instant is solved.
        x_pass = None
        blocks = [x0[None, :].copy()] if record else None
        n_max = int(math.ceil(self.max_step_time / dt))
        while True:
            if n_done >= n_max:
                raise StepFailure("no_heel_strike", f"no heel strike within {self.max_step_time:.4g} s",
                                  self._partial(blocks))
            xs, gs = (a.copy() for a in k["scan"](x, dt, p))
            h, ahead, low = gs
            if not np.all(np.isfinite(xs)):
                raise StepFailure("fell", "the state became non-finite", self._partial(blocks))
            h_prev = np.concatenate([[g_prev[0]], h[:-1]])
            crossing = (h <= 0.0) & (h_prev > 0.0)
            events = np.flatnonzero(crossing | (low <= 0.0))
            j_hit = None
            for j in events:
                if low[j] <= 0.0:
                    if record:
                        blocks.append(xs[:, : j + 1].T)
                    raise StepFailure(
                        "fell",
                        f"a hip or a centre of mass reached the ramp at t = {(n_done + j + 1) * dt:.4g} s",
                        self._partial(blocks),
                    )
                if ahead[j] > 0.0:
                    j_hit = int(j)
                    break
                scuffs += 1
            if record and x_pass is None:  # do the legs pass in this chunk (or the strike's step)?
                seen = np.flatnonzero(ahead[: SCAN if j_hit is None else j_hit + 1] > 0.0)
                if len(seen):
                    first = int(seen[0])
                    x_pass = xs[:, first - 1].copy() if first > 0 else x.copy()
                    ahead_pass = (float(ahead[first - 1] if first > 0 else g_prev[1]),
                                  float(ahead[first]))
                    t_pass = (n_done + first) * dt  # the grid time of x_pass
            if j_hit is not None:
                break
            if record:
                blocks.append(xs.T)
            x = xs[:, -1].copy()
            g_prev = gs[:, -1]
            n_done += SCAN
        hit = n_done + j_hit  # the crossing lies inside integration step number `hit` (0-based)
        x_before = xs[:, j_hit - 1].copy() if j_hit > 0 else x.copy()
        if record:
            blocks.append(xs[:, :j_hit].T)
        h_before = h_prev[j_hit]
        # Newton on the last step's length tau in (0, dt]: h(step(x_before, tau)) = 0.
        tau = dt * h_before / (h_before - h[j_hit])
        for _ in range(_GUARD_MAXIT):
            g, dh, xt = k["final"](x_before, tau, p)
            if abs(g[0, 0]) <= _GUARD_TOL * self.params.leg_length:
                break
            tau = tau - g[0, 0] / dh[0, 0]
        else:
            raise StepFailure("no_heel_strike", "the heel-strike time did not converge")
        x_t = xt.ravel().copy()
        step_time = strike_time = hit * dt + tau
        strike_phase = 0.0
        if self._soft is None:
            x_plus = k["collision"](x_t, p)[0].ravel().copy()
            d_kinetic, impulses, kinetic = (a.ravel().copy() for a in k["impact"](x_t, p))
        else:
            # The compliant phase: its duration adds to the step, and its loss is the rolling
            # model's energy (gravity's included) before it less that after it.
            x_plus, phase, d_kinetic, impulses, kinetic = (
                a.ravel().copy() for a in self._soft["soft_strike"](x_t, p))
            strike_phase = float(phase[0])
            step_time = strike_time + strike_phase
            if not np.all(np.isfinite(x_plus)):
                raise StepFailure("inadmissible_impact",
                                  "the compliant heel strike's state became non-finite: its contact is "
                                  "too stiff for the phase's integration on this walker's feet "
                                  "(docs/soft_feet.md section 5)")
        if self._check_impact:
            _admissible(float(d_kinetic[0]), impulses, float(kinetic[0]))
        travel = slice(lay.n_dyn, lay.nx)
        contact = np.zeros(2)
        contact[: lay.nx - lay.n_dyn] = x_plus[travel] - x0[travel]
        out = Step(
            z_plus=self.to_public(x_plus),
            step_time=float(step_time),
            z_minus=self.to_public(x_t),
            contact=contact,
            scuffs=scuffs,
            clearance=math.nan,
            side=side,
            collision_loss=-float(d_kinetic[0]),
            impulses=impulses,
            strike_phase=strike_phase,
        )
        if record:
            blocks.append(x_t[None, :])
            out.states = np.concatenate(blocks)
            out.times = np.concatenate([np.arange(hit + 1) * dt, [strike_time]])
            out.dissipated = self._dissipated(out.states, out.times, p)
            passing = self._passing(x_pass, t_pass, ahead_pass, p)
            out.swing, out.clearance = self._swing_clearance(out.states, out.times, passing, p)
        if jacobian:
            self._step_jacobian(x0, hit, x_before, tau, x_t, out, params_jacobian, p)
        return out

    def _passing(self, x_pass: np.ndarray, t_pass: float, ahead_pass: tuple[float, float],
                 p: np.ndarray) -> tuple[float, float, np.ndarray]:
        """(h, t, x) at the instant the legs pass: the swing foot's height (m), the time (s) and
        the internal state, from the grid state ``x_pass`` at time ``t_pass`` just before and the
        swing foot's distance ahead of the stance contact there and one integration step later.

        Solved inside that integration step by the Illinois variant of regula falsi (Dowell &
        Jarratt, BIT 11:168, 1971) to _PASS_TOL.
        """
        k = self.eng.k
        a, b = 0.0, self.dt
        fa, fb = ahead_pass
        tol = _PASS_TOL * self.params.leg_length
        tau = b
        for _ in range(_GUARD_MAXIT):
            tau = b - fb * (b - a) / (fb - fa)
            f = float(k["guard"](k["step"](x_pass, tau, p)[0], p)[0][1, 0])
            if abs(f) <= tol:
                break
            if (f > 0.0) == (fb > 0.0):
                b, fb = tau, f
                fa *= 0.5  # Illinois: halve the retained end's value so that it moves too
            else:
                a, fa = b, fb
                b, fb = tau, f
        x = k["step"](x_pass, tau, p)[0].ravel().copy()
        return float(k["guard"](x, p)[0][0, 0]), t_pass + tau, x

    def _swing_clearance(self, states: np.ndarray, times: np.ndarray,
                         passing: tuple[float, float, np.ndarray],
                         p: np.ndarray) -> tuple[SwingClearance, float]:
        """The :class:`SwingClearance` of a recorded step, and its clearance after the legs pass
        (:attr:`Step.clearance`, m), from the internal states ``states`` (n, nx) at ``times`` (n,),
        from just after one heel strike to just before the next, and (h, t, x) as the legs pass
        (:meth:`_passing`).

        The interior extrema of the swing foot's height are found on the samples and each is then
        solved on the flow (dh/dt = 0, :meth:`_extremum`), so that the values do not depend on the
        integration grid beyond the integrator's own error.
        """
        k = self.eng.k
        h = np.array([k["guard"](x, p)[0][0, 0] for x in states])
        lo, mid, hi = h[:-2], h[1:-1], h[2:]
        minima = np.flatnonzero((mid <= lo) & (mid < hi)) + 1
        maxima = np.flatnonzero((mid >= lo) & (mid > hi)) + 1
        # dh/dtau of the integrator's step at tau = 0 is grad(h) . f(x): the rate itself.
        lift_off_rate = float(k["final"](states[0], 0.0, p)[1][0, 0])
        top = int(np.argmax(h))
        apex = max((self._extremum(states, times, i, p)[0] for i in maxima), default=float(h[top]))
        dips = [self._extremum(states, times, i, p) for i in minima]
        height, time, x = min([passing, *dips], key=lambda e: e[0])
        where = "dip" if dips and height < passing[0] else "legs passing"
        after = min([passing[0], *(d[0] for d in dips if d[1] > passing[1])])
        c2 = k["points"](x, p)[0][:, 6]  # the swing foot's lowest point, relative to the contact
        heading = 0.0 if self.planar else float(x[0])
        ahead = math.cos(heading) * c2[0] + math.sin(heading) * c2[1]
        beside = abs(-math.sin(heading) * c2[0] + math.cos(heading) * c2[1])
        swing = SwingClearance(
            minimum=float(height), time=float(time), phase=float(time / times[-1]),
            ahead=float(ahead), beside=float(beside), at_passing=float(passing[0]),
            apex=float(apex), lift_off_rate=lift_off_rate, dips=len(minima), where=where)
        return swing, float(after)

    def _extremum(self, states: np.ndarray, times: np.ndarray, i: int,
                  p: np.ndarray) -> tuple[float, float, np.ndarray]:
        """(h, t, x) at the extremum of the swing foot's height next to sample ``i``: the root of
        dh/dtau along the integrator's step from sample i - 1, tau in [0, t[i+1] - t[i-1]], by
        the Illinois variant of regula falsi. The sample itself when the rate does not change sign
        there (a flat stretch)."""
        final = self.eng.k["final"]
        x0 = states[i - 1]
        a, b = 0.0, float(times[i + 1] - times[i - 1])
        fa = float(final(x0, a, p)[1][0, 0])
        fb = float(final(x0, b, p)[1][0, 0])
        if not fa * fb < 0.0:
            return float(self.eng.k["guard"](states[i], p)[0][0, 0]), float(times[i]), states[i].copy()
        # The rate's root to _PASS_TOL of a leg length per sqrt(l/g): the height is then off by
        # far less than that (it is stationary there).
        tol = _PASS_TOL * self.params.leg_length / self.params.time_scale
        tau = b
        for _ in range(_GUARD_MAXIT):
            tau = b - fb * (b - a) / (fb - fa)
            f = float(final(x0, tau, p)[1][0, 0])
            if abs(f) <= tol:
                break
            if (f > 0.0) == (fb > 0.0):
                b, fb = tau, f
                fa *= 0.5
            else:
                a, fa = b, fb
                b, fb = tau, f
        g, _, xt = final(x0, tau, p)
        return float(g[0, 0]), float(times[i - 1] + tau), xt.ravel().copy()

    def _dissipated(self, states: np.ndarray, times: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Cumulative energy dissipated by each continuous effect at the recorded samples (J)."""
        n = self.eng.fns["dissipation"].size1_out(0)
        out = np.zeros((len(times), n))
        if not self._dissipative:
            return out
        kernel = self.eng.k["dissipation_step"]
        for i in range(1, len(times)):
            out[i] = out[i - 1] + kernel(states[i - 1], times[i] - times[i - 1], p)[0].ravel()
        return out

    def stride(self, z0: np.ndarray, jacobian: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """The stride map P_R o P_L (the seed's map f, collision to the next collision of the same
        foot), whatever the walker's ``period``.

        Returns ``(z_2, J)``: the state after two steps, shape (8,), and dz_2/dz0 (8, 8) or None.
        Mirroring twice restores the original description, so z_2 is in the frame of z0.
        """
        out = self.cycle(z0, jacobian=jacobian, steps=2)
        return out.z_plus, out.jacobian

    def _partial(self, blocks):
        if blocks is None:
            return None
        states = np.concatenate(blocks)
        return np.arange(len(states)) * self.dt, states

    def _step_jacobian(self, x0, n_full, x_before, tau, x_t, out: Step, params: bool,
                       p: np.ndarray) -> None:
        """Chain rule through the full steps, the last step (with the implicit guard time) and the
        collision: dx_T/dx0 = S_x Phi + S_tau dtau/dx0, dtau/dx0 = -h_x S_x Phi / (h_x S_tau)."""
        k, dt = self.eng.k, self.dt
        nd = self.lay.n_dyn
        _, phi_x, phi_p = self.eng.chunk_jacobian(x0, n_full, dt, p, params=params)
        _, s_x, s_tau, s_p = (a.copy() for a in k["final_jac"](x_before, tau, p))
        s_tau = s_tau.ravel()
        _, h_x, h_p = (a.copy().ravel() for a in k["guard_jac"](x_t, p))
        strike = k["collision_jac"] if self._soft is None else self._soft["soft_strike_jac"]
        _, c_x, c_p = (a.copy() for a in strike(x_t, p))
        denom = h_x @ s_tau
        dxt_dx0 = s_x @ phi_x
        dtau_dx0 = -(h_x @ dxt_dx0) / denom
        dxt_dx0 = dxt_dx0 + np.outer(s_tau, dtau_dx0)
        out.jacobian = self._jac_to_public((c_x @ dxt_dx0)[:nd, :nd])
        out.time_gradient = self._cols_to_public(dtau_dx0[:nd])
        if params:
            dxt_dp = s_x @ phi_p + s_p
            dtau_dp = -(h_x @ dxt_dp + h_p) / denom
            dxt_dp = dxt_dp + np.outer(s_tau, dtau_dp)
            # The last input column is the side in stance, not a parameter.
            out.jacobian_params = self._rows_to_public((c_x @ dxt_dp + c_p)[:nd, :N_PARAMS])
            out.time_gradient_params = dtau_dp[:N_PARAMS]
            if self._soft is not None:  # the phase lasts SPAN time constants
                out.time_gradient_params[_SOFT_HEEL] += SPAN


def _admissible(d_kinetic: float, impulses: np.ndarray, kinetic: float) -> None:
    """Raise :class:`StepFailure` for a collision that gains kinetic energy (J, ``kinetic`` before
    it) or has a negative normal impulse (N s) beyond round-off."""
    total = float(np.sum(np.abs(impulses)))
    if d_kinetic > _IMPACT_RTOL * max(kinetic, 0.0) or np.min(impulses) < -_IMPACT_RTOL * total:
        raise StepFailure(
            "inadmissible_impact",
            f"the heel strike would gain {d_kinetic:.3g} J or pull on a foot (normal impulses "
            f"{impulses[0]:.3g}, {impulses[1]:.3g} N s): the collision-law effects are beyond "
            "what this impact admits",
        )


def is_planar_symmetric(params: Params) -> bool:
    """True when motion with phi = psi = 0 is invariant (docs/model.md section 7)."""
    i = params.inertia
    return (params.com_offset[1] == 0.0 and i[3] == 0.0 and i[5] == 0.0 and params.hip_width == 0.0
            and params.effects.get("cross_slope", 0.0) == 0.0)


def _checked_state(z) -> np.ndarray:
    z = np.asarray(z, dtype=float)
    if z.shape != (8,):
        raise ValueError(f"a walker state has 8 components {STATE_NAMES}, got shape {z.shape}")
    if not np.all(np.isfinite(z)):
        raise ValueError(f"a walker state must be finite, got {z.tolist()}")
    return z
