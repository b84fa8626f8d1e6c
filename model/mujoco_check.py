"""The walker in an independent rigid-body engine (MuJoCo), as a new user would build it.

The model's assumptions are checked by an engine that knows nothing of them: soft contacts with
friction at both feet all the time (no guard, no ignored scuffing, no impulsive collision law),
feet of the same bottom curvatures, the same masses and inertias, the same slope. Built from a
parameter file, started from the model's fixed point, it shows whether the model's gait is one
that a physical walker could walk.

The MuJoCo model (Todorov, Erez & Tassa, IROS 2012, doi:10.1109/IROS.2012.6386109):

- the world is the slope frame S (docs/model.md section 1): the ramp is the plane z = 0 and gravity is
  ``g (sin(alpha), 0, -cos(alpha))``;
- the left leg is a free body whose frame is the leg's body frame (origin at its hip point, b1
  forward, b2 along the axle, b3 up the leg); the right leg is its child, hinged about b2 at its hip
  point ``hip_width`` to the right; the axle's point mass is added to the left leg (it lies on the
  hinge axis, so which leg carries it does not matter);
- each foot is an oblate spheroid about the axle direction, centred where the model's torus is
  (``leg_length - foot_radius`` below the hip), equatorial radius ``foot_radius`` and polar
  semi-axis ``sqrt(foot_radius * foot_lateral_radius)``: around its whole rim its radius of
  curvature is ``foot_radius`` fore-aft and ``foot_lateral_radius`` sideways, as the torus's is.
  Its lowest point's height differs from the torus's by O(lean^4) (1e-4 mm at 5 degrees);
- contacts are the feet against the ramp only, with sliding friction and no contact couple
  (condim 3: the model's point contact rolls without slip and has no pivot friction), stiff
  (``solref`` time constant a few integration steps) and critically damped (plastic heel strikes).

Those are the defaults, the build checked against the model (tests/model/test_mujoco.py). The
contacts' time constant and damping ratio, the friction, the foot's semi-axes and its turn about
the axle are options, so that a walk can carry physics the model lacks (softer, overdamped or
bouncing heel strikes, slip, a foot whose curvature changes along its rim); tests/sysid/outside.py
makes such walks.

Heel strikes are read from the contacts: a foot's contact that begins after it has been off the
ramp, ahead of the other foot's, is a heel strike; a new contact of the foot that made the last
heel strike, soon after it and before the other foot has struck, is a bounce of that landing (the
model's plastic strike cannot bounce; MuJoCo's soft one sometimes does); any other new contact of
a foot is a scuff.

The walk's angles are read from the two legs' orientations with the model's own inverse
(:func:`~toywalk.model.kinematics.angles_from_rotations`, docs/model.md section 1): the left leg's
frame is ``Rz(steer) Rx(lean) Ry(pitch_left)`` and the right leg's is that times the hinge's
``Ry(pitch_right - pitch_left)``, so steer, lean and both pitches come back exactly, in the physical
(unmirrored) frame. :func:`mujoco_trajectory` writes them in the trajectory format (docs/formats.md),
for ``toywalk fit`` and ``toywalk diagnose`` to read as data.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .compliant import SPAN, STEPS_PER_TAU
from .effects.soft import FRICTION, ZETA
from .files import software_version as _version
from .kinematics import angles_from_rotations, leg_poses, rotation
from .parameters import PARAMETER_NAMES, Params
from .trajectory import SIGNALS, TrajectoryTable
from .walker import STATE_NAMES, StepFailure, Walker

__all__ = ["STRIKE_SOLIMP", "MujocoStrike", "MujocoWalk", "build_mjcf", "impact_pulse", "initial_state",
           "mujoco_trajectory", "strike_differences", "strike_in_mujoco", "touchdown_predictions",
           "walk_in_mujoco"]

# Contacts: the solver's time constant (s), critically damped. 1 ms is a few times shorter than
# anything the walkers do (steps of 0.1 s and more) and long enough that the heel strike is plastic:
# at 0.2 and 0.4 ms the landing foot of stable-toy widened to 110 mm hips bounced once, 4 ms after
# landing, at 1 ms it did not (measured, 1e-4 s steps). It must span several integration steps
# (MuJoCo's docs: at least two). Measured on data/params/clearing-toy.toml: the stance foot sinks
# 0.24 um at most under the walker's weight, and the landing foot 75 um at a heel strike, whose
# impulse is spread over about 2.5 ms.
_CONTACT_TIME = 1e-3
# A foot must have been off the ramp this long (s) before a new contact counts as a new touch, so
# that the solver's contact chatter within one touch is not counted twice.
_OFF_TIME = 2e-3
# A new touch of the foot that made the last heel strike, within this time (s) after it and before
# the other foot has struck, is that foot bouncing off the ramp and landing again, not a heel
# strike. Measured: data/params/robust-toy.toml kicked (seed 5 of docs/make_basin_mujoco.py, 1 ms
# contacts, friction 1) lands its right foot at 0.6681 s, leaves the ramp for over 2 ms and lands
# again at 0.6751 s, 0.2 mm further on. 30 ms is four times that, and under a third of the
# shortest gait step of a shipped round-footed walker (stable-toy's, 107 ms), so no real step of
# the same foot fits in it; a same-foot touch after it still ends the walk as a fall.
_BOUNCE_TIME = 3e-2
# The contact model's other settings, written into the MJCF and into a trajectory's metadata.
# solimp (0.99, 0.999, 0.1 mm): the constraint's impedance, 0.99 at first touch rising to 0.999 at
# 0.1 mm of penetration. Elliptic friction cones with impratio 10 and MuJoCo's no-slip pass (10
# iterations) hold the rolling foot's contact nearly still where the model's rolls without slip:
# it creeps 15 um sideways and 3 um along in a step of the clearing walker (measured,
# tests/model/test_mujoco.py).
_SOLIMP = (0.99, 0.999, 0.0001)
# The walker is lowered this far (m) at the start of a heel strike in MuJoCo, so that both feet's
# contacts are on from the start: at zero distance MuJoCo may find none (round-off puts the feet
# 1e-17 m above the ramp). It is 4e-6 of the clearing toy's landing foot's deepest penetration at
# tau = 1 ms, and the reference acceleration k r it gives at 1 ms, 1e-3 m/s^2, is 1e-4 g.
_TOUCH = 1e-9
#: The heel-strike comparison's impedance (:func:`strike_in_mujoco`): flat (the same d at any
#: penetration, so MuJoCo's reference spring is exactly ``solref``'s) and near 1.
STRIKE_SOLIMP = (0.9999, 0.9999, 0.001)
_SOLVER = {"integrator": "RK4", "cone": "elliptic", "impratio": 10, "noslip_iterations": 10}


def _require_mujoco():
    try:
        import mujoco
    except ImportError as err:  # pragma: no cover - the extra is installed in the tests
        raise ImportError(
            "the MuJoCo check needs the mujoco package: pip install 'toywalk[test]' or pip install mujoco"
        ) from err
    return mujoco


def _num(values) -> str:
    """Numbers for MJCF, space-separated, every digit kept."""
    return " ".join(repr(float(v)) for v in values)


@dataclasses.dataclass(frozen=True)
class _Foot:
    """The ellipsoid foot: semi-axes (m) along its own axes, which are the leg's (b1, b2, b3)
    turned about b2 by ``pitch`` (rad)."""

    axes: tuple[float, float, float]
    pitch: float = 0.0

    @property
    def shape(self) -> np.ndarray:
        """``R diag(a^2) R'`` in the leg frame, R the turn about b2: the ellipsoid is the set
        ``x' shape^-1 x = 1`` about its centre, shape (3, 3) (m^2)."""
        c, s = math.cos(self.pitch), math.sin(self.pitch)
        turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        return turn @ np.diag(np.square(self.axes)) @ turn.T

    @property
    def depth(self) -> float:
        """Height of the centre over the lowest point with the leg upright (m)."""
        return math.sqrt(self.shape[2, 2])


def _public_state(z, name: str) -> np.ndarray:
    """``z`` as a float array, refused unless it is a finite public state of 8 components."""
    z = np.asarray(z, dtype=float)
    if z.shape != (8,) or not np.all(np.isfinite(z)):
        raise ValueError(f"{name} must be a finite state of 8 components, got {z!r}")
    return z


def _foot(params: Params, foot_axes=None, foot_pitch: float = 0.0) -> _Foot:
    """The foot of ``build_mjcf``'s options (validated): the spheroid of the torus's rim
    curvatures by default."""
    if not math.isfinite(foot_pitch) or abs(foot_pitch) >= math.pi / 2:
        raise ValueError(f"foot_pitch must be a finite angle within (-pi/2, pi/2) rad, got {foot_pitch!r}")
    if foot_axes is None:
        r, rho = params.foot_radius, params.foot_lateral_radius
        return _Foot((r, math.sqrt(r * rho), r), float(foot_pitch))
    try:
        axes = tuple(float(v) for v in foot_axes)
    except (TypeError, ValueError) as err:
        raise ValueError(f"foot_axes must be 3 semi-axes (m), got {foot_axes!r}") from err
    if len(axes) != 3 or not all(math.isfinite(v) and v > 0.0 for v in axes):
        raise ValueError(f"foot_axes must be 3 finite semi-axes > 0 (m), got {foot_axes!r}")
    foot = _Foot(axes, float(foot_pitch))
    if not foot.depth < params.leg_length:
        raise ValueError(f"the foot's centre ({foot.depth} m above its lowest point) must lie below "
                         f"the hip ({params.leg_length} m)")
    return foot


def _foot_centre(params: Params, foot: _Foot) -> float:
    """The foot's centre along the leg from the hip point (m, negative: below): its lowest point
    lies ``leg_length`` below the hip with the leg upright."""
    return -(params.leg_length - foot.depth)


def _contact_settings(contact_time: float, damping_ratio: float) -> None:
    """Refuse contact settings that are not a time constant (s) and a damping ratio."""
    if not (math.isfinite(contact_time) and contact_time > 0):
        raise ValueError(f"contact_time must be a finite time > 0 (s), got {contact_time!r}")
    if not (math.isfinite(damping_ratio) and damping_ratio > 0):
        raise ValueError(f"damping_ratio must be a finite ratio > 0, got {damping_ratio!r}")


def _impedance(solimp) -> tuple[float, ...]:
    """A valid ``solimp`` (3 or 5 numbers: 0 < d0, d_width < 1, width > 0), or ValueError."""
    try:
        values = tuple(float(v) for v in solimp)
    except (TypeError, ValueError) as err:
        raise ValueError(f"solimp must be 3 or 5 numbers, got {solimp!r}") from err
    if (len(values) not in (3, 5) or not all(math.isfinite(v) for v in values)
            or not all(0.0 < d < 1.0 for d in values[:2]) or not values[2] > 0.0):
        raise ValueError(f"solimp must be (d0, d_width, width[, midpoint, power]) with 0 < d < 1 and "
                         f"width > 0 (m), got {solimp!r}")
    return values


def _leg_inertial(params: Params, mirror: bool, with_axle: bool) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia tensor about it), in the leg's body frame (kg, m, kg m^2)."""
    d = np.array(params.com_offset, dtype=float)
    inertia = params.inertia_tensor().copy()
    if mirror:  # the right leg is the mirror image (docs/model.md section 2)
        d[1] = -d[1]
        flip = np.diag([1.0, -1.0, 1.0])
        inertia = flip @ inertia @ flip
    mass = params.leg_mass
    if not with_axle or params.axle_mass == 0.0:
        return mass, d, inertia
    axle = np.array([0.0, -0.5 * params.hip_width, 0.0])  # the axle's middle, right of the left hip
    total = mass + params.axle_mass
    com = (mass * d + params.axle_mass * axle) / total
    out = inertia.copy()
    for m, p in ((mass, d - com), (params.axle_mass, axle - com)):
        out += m * (p @ p * np.eye(3) - np.outer(p, p))  # parallel axes
    return total, com, out


def build_mjcf(params: Params, timestep: float = 1e-4, friction: float = 2.0,
               contact_time: float = _CONTACT_TIME, damping_ratio: float = 1.0,
               foot_axes=None, foot_pitch: float = 0.0, solimp=None) -> str:
    """The MuJoCo model of ``params`` (MJCF text; see the module's docstring).

    Parameters
    ----------
    params : Params
        A walker without effects and with round feet (``foot_lateral_radius`` > 0).
    timestep : float
        Integration step (s).
    friction : float
        Sliding friction coefficient of the feet on the ramp (the model assumes no slip).
    contact_time : float
        The contacts' time constant (s; MuJoCo's ``solref``), at least four timesteps.
    damping_ratio : float
        The contacts' damping ratio (1: critically damped, a plastic heel strike; below 1 the
        landing foot rebounds, which the model's collision law does not).
    foot_axes : sequence of 3 floats, optional
        The ellipsoid foot's semi-axes (m) along b1 (forward), b2 (the axle) and b3 (up the leg),
        its bottom ``leg_length`` below the hip; default the spheroid of the torus's rim
        curvatures. Other axes give a foot the model does not have: the fore-aft radius of
        curvature at the bottom is ``a^2 / c`` and changes along the rim unless ``a = c``.
    foot_pitch : float
        The ellipsoid turned about the axle by this angle (rad), its lowest point with the leg
        upright kept ``leg_length`` below the hip: with ``a != c`` a foot whose fore-aft radius of
        curvature grows along the rim one way and shrinks the other.
    solimp : sequence of 3 or 5 floats, optional
        The contacts' impedance (MuJoCo's ``solimp``: d at zero penetration, d at ``width`` and
        beyond, ``width`` (m)[, midpoint, power]); default the walking build's (0.99, 0.999, 0.1 mm).
    """
    if params.active_effects:
        raise ValueError(f"the MuJoCo walker has no effects; the parameter set has {params.active_effects}")
    if not params.foot_lateral_radius > 0.0:
        raise ValueError("the MuJoCo walker needs round feet (foot_lateral_radius > 0); "
                         f"got {params.foot_lateral_radius}")
    shape = _foot(params, foot_axes, foot_pitch)
    a, b, c = shape.axes
    centre = _foot_centre(params, shape)
    g = params.gravity
    grav = (g * math.sin(params.slope), 0.0, -g * math.cos(params.slope))

    def inertial(mirror: bool, with_axle: bool) -> str:
        mass, com, i = _leg_inertial(params, mirror, with_axle)
        full = (i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2])
        return (f'<inertial pos="{_num(com)}" mass="{_num([mass])}" fullinertia="{_num(full)}"/>')

    turn = f' euler="0 {shape.pitch!r} 0"' if shape.pitch else ""
    foot = (f'type="ellipsoid" size="{a!r} {b!r} {c!r}" pos="0 0 {centre!r}"{turn} contype="1" '
            f'conaffinity="0" condim="3" friction="{friction!r} 0 0" mass="0"')
    _contact_settings(contact_time, damping_ratio)
    impedance = _impedance(_SOLIMP if solimp is None else solimp)
    if not 4 * timestep <= contact_time:
        raise ValueError(f"timestep must be at most a quarter of the contact time constant "
                         f"{contact_time} s, got {timestep}")
    solver = " ".join(f'{key}="{value}"' for key, value in _SOLVER.items())
    return f"""<mujoco model="toywalk">
  <compiler angle="radian"/>
  <option timestep="{timestep!r}" gravity="{grav[0]!r} {grav[1]!r} {grav[2]!r}" {solver}/>
  <default><geom solref="{contact_time!r} {damping_ratio!r}" solimp="{_num(impedance)}"/></default>
  <worldbody>
    <geom name="ramp" type="plane" size="0 0 1" contype="0" conaffinity="1" condim="3"
          friction="{friction!r} 0 0"/>
    <body name="left" pos="0 0 1">
      <freejoint name="left"/>
      {inertial(False, True)}
      <geom name="left_foot" {foot}/>
      <body name="right" pos="0 {-params.hip_width!r} 0">
        <joint name="hip" type="hinge" axis="0 1 0" damping="0"/>
        {inertial(True, False)}
        <geom name="right_foot" {foot}/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@dataclasses.dataclass
class MujocoWalk:
    """A walk in MuJoCo.

    Attributes
    ----------
    status : str
        ``"completed"`` (the steps asked for) or ``"fell"`` (a hip came down to half the leg
        length, the same foot struck twice running (the second touch too late to be a bounce,
        :attr:`bounces`), or the time ran out first; ``message`` says which).
    message : str
    strikes : ndarray, shape (n, 3)
        Heel strikes: time (s), the landing foot's contact position along the ramp and across it (m).
    feet : list of str
        The landing foot of each heel strike, 'L' or 'R'.
    scuffs : int
        New contacts of a foot that were neither heel strikes nor bounces (the swing foot touching
        the ramp).
    steps : int
        Heel strikes that alternate feet (right, left, ...), counted from the start, which is the
        left foot's.
    step_times, step_lengths : ndarray, shape (steps,)
        Between successive alternating heel strikes, the start the first (s; m along the fall line,
        from contact point to contact point).
    duration : float
        Simulated time (s).
    times : ndarray, shape (n_samples,)
        Sample times (s), every ``1 / sample_rate`` from 0 (the start, before the first
        integration step).
    angles : ndarray, shape (n_samples, 4)
        The walker's angles at those times (rad), columns :data:`~toywalk.model.trajectory.SIGNALS`:
        lean (psi), steer (phi), pitch_left, pitch_right (docs/model.md section 1), physical frame.
    stance : ndarray of str, shape (n_samples,)
        The foot of the last heel strike at or before each sample ('L' from the start).
    contact : ndarray, shape (n_samples, 2)
        The stance foot's lowest point on the ramp (m, slope frame): where it touches it.
    start : ndarray, shape (8,)
        The model state the walk started from (just after a left heel strike).
    settings : dict
        MuJoCo and its settings: ``engine`` (MuJoCo's version), ``timestep`` (s), ``friction``,
        ``contact_time_constant`` (s), ``contact_damping_ratio``, ``solimp``, ``integrator``,
        ``cone``, ``impratio``, ``noslip_iterations``, ``condim``, ``sample_rate`` (Hz), and
        where the foot is not the default spheroid ``foot_axes`` (m) and ``foot_pitch`` (rad).
    rates : ndarray, shape (n_samples, 4)
        The angles' rates (rad/s), from the left leg's angular velocity and the hinge's rate.
    stance_force : ndarray, shape (n_samples,)
        The stance foot's normal contact force (N; 0 where its contact is off: chatter, or the
        foot in the air).
    penetration : ndarray, shape (n_samples,)
        The stance foot's penetration: minus its lowest point's height over the ramp (m).
    slip_speed : ndarray, shape (n_samples,)
        The speed along the ramp of the stance foot's material point at its lowest point (m/s):
        0 for the model's rolling contact.
    energy : ndarray, shape (n_samples,)
        The walker's mechanical energy, kinetic and gravitational (J; MuJoCo's ``mj_energyPos``
        and ``mj_energyVel``): constant between heel strikes in the model.
    bounces : int
        New contacts of the foot that made the last heel strike, within 30 ms after it and before
        the other foot struck: the landing foot left the ramp (for over 2 ms) and landed again. They
        are not heel strikes (:attr:`strikes` and :attr:`steps` do not count them), nor scuffs.
    """

    status: str
    message: str
    strikes: np.ndarray
    feet: list
    scuffs: int
    steps: int
    step_times: np.ndarray
    step_lengths: np.ndarray
    duration: float
    times: np.ndarray
    angles: np.ndarray
    stance: np.ndarray
    contact: np.ndarray
    start: np.ndarray
    settings: dict
    rates: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 4)))
    stance_force: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    penetration: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    slip_speed: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    energy: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    bounces: int = 0

    @property
    def lean(self) -> np.ndarray:
        """Lean psi at the samples (rad), shape (n_samples,)."""
        return self.angles[:, 0]

    def public_state(self, i: int) -> np.ndarray:
        """The model's public state at sample ``i`` (docs/model.md section 1), in the step map's
        mirrored description (stance leg the left; the sample's stance foot is taken as stance):
        ``(phi, phi', psi, psi', theta_st, theta_st', theta_sw, theta_sw')``, shape (8,). At sample 0
        it is :attr:`start`."""
        lean, steer, left, right = self.angles[i]
        lean_rate, steer_rate, left_rate, right_rate = self.rates[i]
        if self.stance[i] == "L":
            return np.array([steer, steer_rate, lean, lean_rate, left, left_rate, right, right_rate])
        return np.array([-steer, -steer_rate, -lean, -lean_rate, right, right_rate, left, left_rate])

    @property
    def steer(self) -> np.ndarray:
        """Steer phi at the samples (rad), shape (n_samples,)."""
        return self.angles[:, 1]

    @property
    def stride_ends(self) -> np.ndarray:
        """Times (s) of the start and of every second alternating heel strike (the left foot's):
        the bounds of the walk's complete strides, shape (steps // 2 + 1,)."""
        return np.r_[0.0, self.strikes[:self.steps, 0]][::2]

    def stride_amplitudes(self, signal: str) -> np.ndarray:
        """Half the peak-to-peak of ``signal`` (``"lean"`` or ``"steer"``) over each complete stride
        (rad), shape (steps // 2,): the gait's :attr:`~toywalk.model.gait.Gait.lean_amplitude` and
        :attr:`~toywalk.model.gait.Gait.steer_amplitude` (which for a step-periodic gait is max |psi|,
        max |phi|), stride by stride, in the physical frame.

        Raises
        ------
        ValueError
            An unknown signal, or a walk without a complete stride (fewer than two steps).
        """
        if signal not in ("lean", "steer"):
            raise ValueError(f"signal must be 'lean' or 'steer', got {signal!r}")
        series = self.lean if signal == "lean" else self.steer
        ends = self.stride_ends
        if len(ends) < 2:
            raise ValueError(f"the walk has no complete stride ({self.steps} alternating steps)")
        out = []
        for a, b in zip(ends[:-1], ends[1:], strict=True):
            inside = series[(self.times >= a) & (self.times <= b)]
            out.append(0.5 * (inside.max() - inside.min()))
        return np.array(out)

    @property
    def lean_amplitude(self) -> float:
        """The lean's stride amplitude (rad; :meth:`stride_amplitudes`), averaged over the strides."""
        return float(np.mean(self.stride_amplitudes("lean")))

    @property
    def steer_amplitude(self) -> float:
        """The steer's stride amplitude (rad; :meth:`stride_amplitudes`), averaged over the strides."""
        return float(np.mean(self.stride_amplitudes("steer")))

    @property
    def stride_headings(self) -> np.ndarray:
        """Direction of travel over each complete stride (rad, from the fall line towards the left;
        :attr:`~toywalk.model.gait.Gait.heading`): from one left heel strike's contact point to the
        next, the start's at the origin; shape (steps // 2,)."""
        points = np.vstack([np.zeros((1, 2)), self.strikes[:self.steps, 1:]])[::2]
        d = np.diff(points, axis=0)
        return np.arctan2(d[:, 1], d[:, 0])


def _lowest_offset(params: Params, rot: np.ndarray, foot: _Foot | None = None) -> np.ndarray:
    """The ellipsoid foot's lowest point relative to its centre (m, slope frame) for a leg of
    rotation ``rot``: ``-A e_z / sqrt(e_z' A e_z)``, ``A = R diag(a^2) R'`` (a the semi-axes, R
    the foot's axes in the slope frame)."""
    foot = _foot(params) if foot is None else foot
    a_mat = rot @ foot.shape @ rot.T
    return -a_mat[:, 2] / math.sqrt(a_mat[2, 2])


def _angles_and_rates(data, left: int, right: int) -> tuple[np.ndarray, np.ndarray]:
    """(lean, steer, pitch_left, pitch_right) (rad) and their rates (rad/s) of MuJoCo's walker,
    physical frame: the angles from the legs' frames (:func:`angles_from_rotations`), the rates
    from the left leg's angular velocity (``omega = phi' e_z + psi' a_1 + theta_left' n``, the
    axes of the turns) and the hinge's rate."""
    rot_left, rot_right = data.xmat[left].reshape(3, 3), data.xmat[right].reshape(3, 3)
    steer, lean, pitch_left, pitch_right = angles_from_rotations(rot_left, rot_right)
    omega = rot_left @ data.qvel[3:6]  # the left leg's angular velocity, ramp frame
    axes = np.column_stack([[0.0, 0.0, 1.0], rotation(steer, 0.0, 0.0)[:, 0],
                            rotation(steer, lean, 0.0)[:, 1]])
    steer_rate, lean_rate, left_rate = np.linalg.solve(axes, omega)
    return (np.array([lean, steer, pitch_left, pitch_right]),
            np.array([lean_rate, steer_rate, left_rate, left_rate + data.qvel[6]]))


def initial_state(params: Params, z0: np.ndarray, foot_axes=None,
                  foot_pitch: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's (qpos, qvel) for the public state ``z0`` just after a heel strike, left leg in
    stance, its foot's lowest point on the ramp at the origin (rolling: the contact at rest);
    ``foot_axes`` and ``foot_pitch`` as in :func:`build_mjcf`."""
    foot = _foot(params, foot_axes, foot_pitch)
    phi, phid, psi, psid, th1, th1d, th2, th2d = map(float, z0)
    poses = leg_poses(params, phi, psi, th1, th2, "L", (0.0, 0.0))
    rot = poses.rotation["L"]
    low = _lowest_offset(params, rot, foot)
    centre = rot @ np.array([0.0, 0.0, _foot_centre(params, foot)])
    hip = -low - centre  # the hip with the lowest point at the origin
    n = rotation(phi, psi, 0.0)[:, 1]
    ez = np.array([0.0, 0.0, 1.0])
    omega = phid * ez + psid * rotation(phi, 0.0, 0.0)[:, 0] + th1d * n
    v_hip = np.cross(omega, hip)  # the contact point (origin) is at rest
    quat = _quaternion(rot)
    qpos = np.concatenate([hip, quat, [th2 - th1]])
    qvel = np.concatenate([v_hip, rot.T @ omega, [th2d - th1d]])
    return qpos, qvel


def _quaternion(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    w = math.sqrt(max(0.0, 1.0 + np.trace(rot))) / 2.0
    if w > 1e-6:
        return np.array([w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w),
                         (rot[1, 0] - rot[0, 1]) / (4 * w)])
    raise ValueError("rotation too far from the identity for this start")  # not for a walker


def walk_in_mujoco(params: Params, z0: np.ndarray, steps: int = 20, timestep: float = 1e-4,
                   friction: float = 2.0, max_time: float | None = None,
                   sample_rate: float = 1000.0, contact_time: float = _CONTACT_TIME,
                   damping_ratio: float = 1.0, foot_axes=None, foot_pitch: float = 0.0,
                   solimp=None) -> MujocoWalk:
    """Start the MuJoCo walker at the public state ``z0`` (just after a heel strike, left leg in
    stance) and run it until ``steps`` heel strikes after the start, a fall, or ``max_time``.

    Parameters
    ----------
    params : Params
    z0 : ndarray, shape (8,)
        The model's state just after a heel strike (docs/model.md section 1), e.g. a gait's fixed point.
    steps : int
        Heel strikes to walk.
    timestep : float
        MuJoCo's integration step (s).
    friction : float
        Sliding friction coefficient.
    max_time : float, optional
        Give up after this long (s); default 3 s per step asked for.
    sample_rate : float
        Samples of the angles per second (Hz); ``1 / sample_rate`` must be a whole number of
        integration steps.
    contact_time, damping_ratio, foot_axes, foot_pitch, solimp
        The contacts' time constant (s) and damping ratio, the foot's semi-axes (m) and turn
        (rad), the contacts' impedance, as in :func:`build_mjcf`; the defaults are the build
        checked against the model.

    Returns
    -------
    MujocoWalk
    """
    mujoco = _require_mujoco()
    z0 = _public_state(z0, "z0")
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    if not (sample_rate > 0 and math.isfinite(sample_rate)):
        raise ValueError(f"sample_rate must be a finite rate > 0 (Hz), got {sample_rate!r}")
    every = round(1.0 / (sample_rate * timestep))
    if every < 1 or abs(every * timestep * sample_rate - 1.0) > 1e-9:
        raise ValueError(f"1 / sample_rate must be a whole number of timesteps ({timestep} s), "
                         f"got sample_rate {sample_rate!r} Hz")
    sole = _foot(params, foot_axes, foot_pitch)
    model = mujoco.MjModel.from_xml_string(
        build_mjcf(params, timestep, friction, contact_time, damping_ratio, sole.axes, sole.pitch,
                   solimp))
    impedance = _impedance(_SOLIMP if solimp is None else solimp)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(params, z0, sole.axes, sole.pitch)
    mujoco.mj_forward(model, data)
    foot_of = {model.geom("left_foot").id: "L", model.geom("right_foot").id: "R"}
    bodies = {"L": model.body("left").id, "R": model.body("right").id}
    left, right = bodies["L"], bodies["R"]
    fallen = 0.5 * params.leg_length  # hip height (m)
    max_time = 3.0 * steps if max_time is None else max_time
    last_touch = {"L": 0.0, "R": 0.0}  # both feet are on the ramp at the start
    strikes: list[tuple[float, float, float]] = []
    landed: list[str] = []
    samples: list[tuple[float, ...]] = []
    stances: list[str] = []

    geom_of = {foot: geom for geom, foot in foot_of.items()}
    force, jac = np.zeros(6), np.zeros((3, model.nv))

    def sample() -> None:
        stance = landed[-1] if landed else "L"
        rot = data.xmat[bodies[stance]].reshape(3, 3)
        angles, rates = _angles_and_rates(data, left, right)
        low = (_foot_position(data, model, bodies[stance], params, sole)
               + _lowest_offset(params, rot, sole))
        normal = 0.0
        for i in range(data.ncon):
            if geom_of[stance] in data.contact.geom[i]:
                mujoco.mj_contactForce(model, data, i, force)
                normal += force[0]
        mujoco.mj_jac(model, data, jac, None, low, bodies[stance])  # the material point at low
        slip = jac @ data.qvel
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        samples.append((data.time, *angles, low[0], low[1], *rates, normal, -low[2],
                        math.hypot(slip[0], slip[1]), data.energy[0] + data.energy[1]))
        stances.append(stance)

    scuffs, bounces, n_step = 0, 0, 0
    sample()
    status, message = "fell", f"no {steps} heel strikes within {max_time:.3g} s"
    while data.time < max_time:
        mujoco.mj_step(model, data)
        n_step += 1
        touching = {}  # foot -> index of its (last) contact; plain lists: ncon is 0 to 2
        if data.ncon:
            for i, (g1, g2) in enumerate(data.contact.geom.tolist()):
                foot = foot_of.get(g1) or foot_of.get(g2)
                if foot is not None:
                    touching[foot] = i
        for foot, i in touching.items():
            if data.time - last_touch[foot] > _OFF_TIME:  # a new touch
                pos = data.contact.pos[i]
                other = "R" if foot == "L" else "L"
                last_foot, last_time = (landed[-1], strikes[-1][0]) if landed else ("L", 0.0)
                if foot == last_foot and data.time - last_time < _BOUNCE_TIME:
                    bounces += 1
                elif pos[0] > _foot_position(data, model, bodies[other], params, sole)[0]:
                    strikes.append((data.time, float(pos[0]), float(pos[1])))
                    landed.append(foot)
                else:
                    scuffs += 1
            last_touch[foot] = data.time
        if n_step % every == 0:
            sample()
        if min(data.xpos[left, 2], data.xpos[right, 2]) < fallen:
            status, message = "fell", f"a hip came down to half the leg length at t = {data.time:.3f} s"
            break
        if len(strikes) >= steps:
            status, message = "completed", f"{steps} heel strikes in {data.time:.3f} s"
            break
    # The start is a heel strike of the left foot at the origin; count the strikes that alternate.
    feet_seq = ["L", *landed]
    n_alt = 1
    while n_alt < len(feet_seq) and feet_seq[n_alt] != feet_seq[n_alt - 1]:
        n_alt += 1
    arr = np.array(strikes).reshape(-1, 3)
    if status == "completed" and n_alt < len(feet_seq):
        status, message = "fell", f"the same foot struck twice running at t = {arr[n_alt - 1, 0]:.3f} s"
    good = np.vstack([np.zeros((1, 3)), arr])[:n_alt]
    table = np.array(samples)
    settings = {"engine": f"MuJoCo {mujoco.__version__}", "timestep": timestep, "friction": friction,
                "contact_time_constant": contact_time, "contact_damping_ratio": damping_ratio,
                "solimp": list(impedance), **_SOLVER, "condim": 3, "sample_rate": sample_rate}
    if foot_axes is not None or foot_pitch:
        settings["foot_axes"], settings["foot_pitch"] = list(sole.axes), sole.pitch
    return MujocoWalk(status=status, message=message, strikes=arr, feet=landed, scuffs=scuffs,
                      steps=n_alt - 1, step_times=np.diff(good[:, 0]), step_lengths=np.diff(good[:, 1]),
                      duration=float(data.time), times=table[:, 0], angles=table[:, 1:5],
                      stance=np.array(stances), contact=table[:, 5:7], start=z0.copy(),
                      settings=settings, rates=table[:, 7:11], stance_force=table[:, 11],
                      penetration=table[:, 12], slip_speed=table[:, 13], energy=table[:, 14],
                      bounces=bounces)


def _foot_position(data, model, body: int, params: Params, foot: _Foot) -> np.ndarray:
    """The foot's centre (m, world frame) of the leg ``body``."""
    rot = data.xmat[body].reshape(3, 3)
    return data.xpos[body] + rot @ np.array([0.0, 0.0, _foot_centre(params, foot)])


def mujoco_trajectory(walk: MujocoWalk, params: Params, parameters: str | None = None) -> TrajectoryTable:
    """A MuJoCo walk as a trajectory (docs/formats.md, "Trajectory"), as ``toywalk simulate`` writes one.

    The columns are the walk's samples (``time, lean, steer, pitch_left, pitch_right, stance``
    and the stance foot's ``contact_x, contact_y``), exact, without ``*_sd`` columns; the events
    are the heel strikes that alternate feet after the start (as the model's simulation lists
    them, the start not among them), with their contact positions. The metadata say the source
    is MuJoCo, with its settings, the parameters and the start.

    Parameters
    ----------
    walk : MujocoWalk
    params : Params
        The walker ``walk`` was built from.
    parameters : str, optional
        Where they came from (a parameter file's name), for the metadata.

    Returns
    -------
    TrajectoryTable
    """
    if not isinstance(walk, MujocoWalk):
        raise TypeError(f"walk must be a MujocoWalk, got {type(walk).__name__}")
    signals = {name: walk.angles[:, i] for i, name in enumerate(SIGNALS)}
    signals["contact_x"] = walk.contact[:, 0]
    signals["contact_y"] = walk.contact[:, 1]
    events = [{"time": float(t), "foot": foot, "x": float(x), "y": float(y)}
              for (t, x, y), foot in zip(walk.strikes[:walk.steps], walk.feet[:walk.steps], strict=True)]
    every = round(1.0 / (walk.settings["sample_rate"] * walk.settings["timestep"]))
    metadata = {
        "source": {"kind": "mujoco", "parameters": parameters,
                   "parameter_values": dict(zip(PARAMETER_NAMES, params.vector().tolist(), strict=True)),
                   "effects": dict(params.effects), "steps": walk.steps,
                   "start": dict(zip(STATE_NAMES, walk.start.tolist(), strict=True)),
                   "start_kind": "the model's state just after a left heel strike, left foot's "
                                 "lowest point at the origin",
                   "model": "toywalk.model.mujoco_check: legs hinged on the axle, "
                            + ("ellipsoid feet of the semi-axes foot_axes, turned by foot_pitch"
                               if "foot_axes" in walk.settings
                               else "spheroid feet of the torus's rim curvatures")
                            + ", soft contacts of both feet with the ramp",
                   **walk.settings},
        "units": {"time": "s", "angles": "rad", "contact": "m"},
        "noise_sd": 0.0,
        "position_noise_sd": 0.0,
        "timestamps": f"MuJoCo simulation times, every {every} integration steps from the start",
        "events": "a foot's first contact after 2 ms off the ramp, ahead of the other foot's and not "
                  "a bounce (the last heel strike's foot again within 30 ms); its time to one "
                  "integration step, its position MuJoCo's contact point",
        "status": walk.status, "message": walk.message, "scuffs": walk.scuffs, "bounces": walk.bounces,
        "software": _version(),
    }
    return TrajectoryTable(walk.times, signals, walk.stance, events, metadata)


def touchdown_predictions(walk: MujocoWalk, params: Params, delay: float, steps: int = 1) -> np.ndarray:
    """The model against MuJoCo one step at a time: from MuJoCo's state at the first sample
    ``delay`` or more after each heel strike of the walk (the start the first;
    :meth:`MujocoWalk.public_state`), ``steps`` of the model's steps (:meth:`Walker.step`), and
    the time of the last heel strike they reach against MuJoCo's.

    With ``steps`` = 1 and ``delay`` past the strike's contact phase (10 contact time constants)
    both walkers roll on their stance foot throughout, so the difference is what MuJoCo's
    continuous contact (creep, chatter, penetration, the trailing foot's last touch) does over one
    flow. With ``steps`` = 2 the model's own heel strike (rigid, or compliant with
    ``effects.soft_heel``) replaces MuJoCo's once.

    Parameters
    ----------
    walk : MujocoWalk
    params : Params
        The model walker (with ``effects.soft_heel`` on, the touchdown is predicted, before the phase).
    delay : float
        Time after a heel strike at which the model takes over (s).
    steps : int
        The model's steps from there.

    Returns
    -------
    ndarray, shape (walk.steps,)
        MuJoCo's heel strike ``steps`` after the start's less the model's (s); NaN where no sample
        lies before MuJoCo's next heel strike, MuJoCo's walk ends first, or the model's step fails
        (:class:`StepFailure`).
    """
    if not isinstance(walk, MujocoWalk):
        raise TypeError(f"walk must be a MujocoWalk, got {type(walk).__name__}")
    if not (math.isfinite(delay) and delay >= 0.0):
        raise ValueError(f"delay must be a finite time >= 0 (s), got {delay!r}")
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    walker = Walker(params)
    strikes = np.r_[0.0, walk.strikes[:walk.steps, 0]]
    out = np.full(walk.steps, np.nan)
    for k in range(walk.steps + 1 - steps):
        i = int(np.searchsorted(walk.times, strikes[k] + delay))
        if i >= len(walk.times) or walk.times[i] >= strikes[k + 1]:
            continue
        z, t, side = walk.public_state(i), walk.times[i], 1 if walk.stance[i] == "L" else -1
        try:
            for _ in range(steps):
                step = walker.step(z, side=side)
                t, z, side = t + step.step_time, step.z_plus, -side
        except StepFailure:
            continue
        out[k] = strikes[k + steps] - (t - step.strike_phase)
    return out


@dataclasses.dataclass
class MujocoStrike:
    """One heel strike in MuJoCo (:func:`strike_in_mujoco`), sampled as the model's compliant strike
    (:class:`toywalk.model.compliant.CompliantStrike`) is: foot 1 is the trailing foot (the left,
    in stance before the strike), foot 2 the landing one (the right); time series are
    (n_times, n_signals), n = ``steps_per_tau * span``.

    Attributes
    ----------
    times : ndarray, shape (n + 1,)
        Sample times from touchdown (s).
    normal_forces : ndarray, shape (n + 1, 2)
        Each foot's normal contact force (N; MuJoCo's ``mj_contactForce``, 0 without a contact).
    penetrations : ndarray, shape (n + 1, 2)
        Each foot's penetration: minus its lowest point's height over the ramp (m, negative when
        off it).
    angles : ndarray, shape (n + 1, 4)
        Lean, steer, pitch_left, pitch_right (rad; columns :data:`~toywalk.model.trajectory.SIGNALS`),
        read from the legs' frames by :func:`~toywalk.model.kinematics.angles_from_rotations`.
    rates : ndarray, shape (n + 1, 4)
        Their rates (rad/s), from the left leg's angular velocity and the hinge's rate.
    settings : dict
        MuJoCo's version and the settings of the strike (timestep, solref, solimp, friction, solver).
    """

    times: np.ndarray
    normal_forces: np.ndarray
    penetrations: np.ndarray
    angles: np.ndarray
    rates: np.ndarray
    settings: dict


def strike_in_mujoco(params: Params, z_minus: np.ndarray, tau: float, zeta: float = ZETA,
                     friction: float = FRICTION, solimp=STRIKE_SOLIMP, substeps: int = 20,
                     steps_per_tau: int = STEPS_PER_TAU, span: int = SPAN) -> MujocoStrike:
    """One heel strike in MuJoCo from the model's state at touchdown, sampled as the model's
    compliant strike (:func:`toywalk.model.compliant.compliant_strike`) is, for comparing the two
    (:func:`strike_differences`; docs/soft_feet.md, "Against MuJoCo's heel strike").

    MuJoCo starts from the rolling model's state at the heel strike (left leg in stance, its foot's
    lowest point at the origin and at rest, the right foot's lowest point on the ramp and moving
    into it; :func:`initial_state`), with both feet's contacts on, ``solref = (tau, zeta)`` and
    the impedance ``solimp``, and runs for ``span`` time constants. The start is the model's
    touchdown: the landing foot's contact is at zero distance there, so MuJoCo's force jumps at
    t = 0, on its integration grid, as the model's does. Each sample is taken by ``mj_forward`` at
    the state after a step (forces, contacts and penetrations of that state, not of the last RK4
    stage).

    The two contact laws differ, whatever ``solimp``: MuJoCo's contact is a constraint whose
    acceleration obeys ``a_1 + d (b v + k r) = (1 - d) a_0`` (a_0 the acceleration without it,
    r the signed distance, ``b = 2 / (d_max tau)``, ``k = d(r) / (d_max tau zeta)^2``), solved
    jointly for both feet with the regulariser ``R = (1 - d) / d`` times MuJoCo's approximate
    diagonal of ``J M^-1 J'``. With d flat (d(r) = d_max) and near 1 (the default
    :data:`STRIKE_SOLIMP`), each foot's penetration follows the model's critically damped law in
    acceleration, so the force is the model's ``m_eff (k delta + b d(delta)/dt)`` plus
    ``-m_eff a_0`` (the force that cancels the rest of the walker's pull on the contact, gravity
    and the other foot's push), with ``m_eff`` the exact, current, coupled effective mass; the
    stance foot holds the weight at ``(1 - d) / d`` of the model's preload penetration.

    Parameters
    ----------
    params : Params
        A walker without effects, round feet.
    z_minus : ndarray, shape (8,)
        The public state at the heel strike, left leg in stance (``Walker.step(z0).z_minus`` of a
        state just after a left heel strike); the model's strike takes ``Walker.full_state`` of it.
    tau : float
        The contacts' time constant (s; ``solref[0]``, :class:`~toywalk.model.compliant.SoftContact`).
    zeta : float
        Their damping ratio (``solref[1]``).
    friction : float
        Sliding friction coefficient (default the ``soft_heel`` effect's constant).
    solimp : sequence of 3 or 5 floats
        MuJoCo's impedance (:func:`build_mjcf`).
    substeps : int
        MuJoCo's integration steps per sample: its timestep is ``tau / (steps_per_tau * substeps)``.
    steps_per_tau, span : int
        Samples per time constant and the phase's length in time constants (the model's defaults).

    Returns
    -------
    MujocoStrike
    """
    mujoco = _require_mujoco()
    z_minus = _public_state(z_minus, "z_minus")
    _contact_settings(tau, zeta)
    for name, value in (("substeps", substeps), ("steps_per_tau", steps_per_tau), ("span", span)):
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    timestep = tau / (steps_per_tau * substeps)
    sole = _foot(params)
    model = mujoco.MjModel.from_xml_string(
        build_mjcf(params, timestep, friction, tau, zeta, solimp=solimp))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(params, z_minus)
    data.qpos[2] -= _TOUCH  # both feet touching: the contacts are on from the start
    feet = (model.geom("left_foot").id, model.geom("right_foot").id)
    bodies = (model.body("left").id, model.body("right").id)
    out = np.zeros(6)
    rows = []

    def sample() -> None:
        mujoco.mj_forward(model, data)
        force = [0.0, 0.0]
        for i in range(data.ncon):
            for k, geom in enumerate(feet):
                if geom in data.contact.geom[i]:
                    mujoco.mj_contactForce(model, data, i, out)
                    force[k] += out[0]
        rot = [data.xmat[b].reshape(3, 3) for b in bodies]
        depth = [-(_foot_position(data, model, b, params, sole) + _lowest_offset(params, r, sole))[2]
                 for b, r in zip(bodies, rot, strict=True)]
        rows.append((data.time, *force, *depth, *np.concatenate(_angles_and_rates(data, *bodies))))

    sample()
    for _ in range(steps_per_tau * span):
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        sample()
    table = np.array(rows)
    settings = {"engine": f"MuJoCo {mujoco.__version__}", "timestep": timestep, "friction": friction,
                "solref": [tau, zeta], "solimp": list(_impedance(solimp)), **_SOLVER, "condim": 3}
    return MujocoStrike(times=table[:, 0], normal_forces=table[:, 1:3], penetrations=table[:, 3:5],
                        angles=table[:, 5:9], rates=table[:, 9:13], settings=settings)


# Columns of the compliant strike's phase states (toywalk.model.compliant, 3D: X (3), q (4), V (3),
# u (4), ...; q = (phi, psi, theta_st, theta_sw)) that hold lean, steer, pitch_left, pitch_right
# and their rates when the left leg is in stance before the strike (side 1: physical frame).
_PHASE_ANGLES = [4, 3, 5, 6]
_PHASE_RATES = [11, 10, 12, 13]


def impact_pulse(times: np.ndarray, force: np.ndarray) -> float:
    """The landing impact's duration (s): from the start to the first minimum of the landing foot's
    normal force after its peak (the first sample from which it stops falling). For a lone mass on
    the critically damped contact the force ``m v0 (exp(-t / tau) / tau) (2 - t / tau)`` falls to 0
    at 2 tau (where it leaves, if nothing holds it) and, unclamped, to its minimum at 3 tau.

    Parameters
    ----------
    times : ndarray, shape (n,)
        Sample times from touchdown (s).
    force : ndarray, shape (n,)
        The landing foot's normal force (N).
    """
    k = int(np.argmax(force))
    while k + 1 < len(force) and force[k + 1] < force[k]:
        k += 1
    return float(times[k])


def strike_differences(strike, mujoco_strike: MujocoStrike) -> dict:
    """The model's compliant heel strike against MuJoCo's, sampled at the same times.

    Parameters
    ----------
    strike : toywalk.model.compliant.CompliantStrike
        The model's strike of the 3D walker, left leg in stance before it (``side`` 1), from
        ``Walker.full_state(z_minus)``.
    mujoco_strike : MujocoStrike
        :func:`strike_in_mujoco` from the same ``z_minus``, ``tau``, ``steps_per_tau`` and ``span``.

    Returns
    -------
    dict
        ``angles_end`` and ``rates_end`` (shape (4,), MuJoCo less the model at the phase's end:
        lean, steer, pitch_left, pitch_right; rad, rad/s); ``angles_max`` and ``rates_max``, the
        largest absolute differences through the phase (shape (4,)); for each engine
        (``"model"``, ``"mujoco"``) a dict of the landing foot's ``peak_force`` (N), its impact
        ``pulse`` (s; :func:`impact_pulse`), its largest and last ``max_penetration`` and
        ``end_penetration`` (m), ``unloaded`` (samples after the start at which it carries no
        load: a rebound or chatter), ``leaves`` (its lowest point above the ramp at some sample
        after the start), and the trailing foot's ``lift_off`` (s, first sample after the start
        without load); ``force_rms``, the RMS difference of the landing foot's force through the
        phase (N).

    Raises
    ------
    ValueError
        Strikes sampled at different times.
    """
    if strike.states.shape[1] < 14 or len(strike.times) != len(mujoco_strike.times) or not np.allclose(
            strike.times, mujoco_strike.times, rtol=0, atol=1e-9 * max(strike.duration, 1e-300)):
        raise ValueError("the strikes must be of the 3D walker and sampled at the same times "
                         "(the same tau, steps_per_tau and span)")
    model_angles = strike.states[:, _PHASE_ANGLES]
    model_rates = strike.states[:, _PHASE_RATES]
    d_angles = mujoco_strike.angles - model_angles
    d_rates = mujoco_strike.rates - model_rates

    def summary(times, force, depth):
        trailing_off = np.flatnonzero(force[1:, 0] == 0.0)
        return {"peak_force": float(force[:, 1].max()), "pulse": impact_pulse(times, force[:, 1]),
                "max_penetration": float(depth[:, 1].max()), "end_penetration": float(depth[-1, 1]),
                "unloaded": int(np.sum(force[1:, 1] == 0.0)), "leaves": bool(np.any(depth[1:, 1] < 0.0)),
                "lift_off": float(times[1 + trailing_off[0]]) if len(trailing_off) else math.nan}

    return {"angles_end": d_angles[-1], "rates_end": d_rates[-1],
            "angles_max": np.abs(d_angles).max(axis=0), "rates_max": np.abs(d_rates).max(axis=0),
            "model": summary(strike.times, strike.normal_forces, strike.penetrations),
            "mujoco": summary(mujoco_strike.times, mujoco_strike.normal_forces, mujoco_strike.penetrations),
            "force_rms": float(np.sqrt(np.mean(
                (mujoco_strike.normal_forces[:, 1] - strike.normal_forces[:, 1]) ** 2)))}
