"""Contact couples at the stance foot: rolling resistance and pivot (spin) friction, and the
contact port's further terms about its three axes.

The seed's contact is a point that rolls without slip and transmits no couple. A real foot rolls
on a small deformed patch (the brass shim on a wooden ramp), which resists rolling and spinning.
Both couples act on the stance leg; the ramp, at rest, takes the reaction, so each dissipates
``-M . omega_st`` (docs/model.md section 6).

The contact port splits the couple along three orthonormal axes (:class:`Context`): the heading
``h = Rz(phi) e_x`` (roll: the lean psi), the pitch axis ``p = Rz(phi) e_y``, the hip axis in the
ramp plane (fore-aft rolling), and the ramp normal ``e_z`` (spin). On them the stance leg's
angular velocity is ``omega_st . h = psi'``, ``omega_st . p = theta_st' cos psi`` and
``omega_st . e_z = phi' + theta_st' sin psi``. Its terms are port-only (:attr:`Effect.port_only`):

- viscous roll and pitch couples (``roll_damping``, ``pitch_damping``): with equal strengths
  their sum is ``rolling_resistance`` (h and p span the ramp plane); the viscous spin couple is
  ``pivot_friction`` itself;
- dry (regularised Coulomb) couples about each axis (``roll_coulomb``, ``pitch_coulomb``,
  ``spin_coulomb``), as the hinge's (:func:`coulomb_torque`, :data:`COULOMB_SMOOTHING`);
- restoring couples (``roll_stiffness``, ``pitch_stiffness``), conservative with energies
  ``k psi^2 / 2`` and ``k theta_st^2 / 2``: ``M = -k psi h`` (its generalised force is ``-k psi``
  on psi alone, since h is normal to e_z and to n) and ``M = -k theta_st p / cos psi`` (``-k
  theta_st`` on theta_st alone; ``p . n = cos psi``). Spin has no such term: the walker's heading
  phi is no angle of the contact (the foot's heading at touchdown would be, and the state does not
  remember it), so a couple ``-k phi`` would be a spring to a fixed direction on the ramp.

Every term is written in the step's description, which the mirror maps onto itself (psi and phi
change sign with the couples' components about h and e_z), so none breaks the symmetry.
"""

from __future__ import annotations

from .base import Context, Effect
from .hip import COULOMB_SMOOTHING, coulomb_torque

# CasADi is imported where an expression is built, so that reading parameter files (the tracker
# does) does not load it (effects/base.py).

__all__ = ["PitchCoulomb", "PitchDamping", "PitchStiffness", "PivotFriction", "RollCoulomb",
           "RollDamping", "RollStiffness", "RollingResistance", "SpinCoulomb"]


class RollingResistance(Effect):
    """``M = -c (omega_st - (omega_st . e_z) e_z)``: resists the stance foot's rolling, fore-aft
    and sideways (the tangential part of its angular velocity)."""

    name = "rolling_resistance"
    unit = "N m s/rad"
    null = 0.0
    typical = 2e-4
    bounds = (0.0, 1.0)
    enters = "contact couple"
    physics = "viscous couple opposing the stance foot's rolling (tangential angular velocity)"

    def couples(self, k, ctx):
        import casadi as ca

        ez = ctx.ez
        tangential = ctx.w1 - ca.dot(ctx.w1, ez) * ez
        return [(1, -k * tangential)]


class PivotFriction(Effect):
    """``M = -c (omega_st . e_z) e_z``: resists the stance foot's spin about the ramp normal, which
    the seed's model leaves free (the toy shows "no visible variation in phi")."""

    name = "pivot_friction"
    unit = "N m s/rad"
    null = 0.0
    typical = 1e-3
    bounds = (0.0, 1.0)
    enters = "contact couple"
    physics = "viscous couple about the ramp normal opposing the stance foot's spin"

    def couples(self, k, ctx):
        import casadi as ca

        ez = ctx.ez
        return [(1, -k * ca.dot(ctx.w1, ez) * ez)]


class _ContactPort(Effect):
    """A port term: a couple on the stance leg along one axis (:meth:`axis`), of a strength
    (:meth:`torque`) that depends on the stance leg's angular velocity about it."""

    null = 0.0
    enters = "contact couple"
    port_only = True

    def axis(self, ctx: Context):
        raise NotImplementedError

    def torque(self, k, ctx: Context, rate):
        raise NotImplementedError

    def couples(self, k, ctx):
        import casadi as ca

        a = self.axis(ctx)
        return [(1, self.torque(k, ctx, ca.dot(ctx.w1, a)) * a)]


class _Viscous(_ContactPort):
    unit = "N m s/rad"
    typical = 2e-4  # rolling_resistance's: the pitch's shortens the stable toy's stride by 5 %
    bounds = (0.0, 1.0)

    def torque(self, k, ctx, rate):
        return -k * rate


class _Dry(_ContactPort):
    unit = "N m"
    typical = 5e-4  # hip_coulomb's: the pitch's and the spin's shorten the stable toy's step by 1.2 %
    bounds = (0.0, 1.0)

    def torque(self, k, ctx, rate):
        return coulomb_torque(k, rate, COULOMB_SMOOTHING * ctx.rate_unit)


class _Roll:
    def axis(self, ctx):
        return ctx.heading


class _Pitch:
    def axis(self, ctx):
        return ctx.pitch_axis


class _Spin:
    def axis(self, ctx):
        return ctx.ez


class RollDamping(_Roll, _Viscous):
    """``M = -c (omega_st . h) h``: viscous couple opposing the stance foot's sideways roll."""

    name = "roll_damping"
    # The stable toy leans by 0.3 degrees only: roll terms act on its stability, not its gait's
    # shape. 2e-3 moves the largest eigenvalue from 0.967 to 0.979 (docs/effects.md).
    typical = 2e-3
    physics = "viscous couple -c psi' about the heading axis opposing the stance foot's roll (lean)"


class PitchDamping(_Pitch, _Viscous):
    """``M = -c (omega_st . p) p``: viscous couple opposing the stance foot's fore-aft rolling."""

    name = "pitch_damping"
    physics = "viscous couple about the in-plane hip axis opposing the stance foot's fore-aft rolling"


class RollCoulomb(_Roll, _Dry):
    """Dry couple about the heading axis opposing the stance foot's roll, regularised."""

    name = "roll_coulomb"
    typical = 2e-3  # the largest eigenvalue 0.967 to 0.984, the step 0.8 % shorter (docs/effects.md)
    physics = "dry-friction couple of magnitude T about the heading axis opposing the foot's roll"


class PitchCoulomb(_Pitch, _Dry):
    """Dry couple about the in-plane hip axis opposing the foot's fore-aft rolling, regularised."""

    name = "pitch_coulomb"
    physics = "dry-friction couple of magnitude T about the in-plane hip axis opposing fore-aft rolling"


class SpinCoulomb(_Spin, _Dry):
    """Dry couple about the ramp normal opposing the stance foot's spin, regularised (the dry
    counterpart of ``pivot_friction``)."""

    name = "spin_coulomb"
    physics = "dry-friction couple of magnitude T about the ramp normal opposing the foot's spin"


class RollStiffness(_Roll, _ContactPort):
    """``M = -k psi h``: a restoring couple against the lean, energy ``k psi^2 / 2``."""

    name = "roll_stiffness"
    unit = "N m/rad"
    typical = 0.02  # the largest eigenvalue 0.967 to 0.986 (docs/effects.md)
    # Negative: a couple that tips the foot over (a foot more rounded than the torus), physical;
    # -0.05 N m/rad is past where the stable toy's gait is lost.
    bounds = (-0.05, 1.0)
    physics = "restoring couple -k psi about the heading axis at the stance contact (lean stiffness)"

    def torque(self, k, ctx, rate):
        return -k * ctx.q4[1]


class PitchStiffness(_Pitch, _ContactPort):
    """``M = -k theta_st p / cos psi``: a restoring couple against the stance leg's pitch, with
    generalised force ``-k theta_st`` on theta_st alone, energy ``k theta_st^2 / 2``."""

    name = "pitch_stiffness"
    unit = "N m/rad"
    typical = 2e-3  # the step 1.5 % shorter, the stride 2.3 % longer (docs/effects.md)
    bounds = (-0.05, 1.0)  # as roll_stiffness's
    physics = "restoring couple -k theta_st about the in-plane hip axis at the stance contact"

    def torque(self, k, ctx, rate):
        import casadi as ca

        return -k * ctx.q4[2] / ca.cos(ctx.q4[1])
