"""Measured walks whose physics lies outside the model's effect library (model/effects/).

``toywalk diagnose`` names the effect of its library that a walk has and the base model lacks.
These walks have physics that no effect of the library describes, so that what the analysis
says of them can be measured (docs/make_outside_validation.py) and tested
(tests/sysid/test_outside_walks.py). Each kind is one function ``walk(seed, ...) ->
TrajectoryTable`` in the trajectory format that ``toywalk simulate`` writes (docs/formats.md):
the four angles with white noise of ``noise`` rad and their ``*_sd`` columns, the stance foot's
contact point, the heel strikes after the start as events. The seed draws the noise and a small
perturbation of the start's rates, so a walk is the same for the same seed.

- :func:`contact_walk` (kind ``contact``): the clearing walker (data/params/clearing-toy.toml)
  in MuJoCo (:mod:`toywalk.model.mujoco_check`) with soft, overdamped contacts and a friction
  that lets the feet slip, settings no other test uses. The model's heel strike is an impulsive,
  plastic collision with rolling and no slip; here it is spread over milliseconds by a spring and
  damper, and the feet can slide.
- :func:`hinge_spring_walk` (kind ``hinge_spring``): the stable toy
  (data/params/stable-toy.toml) with a torsion spring between the legs, torque
  ``-k (theta_sw - theta_st)`` on the swing leg about the axle and its reaction on the stance
  leg (:class:`HingeSpring`). Conservative: the library has hinge friction (viscous and dry)
  but no hinge stiffness. The same physics is the port-only term ``hinge_stiffness`` of the
  dictionary of generalised forces at the walker's ports (docs/effects.md), which ``diagnose``
  does not try unless named: the walk stays outside its default causes. The test-only unit keeps
  its own name, so that its walks are made as before (tests/sysid/test_outside_walks.py checks the
  two agree).
- :func:`foot_profile_walk` (kind ``foot_profile``): the walk of ``contact`` on ellipsoid feet whose
  bottom has the torus's radii of curvature but whose fore-aft radius of curvature shortens along
  the rim (:func:`profile_axes`). The model's foot is a torus: one radius all round. Compared
  with the ``contact`` walk of the same seed, its verdict says what the profile adds.

Why each is built where it is
-----------------------------
The hinge spring is an effect unit like those of the library (:class:`HingeSpring`, its
``couples`` the hinge torque pair, as hip damping's), so that the model's own equations, gait
search and simulation walk it. But the parameter layout (:data:`toywalk.model.parameters.
PARAMETER_NAMES`) is frozen from the registry :data:`toywalk.model.effects.EFFECTS` when
``toywalk.model.parameters`` is imported, and the compiled libraries are cached under a digest of
the package's sources, not of the registry: an effect registered in a process that uses the cache
would load libraries of the wrong parameter layout, or write ones that other processes would
load. So the spring's walk is made in a fresh interpreter (:func:`_run_child`) with
``TOYWALK_JIT=0`` (CasADi's virtual machine: no library is read or written) and ``TOYWALK_CACHE``
in a temporary folder, which registers the unit before anything reads the registry, walks, and
writes the trajectory for this process to read. No test-only effect reaches this process's
registry or any cache.

The foot profile is built in MuJoCo: the foot is one ellipsoid geom there
(:func:`toywalk.model.mujoco_check.build_mjcf`, ``foot_axes``), so a foot of another shape is one
option of a build that is checked against the model (tests/model/test_mujoco.py), where in the
model the torus is written into the kinematics of the contact point (model/equations.py,
``_geometry`` and the contact travel), which no effect hook reaches. The walk then also carries
MuJoCo's soft contacts. At the checked settings (1 ms, critically damped, friction 2) the clearing
walker's MuJoCo walk is chaotic: a start changed by 1e-6 rad/s moves its pitches by 0.057 rad RMS
over 20 steps, more than a foot profile the walker survives does (aspect 0.5: 0.03 rad; stronger
profiles fell within 20 steps from most starts). With :data:`CONTACT`'s slipping feet the same
change moves them by 0.007 rad, every start walks, and the profile stands out: aspect 0.25 moves
the pitches by 0.017 rad RMS from the spheroid foot's walk (measured 2026-11-28, seed 0). So the
profile is walked with :data:`CONTACT`, and the test of the generator compares it with the
spheroid foot's walk at the same settings and start: the difference it measures is the profile's.

Shared settings
---------------
Walks are sampled at :data:`SAMPLE_RATE` (a camera's 120 frames per second), :data:`STEPS` heel
strikes, noise :data:`NOISE` (within the 0.002-0.004 rad of the tracker's measured range, docs/
diagnosis.md), start rates perturbed by :data:`START_SD`.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from functools import cache
from pathlib import Path

import numpy as np
from toywalk.model.effects.base import Effect
from toywalk.model.trajectory import SIGNALS, TrajectoryTable, read_trajectory, write_trajectory

__all__ = ["ASPECT", "CONTACT", "DATA", "KINDS", "NOISE", "SAMPLE_RATE", "STABLE_START", "START_SD",
           "STEPS", "STIFFNESS", "TIMESTEP", "HingeSpring", "OutsideWalkError", "clearing_gait",
           "contact_walk", "foot_profile_walk", "hinge_spring_gaits", "hinge_spring_walk", "perturbed",
           "profile_axes", "walk"]

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "data" / "params"
#: Samples per second: a camera's 120 frames per second.
SAMPLE_RATE = 120.0
#: Heel strikes walked: 20 gives 19 complete steps between strikes, within the 16-30 of the
#: analysis's validation walks, and 9 complete strides for its held-out folds.
STEPS = 20
#: Measurement noise on every angle (rad), white; the tracker's level is 0.002-0.004 rad.
NOISE = 0.003
#: Perturbation of the start's four rates (rad/s, normal): small against the gaits' rates (1 to 4
#: rad/s), so that the walks start near the gait, and large enough that seeds differ in their
#: noise-free angles too. In MuJoCo the clearing walker is fragile (docs/gaits.md section 4): the
#: seeds of the generators' tests and the validation were checked to complete their steps.
START_SD = 1e-3
#: MuJoCo's contacts for :func:`contact_walk`: time constant (s), damping ratio, friction. No other
#: test uses them (tests/model/test_mujoco.py: 1 ms, 1, friction 2). 0.8 ms is 9.6 integration steps
#: of 1/12000 s, within MuJoCo's "at least two"; damping ratio 1.5 is an overdamped contact (the
#: landing foot sinks and is stopped over milliseconds, not at an instant); friction 0.6 lets a
#: foot slide where the model's rolls. Of the grid 0.8/1.2/1.5 ms by 0.9/1/1.5 by 0.4/0.6/1, 0.8 ms
#: with 1.5 completed 24 steps from every one of four perturbed starts at every friction; the
#: underdamped 0.9 fell within a step at 0.8 ms (measured 2026-11-28).
CONTACT = {"contact_time": 8e-4, "damping_ratio": 1.5, "friction": 0.6}
#: MuJoCo's integration step (s): 100 a frame at 120 Hz (1 / sample_rate must be whole steps).
TIMESTEP = 1.0 / 12000.0
#: Hinge stiffness of :func:`hinge_spring_walk` (N m/rad): the stable toy's swing leg is a pendulum
#: of gravity stiffness m g |d_z| = 0.060 N m/rad about the hip, so 5e-3 makes it 8 % stiffer.
STIFFNESS = 5e-3
#: Aspect of :func:`foot_profile_walk`'s feet (:func:`profile_axes`): the fore-aft radius 14 % shorter
#: at the ends of the stance foot's roll. With :data:`CONTACT`, seeds 0 to 3 walk 20 steps (measured
#: 2026-11-28). Above 1 the radius grows by at most 5.6 %; an ellipsoid turned about the axle (its
#: radius growing towards the toe and shrinking towards the heel, ``foot_pitch`` of
#: :func:`toywalk.model.mujoco_check.build_mjcf`) by 0.03 rad fell within 8 steps from every start.
ASPECT = 0.25
#: The stable toy's gait (tests/model/test_research_gaits.py's Z_STABLE; its parameter file says
#: find_gait alone does not reach it), the start of the hinge spring's gait search (rad, rad/s).
STABLE_START = (0.04661788900461893, -0.5141677402083711, -0.001876783030565294, 0.021718470946236697,
                -0.08694501480362028, 4.231073000769995, 0.08135087368205376, 2.3913296604495535)
#: A fresh interpreter's walk may take this long (s) before it is given up (measured 2-3 s).
_CHILD_TIMEOUT = 600.0


class OutsideWalkError(RuntimeError):
    """A walk could not be made (the walker fell, no gait): the message says which and why."""


# ------------------------------------------------------------------------------------------ noise
def _measured(table: TrajectoryTable, rng: np.random.Generator, noise: float, seed) -> TrajectoryTable:
    """``table`` as a measurement: white noise of SD ``noise`` (rad) on the four angles and their
    ``*_sd`` columns, as ``toywalk simulate --noise`` writes them; the contact point and events
    as they are."""
    if not (math.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be a finite standard deviation >= 0 (rad), got {noise!r}")
    signals = dict(table.signals)
    for name in SIGNALS:
        clean = table.signals[name]
        signals[name] = clean + rng.normal(0.0, noise, clean.shape) if noise > 0 else clean
        if noise > 0:
            signals[f"{name}_sd"] = np.full(clean.shape, noise)
    metadata = dict(table.metadata, noise_sd=noise, seed=seed)
    return TrajectoryTable(table.time, signals, table.stance, table.events, metadata)


def perturbed(z0, rng: np.random.Generator, start_sd: float) -> np.ndarray:
    """``z0`` (shape (8,), a state just after a heel strike) with its four rates (public order:
    phi', psi', theta_st', theta_sw'; rad/s) perturbed by the next four normal draws of ``rng``
    of SD ``start_sd``: the start of every walk here."""
    z = np.array(z0, dtype=float)
    z[1::2] += rng.normal(0.0, start_sd, 4)
    return z


def _check_steps(steps: int) -> None:
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 2:
        raise ValueError(f"steps must be an integer >= 2 (heel strikes), got {steps!r}")


# ----------------------------------------------------------------------------------- (a) contacts
@cache
def clearing_gait():
    """The clearing walker and its gait (from the start its parameter file stores), found once a
    process (read only)."""
    from toywalk.model import Walker, load_params, solve_fixed_point

    params = load_params(DATA / "clearing-toy.toml")
    return solve_fixed_point(Walker(params), np.array(params.gait_start))


def _mujoco_walk(seed: int, steps: int, noise: float, start_sd: float, kind: str,
                 **build) -> TrajectoryTable:
    from toywalk.model.mujoco_check import mujoco_trajectory, walk_in_mujoco

    _check_steps(steps)
    rng = np.random.default_rng(seed)
    gait = clearing_gait()
    z0 = perturbed(gait.fixed_point, rng, start_sd)
    walk_ = walk_in_mujoco(gait.params, z0, steps=steps, timestep=TIMESTEP, sample_rate=SAMPLE_RATE,
                           **build)
    if walk_.status != "completed":
        raise OutsideWalkError(f"{kind} walk, seed {seed}: {walk_.status} after {walk_.steps} of "
                               f"{steps} steps ({walk_.message}); the clearing walker is fragile in "
                               "MuJoCo (docs/gaits.md section 4): try another seed or fewer steps")
    table = mujoco_trajectory(walk_, gait.params, parameters="clearing-toy.toml")
    table.metadata["outside"] = {"kind": kind, "start_sd": start_sd, **build,
                                 "model_step_time": gait.step_time,
                                 "step_times": walk_.step_times.tolist(), "scuffs": walk_.scuffs}
    return _measured(table, rng, noise, seed)


def contact_walk(seed: int, steps: int = STEPS, noise: float = NOISE, start_sd: float = START_SD,
                 contact_time: float = CONTACT["contact_time"],
                 damping_ratio: float = CONTACT["damping_ratio"],
                 friction: float = CONTACT["friction"]) -> TrajectoryTable:
    """The clearing walker in MuJoCo with soft, overdamped, slipping contacts (:data:`CONTACT`).

    Parameters
    ----------
    seed : int
        Draws the start's perturbation, then the noise.
    steps : int
        Heel strikes after the start.
    noise : float
        Noise SD on the angles (rad).
    start_sd : float
        SD of the start rates' perturbation (rad/s).
    contact_time, damping_ratio, friction
        MuJoCo's contact time constant (s), damping ratio and friction coefficient.

    Raises
    ------
    OutsideWalkError
        The walker fell before ``steps`` heel strikes.
    """
    return _mujoco_walk(seed, steps, noise, start_sd, "contact", contact_time=contact_time,
                        damping_ratio=damping_ratio, friction=friction)


# ------------------------------------------------------------------------------ (c) foot profile
def profile_axes(foot_radius: float, foot_lateral_radius: float, aspect: float) -> tuple[float, ...]:
    """Semi-axes (m) along (b1, b2, b3) of an ellipsoid foot with the torus's radii of curvature at
    its bottom, ``r`` fore-aft and ``rho`` sideways, and ``c / a = sqrt(aspect)``.

    An ellipse of semi-axes a (fore-aft) and c (up) has, where its normal makes the angle theta
    with the axis c, the radius of curvature ``a^2 c^2 / (c^2 cos^2 theta + a^2 sin^2
    theta)^(3/2)`` (``a^2 / c`` at the bottom). With ``c = aspect r``, ``a = sqrt(aspect) r``,
    ``b = sqrt(aspect r rho)``, the bottom's radii are ``r`` and ``rho`` for every aspect, and away
    from the bottom the fore-aft radius is ``r / (1 + (1/aspect - 1) sin^2 theta)^(3/2)``: at
    aspect 0.25 it is 14 % shorter at theta = 0.19 rad, the clearing walker's stance pitch just
    after heel strike: a sole flatter at the bottom than towards heel and toe. Aspect 1 is the
    spheroid of :func:`toywalk.model.mujoco_check.build_mjcf`'s default; above 1 the radius grows
    away from the bottom, to at most ``r / cos^3 theta`` (5.6 % longer at 0.19 rad).
    """
    if not (math.isfinite(aspect) and aspect > 0):
        raise ValueError(f"aspect must be a finite ratio > 0, got {aspect!r}")
    r, rho = foot_radius, foot_lateral_radius
    return math.sqrt(aspect) * r, math.sqrt(aspect * r * rho), aspect * r


def foot_profile_walk(seed: int, steps: int = STEPS, noise: float = NOISE, start_sd: float = START_SD,
                      aspect: float = ASPECT) -> TrajectoryTable:
    """The clearing walker in MuJoCo with :data:`CONTACT`'s contacts, on feet of
    :func:`profile_axes` (``aspect``; 1 is the spheroid foot, the walk of :func:`contact_walk`).

    Parameters and errors as :func:`contact_walk`.
    """
    params = clearing_gait().params
    axes = profile_axes(params.foot_radius, params.foot_lateral_radius, aspect)
    table = _mujoco_walk(seed, steps, noise, start_sd, "foot_profile", foot_axes=axes, **CONTACT)
    table.metadata["outside"]["aspect"] = aspect
    return table


# ------------------------------------------------------------------------------ (b) hinge spring
class HingeSpring(Effect):
    """A torsion spring between the legs: ``tau = -k (theta_sw - theta_st)`` on the swing leg about
    the axle, its reaction on the stance leg. Test-only: never in the library's registry (module
    docstring). Conservative: its power ``tau (theta_sw' - theta_st')`` is the rate of change of
    ``-k (theta_sw - theta_st)^2 / 2``, so between collisions the walker's energy plus that stored
    energy is constant."""

    name = "hinge_spring"
    unit = "N m/rad"
    null = 0.0
    typical = STIFFNESS
    bounds = (0.0, 1.0)
    enters = "equations of motion"
    physics = "hinge torsion spring: torque -k (theta_sw - theta_st) at the hip, reaction on the stance leg"

    def couples(self, k, ctx):
        tau = -k * (ctx.q4[3] - ctx.q4[2])
        return [(2, tau * ctx.n), (1, -tau * ctx.n)]


def _register() -> None:
    """Put :class:`HingeSpring` in the registry of this (fresh) interpreter, before anything has
    read it; refuses where that is not so, or where compiled libraries could be used."""
    if os.environ.get("TOYWALK_JIT") != "0":
        raise RuntimeError("the hinge spring is registered only with TOYWALK_JIT=0 (no compiled "
                           "library may see its parameter layout)")
    frozen = [m for m in ("toywalk.model.parameters", "toywalk.model.equations", "toywalk.model.walker",
                          "toywalk.model.simulate") if m in sys.modules]
    if frozen:
        raise RuntimeError(f"the hinge spring must be registered before {', '.join(frozen)} is "
                           "imported: it reads the registry once")
    from toywalk.model import effects

    unit = HingeSpring()
    effects.EFFECTS[unit.name] = unit
    effects.CONTINUOUS = (*effects.CONTINUOUS, unit.name)


def _child(spec: dict) -> None:
    """The fresh interpreter's job (:func:`_run_child`): register the spring, find the gaits with
    and without it, walk, check its energy over the first step, and write the trajectory and a
    summary (JSON) where ``spec`` says."""
    _register()
    from toywalk.model import Walker, load_params, solve_fixed_point
    from toywalk.model.effects import CONTINUOUS
    from toywalk.model.simulate import simulate

    base = load_params(DATA / "stable-toy.toml")
    k = spec["stiffness"]
    params = base.replace(**{"effects.hinge_spring": k})
    gait0 = solve_fixed_point(Walker(base), np.array(STABLE_START))
    walker = Walker(params)
    gait = solve_fixed_point(walker, gait0.fixed_point) if k != 0 else gait0
    summary = {"stiffness": k, "step_time": gait.step_time, "step_time_without": gait0.step_time,
               "fixed_point": gait.fixed_point.tolist(), "max_abs_eigenvalue": gait.max_abs_eigenvalue}
    rng = np.random.default_rng(spec["seed"])
    z0 = perturbed(gait.fixed_point, rng, spec["start_sd"]) if spec["perturb"] else gait.fixed_point
    # Energy over the first step, between the collisions: kinetic + gravitational (the model's
    # energy output, which does not know the spring) and the spring's k (theta_sw - theta_st)^2 / 2.
    step = walker.step(z0, record=True)
    energy = np.array([walker.energy(x) for x in step.states])
    stored = 0.5 * k * (step.states[:, 3] - step.states[:, 2]) ** 2
    summary["energy"] = {"mechanical_range": float(np.ptp(energy)), "stored_range": float(np.ptp(stored)),
                         "total_drift": float(np.max(np.abs(energy + stored - energy[0] - stored[0]))),
                         "spring_dissipated": float(step.dissipated[-1][CONTINUOUS.index("hinge_spring")]),
                         "stored_change": float(stored[-1] - stored[0]),
                         "taken_minus_stored": float(np.max(np.abs(
                             step.dissipated[:, CONTINUOUS.index("hinge_spring")] - (stored - stored[0]))))}
    traj = simulate(params, z0, spec["steps"], sample_rate=spec["sample_rate"])
    summary["status"], summary["message"] = traj.status, traj.message
    signals = traj.angles()
    signals["contact_x"], signals["contact_y"] = traj.contact[:, 0], traj.contact[:, 1]
    events = [{"time": e.time, "foot": e.foot, "x": e.x, "y": e.y} for e in traj.events]
    metadata = {"source": {"kind": "simulation", "parameters": "stable-toy.toml",
                           "effects": {}, "steps": spec["steps"],
                           "start": "gait fixed point" + (", rates perturbed" if spec["perturb"] else ""),
                           "planar": False},
                "units": {"time": "s", "angles": "rad", "contact": "m"},
                "timestamps": "exact simulation times, uniform sampling",
                "status": traj.status, "message": traj.message, "scuffs": traj.scuffs,
                "outside": {"kind": "hinge_spring", "start_sd": spec["start_sd"], **summary}}
    write_trajectory(TrajectoryTable(traj.times, signals, traj.stance, events, metadata), spec["out"])
    Path(spec["summary"]).write_text(json.dumps(summary))


def _run_child(spec: dict) -> tuple[TrajectoryTable, dict]:
    """Run :func:`_child` in a fresh interpreter (module docstring); its trajectory and summary."""
    with tempfile.TemporaryDirectory(prefix="toywalk-outside-") as tmp:
        spec = dict(spec, out=str(Path(tmp) / "walk.csv"), summary=str(Path(tmp) / "summary.json"))
        env = dict(os.environ, TOYWALK_JIT="0", TOYWALK_CACHE=str(Path(tmp) / "cache"))
        code = (f"import json, sys; sys.path.insert(0, {str(ROOT)!r}); from tests.sysid import outside; "
                "outside._child(json.loads(sys.argv[1]))")
        run = subprocess.run([sys.executable, "-c", code, json.dumps(spec)], env=env, capture_output=True,
                             text=True, timeout=_CHILD_TIMEOUT)
        if run.returncode != 0:
            tail = (run.stderr.strip().splitlines() or ["no message"])[-1]
            raise OutsideWalkError(f"the hinge spring's walk failed (exit {run.returncode}): {tail}")
        return read_trajectory(spec["out"]), json.loads(Path(spec["summary"]).read_text())


def hinge_spring_gaits(stiffness: float = STIFFNESS, steps: int = STEPS, seed: int = 0,
                       perturb: bool = False) -> tuple[TrajectoryTable, dict]:
    """The hinge spring's noise-free walk and its summary: gait step times with and without the
    spring (s), the fixed point, and over the first step the mechanical energy's range, the
    spring's stored energy's range, the drift of their sum (J), and the energy the model's
    dissipation output says the spring took against the change of its stored energy (J)."""
    _check_steps(steps)
    if not (math.isfinite(stiffness) and 0 <= stiffness <= 1):
        raise ValueError(f"stiffness must be in [0, 1] N m/rad, got {stiffness!r}")
    return _run_child({"stiffness": float(stiffness), "steps": steps, "seed": seed, "perturb": perturb,
                       "start_sd": START_SD, "sample_rate": SAMPLE_RATE})


def hinge_spring_walk(seed: int, steps: int = STEPS, noise: float = NOISE, start_sd: float = START_SD,
                      stiffness: float = STIFFNESS) -> TrajectoryTable:
    """The stable toy with a hinge spring of ``stiffness`` (N m/rad), simulated by the model's own
    equations with :class:`HingeSpring` in a fresh interpreter (module docstring).

    Parameters and errors as :func:`contact_walk`.
    """
    _check_steps(steps)
    table, summary = _run_child({"stiffness": float(stiffness), "steps": steps, "seed": seed,
                                 "perturb": True, "start_sd": start_sd, "sample_rate": SAMPLE_RATE})
    if summary["status"] != "completed":
        raise OutsideWalkError(f"hinge spring walk, seed {seed}: {summary['message']}")
    # The child drew the start's perturbation from the seed's first draws; the noise follows them.
    rng = np.random.default_rng(seed)
    rng.normal(0.0, start_sd, 4)
    return _measured(table, rng, noise, seed)


#: The kinds, by name, and their generators.
KINDS = {"contact": contact_walk, "hinge_spring": hinge_spring_walk, "foot_profile": foot_profile_walk}


def walk(kind: str, seed: int, **options) -> TrajectoryTable:
    """A walk of ``kind`` (:data:`KINDS`) for ``seed``; ``options`` go to its generator."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    return KINDS[kind](seed, **options)
