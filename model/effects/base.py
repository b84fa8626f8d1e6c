"""The template every effect follows, and what the equations builder hands to it.

An effect (docs/model.md section 6) is one small unit, like one of emcee's moves: a name, one strength
parameter with its SI unit, its null value (at which the model is exactly the seed's), a typical
magnitude, physical bounds, where it enters the model and whether it breaks the walker's
left-right mirror symmetry, and the terms it contributes. Each contribution is a hook with a
neutral default, so an effect overrides only the hooks it needs:

- :meth:`Effect.com_offsets` and :meth:`Effect.gravity` change the geometry (per-leg mass offsets,
  the gravity vector in the ramp frame);
- :meth:`Effect.couples` returns couples acting on the legs between collisions (a hinge torque
  pair, a contact couple from the ramp); the builder turns them into generalised forces by virtual
  work, ``Q = sum_legs W_leg^T M_leg`` with ``W_leg = d omega_leg / du`` (Kane & Levinson 1985),
  and into the effect's dissipated power ``-sum_legs M_leg . omega_leg`` (for a conservative term,
  a spring, it is the rate of change of the energy the spring stores, of either sign);
- :meth:`Effect.trailing_impulse` and :meth:`Effect.arrest` change the collision law.

Every strength is a symbolic input of the compiled functions (``k`` below is a CasADi SX scalar):
one compiled function set serves every value and every combination. CasADi is imported only where
an expression is built: the parameter files name the effects, and reading them (the tracker does,
``toywalk track``) does not load CasADi (about 1 s).
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import casadi as ca

__all__ = ["Arrest", "Context", "Effect"]


@dataclasses.dataclass
class Context:
    """Symbolic quantities of one system an effect may use (slope frame S, docs/model.md section 1).

    Attributes
    ----------
    planar : bool
        The planar reduction (phi = psi = 0 held).
    params : Any
        Named views of the parameter input (:func:`toywalk.model.parameters.view`).
    side : ca.SX
        +1 when the physical left leg is in stance (the description is the physical one), -1 when
        the right leg is (the description is mirrored, y -> -y).
    q4, u4 : ca.SX, shape (4, 1)
        (phi, psi, theta_st, theta_sw) and their rates.
    n : ca.SX, shape (3, 1)
        The hip axis (to the left of the described stance leg).
    w1, w2 : ca.SX, shape (3, 1)
        Angular velocities of the stance and swing legs (set once velocities exist).
    """

    planar: bool
    params: Any
    side: ca.SX
    q4: ca.SX
    u4: ca.SX
    n: ca.SX | None = None
    w1: ca.SX | None = None
    w2: ca.SX | None = None

    @property
    def ez(self) -> ca.SX:
        """The ramp normal."""
        import casadi as ca

        return ca.SX([0.0, 0.0, 1.0])

    @property
    def heading(self) -> ca.SX:
        """The heading axis ``Rz(phi) e_x`` in the ramp plane: the axis of the lean psi."""
        import casadi as ca

        return ca.vertcat(ca.cos(self.q4[0]), ca.sin(self.q4[0]), 0)

    @property
    def pitch_axis(self) -> ca.SX:
        """``Rz(phi) e_y = e_z x heading``: the hip axis n projected onto the ramp plane, the axis
        of the stance foot's fore-aft rolling."""
        import casadi as ca

        return ca.vertcat(-ca.sin(self.q4[0]), ca.cos(self.q4[0]), 0)

    @property
    def rate_unit(self) -> ca.SX:
        """sqrt(g / l) (rad/s), the natural rate of a pendulum of the leg's length."""
        import casadi as ca

        return ca.sqrt(self.params.gravity / self.params.leg_length)


@dataclasses.dataclass(frozen=True)
class Arrest:
    """A collision variant that also arrests one rate of the landing leg, blended in by ``k``.

    The post-collision rates are ``u0 + k (u1 - u0)``, where ``u0`` solves the collision law (with
    any trailing share) and ``u1`` the seed's plastic law with one more plastic constraint
    ``axis . omega_landing = 0``, enforced by an impulsive couple along ``axis`` (a unit vector) on
    the landing leg. ``u1`` is a plastic impulsive projection (Carnot's theorem: it gains no
    kinetic energy), and kinetic energy is convex in the rates, so no blend with 0 <= k <= 1 gains
    energy where ``u0`` gains none.

    Several arrests blend multilinearly: with strengths k_1..k_m, the law that enforces the
    constraints of a subset S of them has weight ``prod_{i in S} k_i prod_{i not in S} (1 - k_i)``
    (the empty subset is ``u0``). Every law of a non-empty subset is again a plastic projection
    (several plastic constraints at once), the weights are non-negative and sum to 1, so the blend
    gains no energy either; with one arrest it is the blend above.
    """

    strength: ca.SX
    axis: ca.SX


class Effect:
    """One physical effect with one strength parameter.

    Class attributes (each effect sets them)
    ----------------------------------------
    name : str
        The parameter's key in a parameter file's ``[effects]`` table.
    unit : str
        SI unit of the strength.
    null : float
        The strength at which the model is exactly the seed's.
    typical : float
        A magnitude that visibly changes the stable toy's gait (data/params/stable-toy.toml).
    bounds : tuple of 2 floats
        Physically admissible strengths (inclusive); values outside are refused.
    enters : str
        ``"equations of motion"``, ``"contact couple"``, ``"collision law"`` or ``"geometry"``.
    breaks_symmetry : bool
        True when a non-null strength breaks the left-right mirror symmetry, so that gaits are
        stride-periodic (two steps) rather than step-periodic.
    physics : str
        One line of physics.
    port_only : bool
        True for a term of the dictionary of generalised forces at the walker's ports
        (:data:`toywalk.model.effects.ports.PORTS`) that is no effect of the library proper: it is
        in the registry and the parameter vector like every effect, but not among the causes the
        discrepancy analysis tries by default.
    screened : bool
        False for an effect of the library that the discrepancy analysis does not try by default
        yet (a new effect whose fit support is incomplete, as ``soft_heel``'s: the collocation
        transcription keeps the rigid collision). Like a port-only term it stays in the registry
        and the parameter vector, and can be named explicitly.
    local : bool
        True when a score test at the null value speaks for the effect over its physical range
        (its first-order change of the gait points where larger strengths take it). False for an
        effect whose change of the gait is not monotonic in its strength (``soft_heel``'s: the
        step time falls at 5 s/s from tau = 0+ and rises by 2 ms): the discrepancy analysis then
        fits it whatever its score says (:func:`toywalk.sysid.discrepancy.diagnose`).
    """

    name: str = ""
    unit: str = ""
    null: float = 0.0
    typical: float = 0.0
    bounds: tuple[float, float] = (-math.inf, math.inf)
    enters: str = ""
    breaks_symmetry: bool = False
    physics: str = ""
    port_only: bool = False
    screened: bool = True
    local: bool = True

    @property
    def continuous(self) -> bool:
        """True when the effect acts between collisions (it has a dissipation output)."""
        return type(self).couples is not Effect.couples

    def describe(self) -> dict:
        """JSON-ready description (``toywalk effects --json``)."""
        return {"name": self.name, "unit": self.unit, "null": self.null, "typical": self.typical,
                "bounds": list(self.bounds), "enters": self.enters,
                "breaks_symmetry": self.breaks_symmetry, "dissipation_output": self.continuous,
                "physics": self.physics, "port_only": self.port_only,
                "screened": self.screened, "local": self.local}

    # ------------------------------------------------------------------------ hooks (neutral)
    def com_offsets(self, k: ca.SX, ctx: Context, d_st: ca.SX, d_sw: ca.SX) -> tuple[ca.SX, ca.SX]:
        """The stance and swing legs' centre-of-mass offsets in their body frames, shape (3, 1)."""
        return d_st, d_sw

    def gravity(self, k: ca.SX, ctx: Context, gvec: ca.SX) -> ca.SX:
        """Gravity in the (described) ramp frame, shape (3, 1) (m/s^2)."""
        return gvec

    def couples(self, k: ca.SX, ctx: Context) -> list[tuple[int, ca.SX]]:
        """Couples between collisions: ``(leg, M)`` with leg 1 = stance, 2 = swing, M (N m)."""
        return []

    def trailing_impulse(self, k: ca.SX, ctx: Context) -> ca.SX | None:
        """The trailing foot's normal impulse as a fraction of the collision's total normal
        impulse (dimensionless), or None."""
        return None

    def arrest(self, k: ca.SX, ctx: Context) -> Arrest | None:
        """A rate of the landing leg the collision arrests in part, or None."""
        return None
