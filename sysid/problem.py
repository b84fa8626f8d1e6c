"""The fit problem: one walk's gait BVP and its data in one IPOPT problem, set up, solved and read.

The unknowns are the periodic gait's collocation variables ``w`` (model/collocation.py), the
free parameters ``theta`` (any names of :data:`toywalk.model.parameters.PARAMETER_NAMES`, effect
strengths included) and the nuisance offsets ``o`` (:data:`toywalk.sysid.measurement.OFFSETS`).
The problem is

    minimise   1/2 sum_i ((A w + B o - y)_i / sigma_i)^2 + 1/2 sum_k ((T_k(w) - d_k) / sigma_k)^2
               + 1/2 sum_j ((c_j(w, theta, o) - p_j) / sigma_j)^2
    subject to g(w, theta) = 0    (collocation, guard, periodicity with the collision)
               theta within its physical bounds

with ``A``, ``B`` the measurement model's linear operators, ``y`` the measured angles, ``d`` the
measured step durations (or strike times), and, where the events file has them, ``p`` the measured
contact positions at heel strikes and ``c`` the model's (each step's advance, rolled and jumped at
the collision, :func:`toywalk.model.collocation.step_displacements`, from an unknown origin;
:mod:`toywalk.sysid.measurement`). Because the gait is a constraint, not
a forward simulation, the fit works for gaits too unstable to simulate (Biegler, *Nonlinear
Programming*, SIAM 2010, ch. 10; the simultaneous approach of opty, Moore & van den Bogert 2018).

:func:`setup` checks the request and the data and builds the problem (:class:`FitProblem`) with a
start on the BVP; :meth:`FitProblem.solve` solves it from the measured strikes to the model's
(:data:`STAGE_PATH`), :meth:`FitProblem.result` reads a solution as a
:class:`~toywalk.sysid.fitresult.FitResult`, and :func:`continued` starts a problem from an
earlier fit. The one-walk fit (:func:`toywalk.sysid.fit.fit`) and the joint fit of several walks
(:func:`toywalk.sysid.walks.fit_walks`, which joins the walks' problems by :attr:`FitProblem.nlp_fn`
into one NLP) are both built on this interface, with the same IPOPT options
(:func:`ipopt_options`) and noise SDs (:func:`sigma_from`, :func:`contact_sigma`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cache, cached_property

import casadi as ca
import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from toywalk.model.collocation import BVP, bvp, contact_travel, cycle_jacobian, initial_guess, strike_phase
from toywalk.model.effects import EFFECTS
from toywalk.model.gait import GaitNotFound, find_gait, lateral_singular, solve_fixed_point
from toywalk.model.parameters import INPUT_NAMES, PARAMETER_NAMES, ParameterError, Params
from toywalk.model.trajectory import SIGNALS, TrajectoryTable
from toywalk.model.walker import STATE_NAMES, StepFailure, Walker, is_planar_symmetric

from .fitresult import FitResult
from .measurement import (
    OFFSETS,
    POSITION_NUISANCES,
    MeasurementError,
    Observations,
    Path,
    Timing,
    first_side,
    model_steps,
    observations,
    offsets_design,
    path,
    timing,
)
from .residuals import NOISE_INFLATION, scatter_noise, shared_errors

__all__ = ["ALONE", "CONTACT_KEYS", "MODELS", "STAGE_PATH", "FitError", "FitProblem", "check_request",
           "contact_sigma", "continued", "estimates_only", "fit_bounds", "fit_line", "gait_period",
           "ipopt_options", "parameter_bounds", "setup", "shared_covariance", "sigma_from", "stacked", "tied",
           "whitened_loads", "with_values"]

#: The effect a fit takes only on the seed's walker, no other effect on or free beside it: the
#: compliant heel strike (docs/soft_feet.md section 5).
ALONE = "effects.soft_heel"
#: The models of a walk :func:`toywalk.sysid.fit.fit` knows.
MODELS = ("periodic", "transient")
#: Default collocation mesh (intervals per step, degree) of each model (:func:`toywalk.sysid.fit.fit`).
_MESH = {"periodic": (30, 4), "transient": (12, 3)}

#: The stages (0: aligned on the measured strikes, 1: on the model's; between, the residuals'
#: blend) a fit goes through from its aligned solution to the model's strikes, each solved from
#: the last. Where the model misses the walk's period, the model's clock drifts through the walk
#: and the misfit on its strikes has several minima; in one jump from the aligned solution IPOPT
#: took large steps into them or out of the gait (measured, stable-toy, 10 steps, trailing share
#: 0.1 hidden, two free parameters, from the aligned solution: with 0.002 rad noise a restoration
#: failure in one jump, chi-square 4.0e3 through (0.5, 1); without noise chi-square 1.0e4 in one
#: jump, 6.2e3 through (0.5, 1), 197 through this path; with 0.01 rad noise 6.9e3 by all three).
STAGE_PATH = (0.25, 0.5, 0.75, 1.0)
#: Contact-position SD (m) assumed for a fit's first pass when neither the file nor ``noise_sd``
#: gives one (:func:`contact_sigma`): a millimetre, a tracker's error on a toy filmed whole.
_FIRST_PASS_CONTACT_SD = 1e-3
#: Keys of the contact positions' SDs (m) in ``noise_sd`` and ``residual_rms``.
CONTACT_KEYS = ("contact_x", "contact_y")
#: Phase bins of the residual summary.
_PHASE_BINS = 10
#: Identifiability: a direction of the free parameters (scaled to unit column norms) whose
#: singular value is below this fraction of the largest is reported as not determined.
_NEAR_SINGULAR = 1e-6
#: A reported unknown whose squared loading on those directions exceeds this (a component of 0.1,
#: as the warning's combination shows) is not determined: no standard error (NaN).
_UNDETERMINED_SHARE = 0.01
#: Newton's re-solve of the BVP for the Jacobian check (``FitProblem._resolve``): at most this many
#: steps, done when every equality is within the BVP solver's own constraint tolerance (1e-12).
_NEWTON_STEPS, _NEWTON_TOL = 10, 1e-12
#: Newton steps taken after the equalities are within that tolerance (``FitProblem._resolve``).
_POLISH = 2
#: A transient fit holds the model's heel-strike times as unknowns (``FitProblem``); False reads
#: them through the step durations, the naive way benchmarks/transient_speed.py times beside it.
_CLOCK_LIFTED = True


def _misfit_note(obs: Observations, rms: dict, stated: dict | None = None) -> str:
    """What to say when the residuals are mostly the model's misfit (empty when they are not):
    the signals whose residual RMS is more than :data:`toywalk.sysid.residuals.NOISE_INFLATION`
    times their noise SD, ``stated`` (given, or the file's, an RMS per signal), else their
    samples' own scatter within steps (:func:`toywalk.sysid.residuals.scatter_noise`, the larger
    of its every-sample and alternate-sample values: noise a tracker smoothed is larger than its
    every-sample scatter says, a fast pitch's curvature makes the alternate one larger than the
    noise), the noise then being taken from the residuals, misfit and all. Measured: a 10-step
    stable-toy walk with a trailing share of 0.1 the model lacks, 0.002 rad of noise: pitch
    residuals 2.5 times their scatter; 60 steps of it: steer and pitches 15-17 times, the fit
    (``--model periodic``) ending with a pitch offset of 3 degrees; in each case standard errors
    as if the model fitted."""
    if stated is None:
        reference = {n: float(np.nanmax([v["sd"], v["sd_alternate"]])) for n, v in scatter_noise(obs).items()}
        against = "the samples' scatter within steps"
    else:
        reference, against = stated, "the noise SDs stated"
    over = [f"{name} {rms[name] / sd:.2g}" for name, sd in reference.items()
            if name in rms and sd > 0 and rms[name] > NOISE_INFLATION * sd]
    if not over:
        return ""
    held = "the noise SDs taken from the residuals hold that misfit, and " if stated is None else ""
    return (f"the residual RMS is many times {against} ({', '.join(over)} times): the model misses "
            f"the walk, {held}the standard errors assume there is no misfit; `toywalk diagnose` "
            "looks for what the model lacks")


def ipopt_options(max_iter: int) -> dict:
    """IPOPT's options for a fit's NLP, one walk's or several walks' joined
    (:func:`toywalk.sysid.walks.fit_walks`): silent, converged to 1e-10 (the fit's Jacobian and
    covariance are read at the optimum), at most ``max_iter`` iterations."""
    return {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-10,
            "ipopt.max_iter": max_iter}



# Parameters that must stay inside (low, high); lengths and masses are >= 0.
_BASE_BOUNDS = {
    "leg_length": (0.0, math.inf), "foot_radius": (0.0, math.inf),
    "foot_lateral_radius": (0.0, math.inf), "hip_width": (0.0, math.inf),
    "leg_mass": (0.0, math.inf), "axle_mass": (0.0, math.inf), "slope": (-math.pi / 2, math.pi / 2),
    "gravity": (0.0, math.inf), "inertia[0]": (0.0, math.inf), "inertia[1]": (0.0, math.inf),
    "inertia[2]": (0.0, math.inf),
}


class FitError(ValueError):
    """The fit cannot be set up (bad names, unusable data, no starting gait)."""



# --------------------------------------------------------------------------------- set-up
def _check_free(params: Params, free) -> list[str]:
    names = list(free)
    for name in names:
        if name not in PARAMETER_NAMES:
            raise FitError(f"cannot fit {name!r}: not a parameter; names are those of a parameter "
                           f"file ({', '.join(PARAMETER_NAMES[:3])}, ..., com_offset[1], "
                           "effects.hip_damping, ...)")
    if len(set(names)) != len(names):
        raise FitError(f"a parameter is named twice in {names}")
    # The compliant heel strike is the seed's walker's (docs/soft_feet.md section 5).
    if ALONE in names or params.get(ALONE) != 0.0:
        others = sorted({n for n in names if n.startswith("effects.") and n != ALONE}
                        | {f"effects.{n}" for n in params.active_effects if f"effects.{n}" != ALONE})
        if others:
            raise FitError(f"cannot fit {ALONE} with {', '.join(others)}: the compliant heel "
                           "strike models the seed's walker; leave the other effects at their null "
                           "values and out of the free parameters")
    return names


def _check_priors(priors: dict, free: list[str], params: Params) -> dict:
    """Priors as ``name -> (mean, sd)``, each on a free parameter, with a positive SD and a mean
    that the fit's bounds allow (a measured value outside them is a mistake: a sign or a unit)."""
    out = {}
    for name, value in priors.items():
        if name not in free:
            raise FitError(f"a prior on {name!r}, which is not free (free: {', '.join(free)})")
        try:
            mean, sd = (float(v) for v in value)
        except (TypeError, ValueError) as err:
            raise FitError(f"the prior on {name} must be (mean, sd), got {value!r}") from err
        if not (math.isfinite(mean) and math.isfinite(sd) and sd > 0):
            raise FitError(f"the prior on {name} needs a finite mean and a positive sd, got {value!r}")
        low, high = fit_bounds(params, free, name)
        if not low <= mean <= high:
            raise FitError(f"the prior on {name} has its mean {mean:g} outside the parameter's "
                           f"bounds [{low:g}, {high:g}]")
        out[name] = (mean, sd)
    return out


def parameter_bounds(params: Params, name: str) -> tuple[float, float]:
    """The physical bounds of a parameter-file name (effects: their declaration; lengths and
    masses non-negative; foot radii below the leg length; slope within +-pi/2)."""
    if name.startswith("effects."):
        return EFFECTS[name.split(".", 1)[1]].bounds
    low, high = _BASE_BOUNDS.get(name, (-math.inf, math.inf))
    if name in ("foot_radius", "foot_lateral_radius"):
        high = params.leg_length * (1 - 1e-9)
    return low, high


def tied(params: Params, free) -> dict[str, str]:
    """Parameters that follow a free one, ``{follower: leader}``.

    A spherical foot stays a sphere: when ``foot_radius`` is free and ``foot_lateral_radius`` is
    not, and the walker's foot is a sphere (rho = r, the seed's point foot r = rho = 0 included),
    the sideways radius moves with the fore-aft one. Freed alone it could only grow into a torus
    with a sharp rim (rho fixed), which is not what a foot radius "held at the wrong value" means;
    free ``foot_lateral_radius`` too to let the two part."""
    free = list(free)
    if ("foot_radius" in free and "foot_lateral_radius" not in free
            and params.foot_lateral_radius == params.foot_radius):
        return {"foot_lateral_radius": "foot_radius"}
    return {}


def with_values(params: Params, free, values: dict) -> Params:
    """``params`` with the free parameters at ``values`` (and what follows them: :func:`tied`)."""
    values = dict(values)
    for follower, leader in tied(params, free).items():
        values[follower] = values[leader]
    return params.replace(**values)


def fit_bounds(params: Params, free, name: str) -> tuple[float, float]:
    """The fit's bounds on a free parameter: its physical bounds (:func:`parameter_bounds`), and
    a foot radius bounded by the other when only one of the two is free and the foot is not a
    sphere (docs/model.md section 2: the sideways radius never exceeds the fore-aft one; when both are
    free a constraint keeps them in order; a sphere's radii move together, :func:`tied`)."""
    low, high = parameter_bounds(params, name)
    if name == "foot_radius" and "foot_lateral_radius" not in free and not tied(params, free):
        low = max(low, params.foot_lateral_radius)
    if name == "foot_lateral_radius" and "foot_radius" not in free:
        high = min(high, params.foot_radius)
    return low, high


def _scale(params: Params, name: str) -> float:
    """A magnitude for each free parameter, so that IPOPT sees unknowns of order one."""
    value = abs(params.get(name))
    if name.startswith("effects."):
        return max(value, abs(EFFECTS[name.split(".", 1)[1]].typical))
    if name.startswith("inertia"):
        return max(value, 0.01 * max(abs(v) for v in params.inertia) or 1e-6)
    if name in ("slope",):
        return max(value, 0.01)
    if name in ("leg_mass", "axle_mass"):
        return max(value, 0.1 * params.total_mass)
    return max(value, 0.01 * params.leg_length)  # lengths


def gait_period(params: Params, free) -> int:
    """Steps per period of the gait to fit: 2 when the walker or a free effect breaks the mirror
    symmetry, else 1."""
    breaking = any(n.startswith("effects.") and EFFECTS[n.split(".", 1)[1]].breaks_symmetry for n in free)
    return 2 if breaking or params.breaks_symmetry else 1


_PLANAR_BREAKERS = {"com_offset[1]", "inertia[3]", "inertia[5]", "hip_width", "effects.cross_slope"}


def _start(params: Params, period: int, free: list[str], z_guess):
    """The starting gait: planar only when the walker is and stays planar (a point-mass limit)."""
    try:
        gait = find_gait(params) if z_guess is None else None
        planar = gait.planar if gait is not None else (is_planar_symmetric(params)
                                                        and lateral_singular(params))
        if planar and _PLANAR_BREAKERS & set(free):
            raise FitError("this walker is solved in its planar reduction (a point-mass limit): "
                           f"{sorted(_PLANAR_BREAKERS & set(free))} cannot be fitted")
        z0 = gait.fixed_point if gait is not None else np.asarray(z_guess, float)
        walker = Walker(params, planar=planar, period=period)
        if gait is None or gait.period != period:
            gait = solve_fixed_point(walker, z0)
    except GaitNotFound as err:
        raise FitError(f"no gait for the starting parameters: {err}") from err
    return walker, gait


@cache
def _equality_jacobians(prob: BVP) -> ca.Function:
    """``(w, p) -> (dg/dw, dg/dp)`` of the BVP's equality constraints."""
    w = ca.MX.sym("w", prob.phases * prob.phase_size)
    p = ca.MX.sym("p", len(INPUT_NAMES))
    g = prob.constraints(w, p)[:prob.n_equalities]
    return ca.Function("bvp_jac", [w, p], [ca.jacobian(g, w), ca.jacobian(g, p)])


@cache
def _travel_jacobians(prob: BVP) -> ca.Function:
    """``(w, p) -> (d rolled/dw, d rolled/dp, d jump/dw, d jump/dp)`` of
    :func:`toywalk.model.collocation.contact_travel`'s outputs (column-major, as the fit's
    unknowns)."""
    w = ca.MX.sym("w", prob.phases * prob.phase_size)
    p = ca.MX.sym("p", len(INPUT_NAMES))
    rolled, jump = (ca.vec(m) for m in contact_travel(prob)(w, p))
    return ca.Function("travel_jac", [w, p], [ca.jacobian(rolled, w), ca.jacobian(rolled, p),
                                              ca.jacobian(jump, w), ca.jacobian(jump, p)])


@cache
def _interval_sums(prob: BVP) -> sp.csr_matrix:
    """Sums each step's interval travels (column-major (2, phases * n_int)) into its
    displacement (column-major (2, phases)), shape (2 phases, 2 phases n_int)."""
    rows = np.repeat(np.arange(2 * prob.phases).reshape(prob.phases, 2), prob.n_int, axis=0).ravel()
    return sp.csr_matrix((np.ones(len(rows)), (rows, np.arange(len(rows)))),
                         shape=(2 * prob.phases, 2 * prob.phases * prob.n_int))


def _sparse(m: ca.DM) -> sp.csc_matrix:
    col_ptr, row_idx = (np.array(v) for v in m.sparsity().get_ccs())
    return sp.csc_matrix((np.array(m.nonzeros()), row_idx, col_ptr), shape=m.shape)



def setup(table: TrajectoryTable, params: Params, free, *, model, offsets, n_intervals, degree,
           z_guess, max_iter, check_jacobian, priors, strikes, w_start=None, say=None):
    """The fit's NLP (:class:`FitProblem`) and a start ``w0`` on the BVP (``w_start`` when given,
    else the starting gait solved on the BVP); ``say`` is given the fit's line once the request
    and the data are checked, before the starting gait is searched and the NLP built."""
    free, priors, obs = check_request(table, params, free, priors, strikes)
    if model not in MODELS:
        raise FitError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    if say is not None:
        say(f"{fit_line(model, strikes)}, {obs.n_steps} steps")
    period = gait_period(params, free)
    walker, gait = _start(params, period, free, z_guess)
    planar = walker.planar
    side = first_side(obs)
    n_intervals = n_intervals or _MESH[model][0]
    degree = degree or _MESH[model][1]
    soft = ALONE in free or params.get(ALONE) != 0.0
    if model == "periodic":
        prob = bvp(planar, n_intervals, degree, period, soft=soft)
        side, z_first = 1, gait.fixed_point
    else:
        prob = bvp(planar, n_intervals, degree, obs.n_steps, periodic=False, soft=soft)
        # A stride's fixed point starts with the left leg in stance; a walk that starts on the
        # right starts one step later.
        z_first = gait.fixed_point if side == 1 or period == 1 else \
            walker.step(gait.fixed_point, side=1).z_plus
    tm = timing(obs, prob, planar)
    b_op = offsets_design(obs) if offsets else np.zeros((len(obs.value), len(OFFSETS)))
    model_step = model_steps(obs, prob.phases, prob.periodic)
    w0 = _feasible_start(prob, walker, z_first, side) if w_start is None else np.asarray(w_start, float)
    pth = path(obs, prob.phases, prob.periodic)
    problem = FitProblem(prob, walker, free, obs, tm, b_op, model_step, offsets, max_iter,
                       check_jacobian, priors, side, strikes, pth)
    problem.options = {"model": model, "offsets": offsets, "n_intervals": n_intervals,
                       "degree": degree, "strikes": strikes, "max_iter": max_iter}
    return problem, w0


def check_request(table: TrajectoryTable, params: Params, free, priors,
             strikes) -> tuple[list, dict, Observations]:
    """The request and the data checked, before any fit says a line or searches a gait: the free
    names, the priors and the walk's observations (:class:`FitError` naming what is wrong)."""
    if not isinstance(params, Params):
        raise TypeError(f"params must be a Params, got {type(params).__name__}")
    free = _check_free(params, free)
    priors = _check_priors(priors or {}, free, params)
    if strikes not in ("model", "measured"):
        raise FitError(f"strikes must be 'model' or 'measured', got {strikes!r}")
    try:
        obs = observations(table)
    except MeasurementError as err:
        raise FitError(str(err)) from err
    return free, priors, obs


def contact_sigma(pth: Path, noise_sd: dict | None) -> tuple[np.ndarray, str]:
    """The contact positions' SDs, x rows then y rows (shape (2 n_pos,), m), and their source:
    ``noise_sd``'s :data:`CONTACT_KEYS` when it has them, else the events file's ``x_sd, y_sd``,
    else a first guess to be replaced by the residuals' RMS ("estimated from residuals")."""
    if not pth.n:
        return np.zeros(0), "none"
    if noise_sd is not None and all(k in noise_sd for k in CONTACT_KEYS):
        values = [noise_sd[k] for k in CONTACT_KEYS]
        if not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in values):
            raise FitError(f"noise_sd needs positive SDs (m) for {', '.join(CONTACT_KEYS)}, got {values}")
        return np.repeat(np.asarray(values, float), pth.n), "given"
    if np.all(np.isfinite(pth.sd)):
        return np.r_[pth.sd[:, 0], pth.sd[:, 1]], "file"
    return np.full(2 * pth.n, _FIRST_PASS_CONTACT_SD), "estimated from residuals"


def sigma_from(noise_sd: dict, obs: Observations) -> np.ndarray:
    """Per-observation SDs from one SD per signal."""
    sigma = np.empty(len(obs.value))
    for s_i, name in enumerate(SIGNALS):
        sel = obs.signal == s_i
        if np.any(sel):
            value = noise_sd.get(name) if isinstance(noise_sd, dict) else None
            if value is None or not (math.isfinite(value) and value > 0):
                raise FitError(f"noise_sd needs a positive SD for {name}, got {value!r}")
            sigma[sel] = max(float(value), 1e-9)
    return sigma


def _feasible_start(prob: BVP, walker: Walker, z0: np.ndarray, side: int) -> np.ndarray:
    """BVP unknowns of the starting gait (simulated steps, polished by the BVP solver)."""
    w = initial_guess(walker, z0, prob, side)
    sol = prob.solver(x0=w, p=walker.params.input_vector(side), lbg=prob.lbg, ubg=prob.ubg)
    if not prob.solver.stats()["success"]:
        raise FitError(f"the starting gait does not solve the BVP ({prob.solver.stats()['return_status']})")
    return np.array(sol["x"]).ravel()


class FitProblem:
    """One walk's fit NLP (module docstring), built by :func:`setup` once per fit: its CasADi
    functions (:attr:`nlp_fn`, residuals and their Jacobian), bounds, the IPOPT solver
    (:attr:`solver`, built when first asked for), and the readings of a solution (estimates,
    residuals, the Jacobian through the BVP, :meth:`result`). The one-walk fit solves it
    (:meth:`solve`); the joint fit of several walks joins several through :attr:`nlp_fn`."""

    def __init__(self, prob: BVP, walker: Walker, free, obs: Observations, tm: Timing, b_op,
                 model_step, offsets: bool, max_iter: int, check_jacobian: bool, priors: dict,
                 side: int, strikes: str, pth: Path):
        params = walker.params
        self.prob, self.planar, self.params, self.free, self.obs = prob, walker.planar, params, free, obs
        self.walker, self.side = walker, side
        # A transient's start: the first step's state, all but one component independent (the
        # one the start condition h(x_0) = 0 fixes, chosen where it is best conditioned).
        self.start_cols = np.arange(prob.state_index(0, 0, 0), prob.state_index(0, 0, 0) + prob.n_dyn)
        self.start_free = np.zeros(0, dtype=int)
        self.check_jacobian, self.priors = check_jacobian, priors
        # Prior rows: (theta_j - mean) / sd for each free parameter with a prior.
        self.prior_index = [free.index(n) for n in priors]
        self.prior_mean = np.array([priors[n][0] for n in priors])
        self.prior_sd = np.array([priors[n][1] for n in priors])
        self.tm, self.b_op, self.model_step = tm, b_op, model_step
        self.stage = 1.0 if strikes == "model" else 0.0
        self.offsets, self.path = offsets, pth
        n_w = prob.phases * prob.phase_size
        n_f, n_o, n_c = len(free), len(OFFSETS), len(POSITION_NUISANCES)
        self.n_w, self.n_obs = n_w, len(obs.value)
        self.options: dict = {}
        # The contacts' origin is in units of the leg length (IPOPT sees order one).
        self.c_scale = params.leg_length
        # The time offset's unknown is in units of the strikes' typical SD (IPOPT sees order one).
        self.t_scale = float(np.median(obs.strike_sd))
        self.theta0 = np.array([params.get(n) for n in free])
        self.scale = np.array([_scale(params, n) for n in free])
        self.p0 = params.input_vector(side)
        self.index = [INPUT_NAMES.index(n) for n in free]
        # With contact positions, each model step's displacement (2 per step) and the contact's
        # travel on each mesh interval (2 per interval) are unknowns of their own (in leg
        # lengths), tied to the gait by equalities (measurement.Path, collocation.contact_travel):
        # the data term depends on the few displacements, each equality on one interval, and the
        # derivatives keep the BVP's sparsity. Written directly in w, the data term coupled every
        # state of a step: 10 times slower (measured: 274 s vs 28 s for a 12-step fit), and the
        # displacement unknowns alone left the constraint Jacobian with dense rows (45 s).
        n_d = 2 * prob.phases if pth.n else 0
        n_t = n_d * prob.n_int
        self.lift_cols = np.arange(n_w + n_f + n_o + n_c, n_w + n_f + n_o + n_c + n_d + n_t)
        # A transient walk's model strikes (s) are unknowns too, tied to the step durations and
        # the time offset by equalities (measurement.Timing.clock_links): written through the
        # durations, every sample depends on every step before its own, and the misfit's
        # Hessian fills in (measured on stable-toy with a trailing share of 0.1: IPOPT's solver
        # for 20 steps took 24 s to build, 1.8 s with the clock; the transient fit of 60 steps
        # ran more than 9.5 minutes, 30 s with the clock). A periodic fit's one or two step
        # durations need no clock.
        n_k = 0 if prob.periodic or not _CLOCK_LIFTED else obs.n_steps + 1
        n_before = n_w + n_f + n_o + n_c + n_d + n_t
        self.clock_cols = np.arange(n_before, n_before + n_k)
        x = ca.MX.sym("x", n_w + n_f + n_o + n_c + n_d + n_t + n_k + 1)
        w, delta, off = x[:n_w], x[n_w:n_w + n_f], x[n_w + n_f:n_w + n_f + n_o]
        origin = x[n_w + n_f + n_o:n_w + n_f + n_o + n_c] * self.c_scale
        disp = x[self.lift_cols[:n_d]] if n_d else ca.MX(0, 1)
        trav = x[self.lift_cols[n_d:]] if n_d else ca.MX(0, 1)
        time_offset = x[-1] * self.t_scale
        p = ca.MX(ca.DM(self.p0))
        for j, k in enumerate(self.index):
            p[k] = self.p0[k] + self.scale[j] * delta[j]
        self.tied = [(INPUT_NAMES.index(a), INPUT_NAMES.index(b)) for a, b in tied(params, free).items()]
        for follower, leader in self.tied:
            p[follower] = p[leader]
        # d(model inputs)/d(theta): one per free parameter, and its followers (tied) move with it.
        self.dp_dtheta = np.zeros((len(self.p0), n_f))
        self.dp_dtheta[self.index, np.arange(n_f)] = 1.0
        for follower, leader in self.tied:
            self.dp_dtheta[follower, self.index.index(leader)] = 1.0
        inv_sd_all = ca.MX.sym("inv_sd", self.n_obs + 2 * pth.n)
        inv_sd, inv_sd_c = inv_sd_all[:self.n_obs], inv_sd_all[self.n_obs:]
        # each model step's duration among the BVP's unknowns
        self.duration_rows = np.array([prob.duration_index(j) for j in range(prob.phases)])
        durations = w[self.duration_rows]
        clock = x[self.clock_cols] if n_k else None
        lead = strike_phase(p) if prob.soft else 0.0  # a compliant strike's phase starts each step
        model = tm.values(w, durations, time_offset, clock, lead) + ca.mtimes(ca.DM(b_op), off)
        r_ang = (model - ca.DM(obs.value)) * inv_sd
        strikes = tm.strikes(durations, time_offset) if clock is None else clock
        self.strikes_fn = ca.Function("strikes", [x], [strikes])
        r_dur = (strikes - ca.DM(tm.strike_rel)) / ca.DM(obs.strike_sd)
        theta = ca.DM(self.theta0) + ca.DM(self.scale) * delta
        r_prior = ca.vertcat(*[(theta[j] - m) / sd for j, m, sd in
                               zip(self.prior_index, self.prior_mean, self.prior_sd, strict=True)])
        # The same misfit with every step aligned on its measured strikes (the operator's fixed
        # phases, step durations against the measured ones): the first stage of each solve, and
        # the whole of a fit with ``strikes="measured"``. From
        # a start far off, the model's strikes drift through the walk and the misfit in the
        # time offset and the step durations has other minima (measured: a start at the Tinkertoy's
        # foot radius ended at chi-square 1.4e6 instead of 484); aligned step by step it has not,
        # and from its solution the second stage only refines.
        read = tm.aligned(w, lead) if prob.soft else ca.mtimes(ca.DM(sp.csc_matrix(tm.at_phases())), w)
        model_aligned = read + ca.mtimes(ca.DM(b_op), off)
        r_ang_aligned = (model_aligned - ca.DM(obs.value)) * inv_sd
        per_step = ca.vertcat(*[w[prob.duration_index(int(j))] for j in model_step])
        r_dur_aligned = (per_step - ca.DM(obs.durations)) / ca.DM(obs.duration_sd)
        stage = ca.MX.sym("stage")  # 0: aligned on the measured strikes, 1: the model's strikes
        self.angles_fn = ca.Function("angles", [x, stage], [(1 - stage) * model_aligned + stage * model])
        # Contact positions at the measured strikes (measurement.Path): the same in both stages.
        if n_d:
            along, across = pth.relative(ca.reshape(disp, 2, prob.phases) * self.c_scale)
            yaw = off[1] if offsets else 0
            contacts = ca.vertcat(origin[0] + along - yaw * across, origin[1] + across + yaw * along)
        else:
            contacts = ca.MX(0, 1)
        self.contacts_fn = ca.Function("contacts", [x], [contacts])
        r_contact = (contacts - ca.DM(np.r_[pth.value[:, 0], pth.value[:, 1]])) * inv_sd_c
        residuals = ca.vertcat((1 - stage) * r_ang_aligned + stage * r_ang,
                               (1 - stage) * r_dur_aligned, stage * r_dur, r_prior, r_contact)
        f = 0.5 * ca.sumsqr(residuals)
        g = prob.constraints(w, p)
        # A foot's sideways radius never exceeds its fore-aft one (docs/model.md section 2): a bound
        # when one of them is free, a constraint when both are.
        self.lbg, self.ubg = prob.lbg, prob.ubg
        if {"foot_radius", "foot_lateral_radius"} <= set(free):
            k_r, k_rho = free.index("foot_radius"), free.index("foot_lateral_radius")
            g = ca.vertcat(g, theta[k_r] - theta[k_rho])
            self.lbg, self.ubg = np.r_[prob.lbg, 0.0], np.r_[prob.ubg, np.inf]
        if n_d:
            rolled, jump = contact_travel(prob)(w, p)
            summed = ca.DM(sp.csc_matrix(_interval_sums(prob)))
            g = ca.vertcat(g, trav - ca.vec(rolled) / self.c_scale,
                           disp - ca.mtimes(summed, trav) - ca.vec(jump) / self.c_scale)
            self.lbg, self.ubg = np.r_[self.lbg, np.zeros(n_d + n_t)], np.r_[self.ubg, np.zeros(n_d + n_t)]
        if n_k:
            g = ca.vertcat(g, tm.clock_links(clock, durations, time_offset))
            self.lbg, self.ubg = np.r_[self.lbg, np.zeros(n_k)], np.r_[self.ubg, np.zeros(n_k)]
        # The NLP as a function, so that several walks' NLPs can be joined into one
        # (toywalk.sysid.walks: shared parameters, each walk its own gait and nuisances).
        self.nlp_fn = ca.Function("nlp", [x, ca.vertcat(inv_sd_all, stage)], [f, g])
        self.residuals_fn = ca.Function("residuals", [x, inv_sd_all, stage], [residuals])
        self.residuals_jac = ca.Function("residuals_jac", [x, inv_sd_all, stage],
                                         [ca.jacobian(residuals, x)])
        self._nlp = ({"x": x, "p": ca.vertcat(inv_sd_all, stage), "f": f, "g": g}, max_iter)
        low, high = np.full(len(x.nz), -np.inf), np.full(len(x.nz), np.inf)
        for j, name in enumerate(free):
            lo, hi = fit_bounds(params, free, name)
            low[n_w + j] = (lo - self.theta0[j]) / self.scale[j]
            high[n_w + j] = (hi - self.theta0[j]) / self.scale[j]
        if not offsets:
            low[n_w + n_f:n_w + n_f + n_o] = high[n_w + n_f:n_w + n_f + n_o] = 0.0
        if not pth.n:
            low[n_w + n_f + n_o:n_w + n_f + n_o + n_c] = high[n_w + n_f + n_o:n_w + n_f + n_o + n_c] = 0.0
        self.lbx, self.ubx = low, high
        self.theta_low = self.theta0 + self.scale * low[n_w:n_w + n_f]
        self.theta_high = self.theta0 + self.scale * high[n_w:n_w + n_f]

    @cached_property
    def solver(self) -> ca.Function:
        """IPOPT on this walk's NLP, built when first asked for: the joint fit of several walks
        (toywalk.sysid.walks) joins the walks' :attr:`nlp_fn` into one NLP and never needs it
        (about 0.3 s a walk saved per joint fit)."""
        nlp, max_iter = self._nlp
        return ca.nlpsol("fit", "ipopt", nlp, ipopt_options(max_iter))

    def lifted(self, w: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The displacement and interval-travel unknowns (leg lengths) of the gait ``w`` at
        ``theta``."""
        if not len(self.lift_cols):
            return np.zeros(0)
        rolled, jump = (np.array(m).ravel(order="F")
                        for m in contact_travel(self.prob)(w, self.p_full(theta)))
        return np.r_[_interval_sums(self.prob) @ rolled + jump, rolled] / self.c_scale

    def start(self, w0: np.ndarray) -> np.ndarray:
        """The NLP's start from a gait ``w0`` at the starting parameters (nuisances at zero)."""
        return self.clocked(np.concatenate([
            w0, np.zeros(len(self.free) + len(OFFSETS) + len(POSITION_NUISANCES)),
            self.lifted(w0, self.theta0), np.zeros(len(self.clock_cols)), [0.0]]))

    def durations(self, x: np.ndarray) -> np.ndarray:
        """The model steps' durations (s), shape (phases,)."""
        return x[self.duration_rows]

    def clocked(self, x: np.ndarray) -> np.ndarray:
        """``x`` with its clock (a transient's model strikes) set from its durations and time
        offset, where the equalities put it."""
        x = x.copy()
        x[self.clock_cols] = self.tm.strikes(self.durations(x), x[-1] * self.t_scale)[:len(self.clock_cols)]
        return x

    def theta(self, x: np.ndarray) -> np.ndarray:
        """The free parameters, clipped into their bounds (IPOPT may end a hair outside one)."""
        theta = np.clip(self.theta0 + self.scale * x[self.n_w:self.n_w + len(self.free)],
                        self.theta_low, self.theta_high)
        if {"foot_radius", "foot_lateral_radius"} <= set(self.free):  # and its constraint
            k_r, k_rho = self.free.index("foot_radius"), self.free.index("foot_lateral_radius")
            theta[k_rho] = min(theta[k_rho], theta[k_r])
        return theta

    def p_full(self, theta: np.ndarray) -> np.ndarray:
        p = self.p0.copy()
        p[self.index] = theta
        for follower, leader in self.tied:
            p[follower] = p[leader]
        return p

    def solve(self, x0: np.ndarray, sigma: np.ndarray, aligned_first: bool = True, progress=None):
        """Aligned on the measured strikes (time offset held at 0), then, unless the fit stays
        there (``strikes="measured"``), on the model's strikes from that solution, through the
        blends of :data:`STAGE_PATH` (each solve from the last; a failed one ends the path with
        its status); from a start already near the model's strikes (``aligned_first`` False),
        the second stage only. ``progress`` is called with a line before each stage.
        Returns the solution, IPOPT's statistics, and the angle residuals' RMS per signal at the
        aligned stage's solution when the model's strikes follow it (else None)."""
        say = progress or (lambda _msg: None)
        sol = {"x": x0}
        aligned_rms = None
        if aligned_first or self.stage == 0.0:
            say("aligned on the measured heel strikes")
            lbx, ubx = self.lbx.copy(), self.ubx.copy()
            lbx[-1] = ubx[-1] = 0.0
            sol = self.solver(x0=x0, p=np.r_[1.0 / sigma, 0.0], lbx=lbx, ubx=ubx, lbg=self.lbg,
                              ubg=self.ubg)
            if self.stage == 1.0 and self.solver.stats()["success"]:
                aligned_rms = self.residual_rms(np.array(sol["x"]).ravel(), stage=0.0)
        if self.stage == 1.0 and (not aligned_first or self.solver.stats()["success"]):
            say("on the model's heel strikes" + (f", in {len(STAGE_PATH)} steps from the aligned "
                                                 "solution" if aligned_first else ""))
            for stage in STAGE_PATH if aligned_first else (1.0,):
                sol = self.solver(x0=np.array(sol["x"]).ravel(), p=np.r_[1.0 / sigma, stage],
                                  lbx=self.lbx, ubx=self.ubx, lbg=self.lbg, ubg=self.ubg)
                if not self.solver.stats()["success"]:
                    break
        return np.array(sol["x"]).ravel(), self.solver.stats(), aligned_rms

    def angle_residuals(self, x: np.ndarray, stage: float | None = None) -> np.ndarray:
        """Model minus measurement of every angle observation (rad), read between the fit's
        strikes (or ``stage`` 0.0: the measured ones, 1.0: the model's)."""
        return np.array(self.angles_fn(x, self.stage if stage is None else stage)).ravel() - self.obs.value

    def offsets_of(self, x: np.ndarray) -> np.ndarray:
        n = self.n_w + len(self.free)
        return x[n:n + len(OFFSETS)]

    def origin_of(self, x: np.ndarray) -> np.ndarray:
        """The measured contacts' origin (m): where the model puts the first measured strike's."""
        n = self.n_w + len(self.free) + len(OFFSETS)
        return x[n:n + len(POSITION_NUISANCES)] * self.c_scale

    def contact_residuals(self, x: np.ndarray) -> np.ndarray:
        """Model minus measurement of the contact positions, shape (n_pos, 2) (m)."""
        model = np.array(self.contacts_fn(x)).ravel().reshape(2, -1).T
        return model - self.path.value

    def contact_rms(self, x: np.ndarray, floor: float = 0.0) -> dict:
        """RMS of the contact-position residuals along and across the ramp (m), at least ``floor``."""
        res = self.contact_residuals(x)
        return {k: max(float(np.sqrt(np.mean(res[:, i] ** 2))), floor) for i, k in enumerate(CONTACT_KEYS)}

    def residual_rms(self, x: np.ndarray, stage: float | None = None) -> dict:
        """RMS of the angle residuals per signal (rad; ``stage`` as :meth:`angle_residuals`)."""
        res = self.angle_residuals(x, stage)
        return {name: float(np.sqrt(np.mean(res[self.obs.signal == s_i] ** 2)))
                for s_i, name in enumerate(SIGNALS) if np.any(self.obs.signal == s_i)}

    def start_names(self) -> list[str]:
        """Names of a transient's free start components (``start.`` and the public state name)."""
        public = self.walker.to_internal(np.arange(8.0)).astype(int)[:self.prob.n_dyn]
        return [f"start.{STATE_NAMES[public[i - self.start_cols[0]]]}" for i in self.start_free]

    def whitened(self, x: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        return np.array(self.residuals_fn(x, 1.0 / sigma, self.stage)).ravel()

    # ----------------------------------------------------------------------------- result
    def jacobian(self, x: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Total derivative of the whitened residuals in (theta, the free start of a transient,
        offsets, the contacts' origin, time offset) through the BVP: columns ``free``,
        :meth:`start_names`, :data:`OFFSETS` (when fitted), :data:`POSITION_NUISANCES` (when
        the walk has contact positions), ``time_offset``."""
        prob = self.prob
        w = x[:self.n_w]
        g_w, g_p = (_sparse(m) for m in _equality_jacobians(prob)(w, self.p_full(self.theta(x))))
        g_w = g_w.tocsc()
        indep = np.zeros((g_w.shape[0], 0))
        if not prob.periodic:
            start_row = g_w[prob.start_guard_index][:, self.start_cols].toarray().ravel()
            fixed = self.start_cols[int(np.argmax(np.abs(start_row)))]
            self.start_free = self.start_cols[self.start_cols != fixed]
            indep = g_w[:, self.start_free].toarray()
        dep = np.setdiff1d(np.arange(self.n_w), self.start_free)
        n_f, n_s = len(self.free), len(self.start_free)
        rhs = np.hstack([g_p @ self.dp_dtheta, indep])
        dw = np.zeros((self.n_w, n_f + n_s))
        if n_f + n_s:
            dw[dep] = -splu(g_w[:, dep].tocsc()).solve(rhs)
        dw[self.start_free, n_f:] = np.eye(n_s)
        # The residuals' own derivatives (CasADi), chained through the BVP: w moves with theta
        # and the free start, and theta, offsets and time offset also enter directly.
        jr = _sparse(self.residuals_jac(x, 1.0 / sigma, self.stage)).tocsc()
        n_o, n_c = len(OFFSETS), len(POSITION_NUISANCES)
        j_model = jr[:, :self.n_w] @ dw
        j_model[:, :n_f] += jr[:, self.n_w:self.n_w + n_f].toarray() / self.scale
        if len(self.lift_cols):  # the lifted unknowns follow w and theta through their equalities
            jac = _travel_jacobians(prob)(w, self.p_full(self.theta(x)))
            r_w, r_p, j_w, j_p = (_sparse(m) for m in jac)
            sums = _interval_sums(prob)
            d_lift = np.vstack([sums @ (r_w @ dw) + j_w @ dw, r_w @ dw])
            d_lift[:, :n_f] += np.vstack([(sums @ r_p + j_p) @ self.dp_dtheta,
                                          r_p @ self.dp_dtheta])
            j_model += jr[:, self.lift_cols] @ d_lift / self.c_scale
        j_off = jr[:, self.n_w + n_f:self.n_w + n_f + n_o].toarray()
        j_origin = jr[:, self.n_w + n_f + n_o:self.n_w + n_f + n_o + n_c].toarray() / self.c_scale
        j_time = jr[:, -1:].toarray() / self.t_scale
        if len(self.clock_cols):  # the clock follows the durations and the time offset
            j_clock = jr[:, self.clock_cols]
            j_model += j_clock @ (self.tm.strikes_before @ dw[self.duration_rows])
            j_time += np.asarray(j_clock.sum(axis=1))
        if not self.offsets:
            j_off = j_off[:, :0]
        if not self.path.n:
            j_origin = j_origin[:, :0]
        if self.stage == 0.0:
            j_time = j_time[:, :0]
        return np.hstack([j_model, j_off, j_origin, j_time])

    def _resolve(self, x: np.ndarray, theta: np.ndarray) -> np.ndarray | None:
        """The BVP's unknowns at parameters ``theta`` from ``x``'s (a transient's free start held),
        or None: Newton on the equalities in the unknowns that are not held (the square system
        :meth:`jacobian` differentiates) from ``x``, which solves them at the fit's parameters, a
        central difference's step away; only where Newton does not end within the BVP solver's
        tolerance, IPOPT, then Newton from IPOPT's solution.

        Newton first because IPOPT on this BVP can cost minutes for nothing: on a transient's
        start held it stopped at once with a restoration failure (the README's walk,
        clearing-toy filmed at 120 frames/s, ``fit`` by default, even at the unperturbed
        parameters where ``x`` satisfies the equalities to 2e-14); on a walk off its cycle
        (tests/sysid/offcycle.py) it did so from 14 steps on, and its one iteration grew with the
        walk: 25-41 s at 20 steps, 324 s at 60 (23580 unknowns), where the default fit's check
        makes four such re-solves after a minute of fitting. Newton from ``x`` converges in two or
        three steps of a sparse LU (under 0.3 s up to 20 steps; benchmarks/fit_speed.py).

        Newton's steps go on :data:`_POLISH` steps past the tolerance: IPOPT's equalities hold to
        its tolerance while its unknowns can stand off the root along the BVP's ill-conditioned
        directions, and a central difference divides that by the step (measured on a 12-step
        transient fit of stable-toy, foot radius: the check 1.5e-5 relative, erratic with the
        step size, and 4e-9 polished). The result rests on the equalities only, not on the
        derivatives the check tests."""
        w0, p = x[:self.n_w], self.p_full(theta)
        w = self._newton(w0.copy(), p, None)
        if w is not None:
            return w
        lbx, ubx = np.full(self.n_w, -np.inf), np.full(self.n_w, np.inf)
        lbx[self.start_free] = ubx[self.start_free] = w0[self.start_free]
        sol = self.prob.solver(x0=w0, p=p, lbg=self.prob.lbg, ubg=self.prob.ubg, lbx=lbx, ubx=ubx)
        if not self.prob.solver.stats()["success"]:
            return None
        w = np.array(sol["x"]).ravel()
        return self._newton(w.copy(), p, w)

    def _newton(self, w: np.ndarray, p: np.ndarray, within: np.ndarray | None) -> np.ndarray | None:
        """Newton on the BVP's equalities from ``w`` (changed in place) in the unknowns that are
        not held, :data:`_POLISH` steps past :data:`_NEWTON_TOL`; where the steps do not end
        within the tolerance, the latest unknowns that were, else ``within`` (unknowns known to
        be within it, or None)."""
        n_eq = self.prob.n_equalities
        dep = np.setdiff1d(np.arange(self.n_w), self.start_free)
        polish = 0
        for _ in range(_NEWTON_STEPS + _POLISH):
            g = np.array(self.prob.constraints(w, p)).ravel()[:n_eq]
            if not np.all(np.isfinite(g)):
                return within
            if np.max(np.abs(g)) <= _NEWTON_TOL:
                within = w.copy()
                if polish == _POLISH:
                    return w
                polish += 1
            g_w = _sparse(_equality_jacobians(self.prob)(w, p)[0]).tocsc()
            w[dep] -= splu(g_w[:, dep]).solve(g)
        return within

    def fd_check(self, x: np.ndarray, sigma: np.ndarray, jac: np.ndarray) -> dict:
        """Central differences of the residuals in each free parameter, re-solving the BVP (with a
        transient's free start held; :meth:`_resolve`)."""
        out = {}
        theta = self.theta(x)
        for j, name in enumerate(self.free):
            h = 1e-5 * self.scale[j]
            cols = []
            for sign in (1.0, -1.0):
                th = theta.copy()
                th[j] += sign * h
                w = self._resolve(x, th)
                if w is None:
                    break
                xs = x.copy()
                xs[:self.n_w] = w
                xs[self.lift_cols] = self.lifted(xs[:self.n_w], th)
                xs = self.clocked(xs)
                xs[self.n_w + j] += sign * h / self.scale[j]
                cols.append(self.whitened(xs, sigma))
            if len(cols) < 2:
                out[name] = None
                continue
            fd = (cols[0] - cols[1]) / (2 * h)
            out[name] = float(np.linalg.norm(jac[:, j] - fd) / max(np.linalg.norm(fd), 1e-300))
        return out

    def result(self, x: np.ndarray, stats: dict, sigma: np.ndarray, noise_source: str,
               contact_source: str, aligned_rms: dict | None = None) -> FitResult:
        """The fit at the solution ``x`` (IPOPT's ``stats``, the SDs ``sigma`` of every residual
        and where they came from, the aligned stage's residual RMS): estimates, covariance over
        the determined directions, the identifiability, bound and Jacobian-check notes,
        residuals, and the fitted walker's gait."""
        obs, prob = self.obs, self.prob
        theta = self.theta(x)
        names = (list(self.free) + (list(OFFSETS) if self.offsets else [])
                 + (list(POSITION_NUISANCES) if self.path.n else [])
                 + (["time_offset"] if self.stage == 1.0 else []))
        estimates = dict(zip(self.free, map(float, theta), strict=True))
        if self.offsets:
            estimates.update(zip(OFFSETS, map(float, self.offsets_of(x)), strict=True))
        if self.path.n:
            estimates.update(zip(POSITION_NUISANCES, map(float, self.origin_of(x)), strict=True))
        if self.stage == 1.0:
            estimates["time_offset"] = float(x[-1] * self.t_scale)
        notes: list[str] = [self.obs.note] if self.obs.note else []
        jac = self.jacobian(x, sigma)
        # The information over every unknown the data see (the free start of a transient too);
        # the reported covariance is its inverse's block of the free parameters and offsets.
        names_all = list(self.free) + self.start_names() + names[len(self.free):]
        keep = [names_all.index(n) for n in names]
        info = jac.T @ jac
        norms = np.sqrt(np.maximum(np.diag(info), 1e-300))
        scaled = info / np.outer(norms, norms)
        evals, evecs = np.linalg.eigh(scaled)
        good = evals >= _NEAR_SINGULAR * evals[-1] if len(evals) else np.zeros(0, bool)
        null = evecs[:, ~good]
        if null.shape[1]:
            vec = null[:, 0]
            combo = " ".join(f"{v:+.2f} {n}" for v, n in zip(vec, names_all, strict=True) if abs(v) > 0.1)
            notes.append(f"not determined by these data: the combination {combo} (scaled) has "
                         f"{math.sqrt(max(evals[0], 0) / evals[-1]):.1e} of the largest singular value")
        # a reported unknown with a share of the near-null directions has no standard error: the
        # pseudo-inverse would give a number (2e-15 for a foot radius, 2e-25 for an offset, on a
        # transient fit of an unstable walker), precision the data do not hold
        loading = np.sum(null**2, axis=1)
        undetermined = [n for n in names if loading[names_all.index(n)] > _UNDETERMINED_SHARE]
        # The inverse over the determined directions of the scaled information: a pseudo-inverse
        # of the unscaled one cuts directions small against the largest (rcond 1e-15) and gives
        # them no variance at all, where an unstable walker's free start makes the largest 1e30
        # times the offsets' (their standard errors came out 2e-25 rad on such a transient fit)
        kept = evecs[:, good]
        cov_all = (kept / evals[good]) @ kept.T / np.outer(norms, norms)
        cov_all, widened = self._shared_covariance(cov_all, jac, sigma, names_all)
        cov = cov_all[np.ix_(keep, keep)]
        lost = np.array([n in undetermined for n in names], bool)
        cov[lost, :] = cov[:, lost] = np.nan
        std_all = np.sqrt(np.maximum(np.diag(cov), 0.0))
        corr = cov / np.outer(np.maximum(std_all, 1e-300), np.maximum(std_all, 1e-300))
        std = dict(zip(names, map(float, std_all), strict=True))
        for j, name in enumerate(self.free):
            if std[name] > self.scale[j]:
                notes.append(f"{name} is weakly determined by these data: standard error "
                             f"{std[name]:.3g} against a magnitude of {self.scale[j]:.3g}")
            lo, hi = self.theta_low[j], self.theta_high[j]
            if min(theta[j] - lo, hi - theta[j]) <= 1e-6 * self.scale[j]:
                notes.append(f"{name} = {theta[j]:.6g} sits on its bound [{lo:g}, {hi:g}]: its "
                             "standard error assumes it could move past it")
        check = self.fd_check(x, sigma, jac) if self.free and self.check_jacobian else {}
        bad = {k: v for k, v in check.items() if v is not None and v > 1e-3}
        unchecked = sorted(k for k, v in check.items() if v is None)
        if bad:
            notes.append(f"the AD and finite-difference Jacobians disagree for {sorted(bad)}: "
                         f"{bad} (relative); the covariance may be unreliable")
        if unchecked:
            notes.append(f"the AD Jacobian could not be checked by finite differences for "
                         f"{unchecked}: the gait's re-solve at a perturbed value did not converge")
        res = self.angle_residuals(x)
        rms, by_phase = {}, {}
        bins = np.minimum((obs.phase * _PHASE_BINS).astype(int), _PHASE_BINS - 1)
        for s_i, name in enumerate(SIGNALS):
            sel = obs.signal == s_i
            if not np.any(sel):
                continue
            rms[name] = float(np.sqrt(np.mean(res[sel] ** 2)))
            by_phase[name] = [float(np.sqrt(np.mean(res[sel & (bins == b)] ** 2)))
                              if np.any(sel & (bins == b)) else None for b in range(_PHASE_BINS)]
        durations = np.array([x[prob.duration_index(int(j))] for j in self.model_step])
        rms["step_duration"] = float(np.sqrt(np.mean((durations - obs.durations) ** 2)))
        if self.stage == 1.0:
            strikes = np.array(self.strikes_fn(x)).ravel()
            rms["strike_time"] = float(np.sqrt(np.mean((strikes - self.tm.strike_rel) ** 2)))
        # the RMS of the samples' SDs, the noise an RMS of residuals is compared with: a
        # tracker's SDs vary (the far leg's 0.04 to 0.19 degrees, the largest where the legs
        # pass), and their median (0.062 degrees) understated it (0.097) so much that a model
        # fitting the truth to 0.01 degrees was judged short of explaining the walk
        noise = {name: float(np.sqrt(np.mean(sigma[:self.n_obs][obs.signal == s_i] ** 2)))
                 for s_i, name in enumerate(SIGNALS) if np.any(obs.signal == s_i)}
        note = _misfit_note(obs, rms, None if noise_source == "estimated from residuals" else noise)
        if note:
            notes.append(note)
        if self.path.n:
            rms.update(self.contact_rms(x))
            sd_c = sigma[self.n_obs:].reshape(2, -1)
            noise.update({k: float(np.sqrt(np.mean(sd_c[i] ** 2))) for i, k in enumerate(CONTACT_KEYS)})
        whitened = self.whitened(x, sigma)
        success = bool(stats["success"])
        try:
            fitted = with_values(self.params, self.free, estimates_only(estimates, self.free))
            gait = self._gait(x, fitted, notes)
        except ParameterError as err:
            fitted, gait, success = self.params, {}, False
            notes.append(f"the estimates are not a valid walker: {err}")
        start = {}
        if not prob.periodic:
            z = self.walker.to_public(np.r_[x[self.start_cols], np.zeros(self.walker.lay.nx - prob.n_dyn)])
            z[:4] *= self.side  # the physical description: lean and steer of a right stance flip
            start = dict(zip(STATE_NAMES, map(float, z), strict=True))
            start["stance"] = "L" if self.side == 1 else "R"
        return FitResult(
            free=list(self.free), estimates=estimates, std=std, covariance=cov, correlation=corr,
            names=names, noise_sd=noise, noise_source=noise_source, residual_rms=rms,
            residual_rms_by_phase=by_phase, chi2=float(whitened @ whitened),
            n_residuals=len(whitened), success=success, status=str(stats["return_status"]),
            iterations=int(stats["iter_count"]), params=fitted, gait=gait, warnings=notes,
            jacobian_check=check, priors=self.priors, solution=x,
            model="periodic" if prob.periodic else "transient", initial_state=start, sigma=sigma,
            start_dof=len(self.start_free), contact_source=contact_source, residuals=res,
            model_durations=durations, options=dict(self.options), n_w=self.n_w,
            aligned_rms=aligned_rms, exposure_s=self.obs.exposure, undetermined=undetermined,
            shared_widening=widened)

    def _shared_covariance(self, cov: np.ndarray, jac: np.ndarray, sigma: np.ndarray,
                           names: list) -> tuple[np.ndarray, dict]:
        """:func:`shared_covariance` with the errors the samples share by phase (the file's
        ``*_phase_sd``, :func:`toywalk.sysid.residuals.shared_errors`), and each free
        parameter's standard error over the one without them (those above 1.01).

        A tracker's bias by phase repeats in every step, so an estimate moves with it as a
        whole and more steps do not average it away. Through video on compass-3d (a collision's
        trailing share 0.03) the fit of the tracked angles gave 0.0286 +- 0.00055, 2.5 SE from
        the truth, which a fit of the render's own angles gives to 1e-6: the phase-locked
        errors, not the noise, set how far an estimate can be off (+- 0.0011 with them)."""
        loads = shared_errors(self.obs)
        if not loads.nnz:
            return cov, {}
        total = shared_covariance(cov, jac, sigma, loads)
        before, after = np.sqrt(np.diag(cov)), np.sqrt(np.diag(total))
        widened = {name: float(after[j] / before[j]) for j, name in enumerate(names)
                   if name in self.free and before[j] > 0 and after[j] > 1.01 * before[j]}
        return total, widened

    def _gait(self, x: np.ndarray, fitted: Params, notes: list) -> dict:
        """The fitted walker's gait: the periodic fit's own, or for a transient the fitted
        walker's gait found as for a periodic fit's start (its mesh)."""
        prob = self.prob
        period = gait_period(fitted, self.free)
        walker = Walker(fitted, planar=self.planar, period=period)
        w = x[:self.n_w]
        if not prob.periodic:
            # Not from the walk's last steps: a periodic BVP started there can land on another
            # gait (measured: a 0.055 s step beside the 0.107 s one on stable-toy).
            try:
                walker, gait = _start(fitted, period, self.free, None)
                prob = bvp(self.planar, *_MESH["periodic"], period, soft=self.prob.soft)
                w = _feasible_start(prob, walker, gait.fixed_point, 1)
            except FitError as err:
                notes.append(f"no periodic gait of the fitted walker: {err}")
                return {}
        jac = cycle_jacobian(w, fitted.input_vector(), prob, walker)
        vals = np.linalg.eigvals(jac)
        vals = vals[np.argsort(-np.abs(vals))]
        z0 = walker.to_public(np.r_[w[1:1 + prob.n_dyn], np.zeros(walker.lay.nx - prob.n_dyn)])
        times = [float(w[prob.duration_index(j)]) for j in range(prob.phases)]
        # the swing foot over the cycle, as `toywalk gait` reports it (scuffs before the legs pass)
        scuffs = lowest = None
        try:
            steps = walker.cycle(z0, record=True).steps
            scuffs, lowest = int(sum(st.scuffs for st in steps)), min(float(st.swing.minimum) for st in steps)
        except StepFailure as err:  # the BVP's gait, which the simulator cannot follow through a step
            notes.append(f"the fitted walker's gait, simulated from its fixed point, {err.status} ({err}): "
                         "its swing clearance is not known, and the fit may have found a gait the walker "
                         "does not walk")
        return {
            "scuffs": scuffs, "swing_clearance": lowest,
            "map": "step" if prob.phases == 1 else "stride",
            "fixed_point": dict(zip(STATE_NAMES, map(float, z0), strict=True)),
            "step_times": times,
            "eigenvalues": [{"re": float(v.real), "im": float(v.imag)} for v in vals],
            "max_abs_eigenvalue": float(np.max(np.abs(vals))),
            "stable": bool(np.max(np.abs(vals)) < 1.0),
            "planar": self.planar,
        }


def shared_covariance(cov: np.ndarray, jac: np.ndarray, sigma: np.ndarray, loads: sp.spmatrix) -> np.ndarray:
    """The estimates' covariance when the first ``loads.shape[0]`` data share errors.

    ``cov`` is the Gauss-Newton ``(J^T J)^+`` of the whitened residuals (``jac``, rows the
    residuals, the first ones the angles whose SDs are ``sigma``); ``loads`` (n_angles, cells)
    the shared errors' loadings (rad; covariance ``L L^T``), whose part of each sample's
    variance ``sigma^2`` already holds. With ``A = cov J^T``, the estimates' response to the
    whitened data, and ``Q = diag(1/sigma) L``, ``q`` its rows' norms, the whitened errors'
    covariance is ``diag(1 - q^2) + Q Q^T`` over the angles (the identity over the other rows),
    and the estimates' is ``A (diag(1 - q^2) + Q Q^T) A^T``: ``cov`` itself when nothing is
    shared. Checked against the spread of least-squares estimates over draws of such errors
    (tests/sysid/test_fit_shared.py)."""
    n = loads.shape[0]
    q = whitened_loads(loads, sigma)
    gain = cov @ jac[:n].T
    through = np.asarray((q.T @ gain.T).T)
    white = np.maximum(1.0 - np.asarray(q.multiply(q).sum(axis=1)).ravel(), 0.0)
    tail = cov @ jac[n:].T
    return through @ through.T + (gain * white) @ gain.T + tail @ tail.T


def whitened_loads(loads: sp.spmatrix, sigma: np.ndarray, rows: int | None = None) -> sp.csr_matrix:
    """The shared errors' loadings ``loads`` (the first ``loads.shape[0]`` residuals', rad) over
    those residuals' SDs ``sigma``: ``Q = diag(1/sigma) L``, so that the whitened errors'
    covariance is ``diag(1 - q^2) + Q Q^T`` with ``q`` Q's row norms; with ``rows``, padded with
    zero rows to that many residuals (a prior's or a strike time's row shares nothing)."""
    n = loads.shape[0]
    q = sp.csr_matrix(sp.diags(1.0 / sigma[:n]) @ loads)
    if rows is not None and rows > n:
        q = sp.csr_matrix(sp.vstack([q, sp.csr_matrix((rows - n, q.shape[1]))]))
    return q


def stacked(shared: Sequence[np.ndarray], nuisance: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Several walks' Jacobian columns as one problem's: the shared unknowns' columns (each walk's
    shape (n_k, s)) one above the other, the nuisances' (n_k, m_k) block-diagonal, each in its
    walk's rows. Returns the shared (sum n_k, s) and nuisance (sum n_k, sum m_k) columns."""
    rows = sum(len(a) for a in shared)
    block = np.zeros((rows, sum(b.shape[1] for b in nuisance)))
    r = c = 0
    for a, b in zip(shared, nuisance, strict=True):
        block[r:r + len(a), c:c + b.shape[1]] = b
        r, c = r + len(a), c + b.shape[1]
    return np.vstack(shared), block


def continued(problem: FitProblem, w0: np.ndarray, result: FitResult) -> np.ndarray:
    """The NLP's unknowns continuing the fit ``result`` on ``problem`` (built at the fit's
    estimates, with the same free parameters and perhaps more): its gait (or transient walk)
    when the BVPs match, its step gait twice over for a stride BVP (a symmetric gait's second
    step, in the mirrored description, is its first), else ``w0``; the new parameters at their
    values; its nuisances."""
    w = w0
    if problem.n_w == result.n_w:
        w = result.solution[:result.n_w]
    elif problem.prob.periodic and result.model == "periodic" and problem.n_w == 2 * result.n_w:
        w = np.tile(result.solution[:result.n_w], 2)
    x = problem.start(w)
    n_w, n_f = problem.n_w, len(problem.free)
    est = result.estimates
    if problem.offsets and all(o in est for o in OFFSETS):
        x[n_w + n_f:n_w + n_f + len(OFFSETS)] = [est[o] for o in OFFSETS]
    if problem.path.n and all(o in est for o in POSITION_NUISANCES):
        k = n_w + n_f + len(OFFSETS)
        x[k:k + len(POSITION_NUISANCES)] = np.array([est[o] for o in POSITION_NUISANCES]) / problem.c_scale
    if problem.stage == 1.0 and "time_offset" in est:
        x[-1] = est["time_offset"] / problem.t_scale
    return problem.clocked(x)



def fit_line(model: str, strikes: str) -> str:
    """A fit as a progress line names it: its model and the heel strikes it reads the walk on."""
    return f"the {model} model, on {'its own' if strikes == 'model' else 'the measured'} heel strikes"



def estimates_only(estimates: dict, free) -> dict:
    """The free parameters' estimates (without the nuisance offsets)."""
    return {name: estimates[name] for name in free}
