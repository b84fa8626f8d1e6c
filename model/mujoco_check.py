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
ramp, ahead of the other foot's, is a heel strike; any other new contact of a foot is a scuff.

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

from .files import software_version as _version
from .kinematics import angles_from_rotations, leg_poses, rotation
from .parameters import PARAMETER_NAMES, Params
from .trajectory import SIGNALS, TrajectoryTable
from .walker import STATE_NAMES

__all__ = ["MujocoWalk", "build_mjcf", "initial_state", "mujoco_trajectory", "walk_in_mujoco"]

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
# The contact model's other settings, written into the MJCF and into a trajectory's metadata.
# solimp (0.99, 0.999, 0.1 mm): the constraint's impedance, 0.99 at first touch rising to 0.999 at
# 0.1 mm of penetration. Elliptic friction cones with impratio 10 and MuJoCo's no-slip pass (10
# iterations) hold the rolling foot's contact nearly still where the model's rolls without slip:
# it creeps 15 um sideways and 3 um along in a step of the clearing walker (measured,
# tests/model/test_mujoco.py).
_SOLIMP = (0.99, 0.999, 0.0001)
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
               foot_axes=None, foot_pitch: float = 0.0) -> str:
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
    if not 4 * timestep <= contact_time:
        raise ValueError(f"timestep must be at most a quarter of the contact time constant "
                         f"{contact_time} s, got {timestep}")
    solver = " ".join(f'{key}="{value}"' for key, value in _SOLVER.items())
    return f"""<mujoco model="toywalk">
  <compiler angle="radian"/>
  <option timestep="{timestep!r}" gravity="{grav[0]!r} {grav[1]!r} {grav[2]!r}" {solver}/>
  <default><geom solref="{contact_time!r} {damping_ratio!r}" solimp="{_num(_SOLIMP)}"/></default>
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
        length, the same foot struck twice running, or the time ran out first; ``message`` says
        which).
    message : str
    strikes : ndarray, shape (n, 3)
        Heel strikes: time (s), the landing foot's contact position along the ramp and across it (m).
    feet : list of str
        The landing foot of each heel strike, 'L' or 'R'.
    scuffs : int
        New contacts of a foot that were not heel strikes (the swing foot touching the ramp).
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

    @property
    def lean(self) -> np.ndarray:
        """Lean psi at the samples (rad), shape (n_samples,)."""
        return self.angles[:, 0]

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
                   damping_ratio: float = 1.0, foot_axes=None, foot_pitch: float = 0.0) -> MujocoWalk:
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
    contact_time, damping_ratio, foot_axes, foot_pitch
        The contacts' time constant (s) and damping ratio, the foot's semi-axes (m) and turn
        (rad), as in :func:`build_mjcf`; the defaults are the build checked against the model.

    Returns
    -------
    MujocoWalk
    """
    mujoco = _require_mujoco()
    z0 = np.asarray(z0, dtype=float)
    if z0.shape != (8,) or not np.all(np.isfinite(z0)):
        raise ValueError(f"z0 must be a finite state of 8 components, got {z0!r}")
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
        build_mjcf(params, timestep, friction, contact_time, damping_ratio, sole.axes, sole.pitch))
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

    def sample() -> None:
        stance = landed[-1] if landed else "L"
        rot = {k: data.xmat[b].reshape(3, 3) for k, b in bodies.items()}
        steer, lean, pitch_left, pitch_right = angles_from_rotations(rot["L"], rot["R"])
        low = (_foot_position(data, model, bodies[stance], params, sole)
               + _lowest_offset(params, rot[stance], sole))
        samples.append((data.time, lean, steer, pitch_left, pitch_right, low[0], low[1]))
        stances.append(stance)

    scuffs, n_step = 0, 0
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
                if pos[0] > _foot_position(data, model, bodies[other], params, sole)[0]:
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
                "solimp": list(_SOLIMP), **_SOLVER, "condim": 3, "sample_rate": sample_rate}
    if foot_axes is not None or foot_pitch:
        settings["foot_axes"], settings["foot_pitch"] = list(sole.axes), sole.pitch
    return MujocoWalk(status=status, message=message, strikes=arr, feet=landed, scuffs=scuffs,
                      steps=n_alt - 1, step_times=np.diff(good[:, 0]), step_lengths=np.diff(good[:, 1]),
                      duration=float(data.time), times=table[:, 0], angles=table[:, 1:5],
                      stance=np.array(stances), contact=table[:, 5:7], start=z0.copy(),
                      settings=settings)


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
        "events": "a foot's first contact after 2 ms off the ramp, ahead of the other foot's; its "
                  "time to one integration step, its position MuJoCo's contact point",
        "status": walk.status, "message": walk.message, "scuffs": walk.scuffs,
        "software": _version(),
    }
    return TrajectoryTable(walk.times, signals, walk.stance, events, metadata)
