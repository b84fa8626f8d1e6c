"""The collision law's compliance: the trailing foot's share and the landing foot's spin arrest.

The seed's collision is instantaneous and plastic at the landing foot D, with no impulse on the
trailing foot (Coleman & Ruina 1998, eqs. 3-4). The toy's feet are spools covered by brass shim
strips, 5 mm wide, which "deform during foot collision in a way that may or may not be
essential". Two consequences of a compliant, finite contact, each reducing to the seed's law at 0:

- ``impact_trailing_share``: a short double support. The trailing foot (the old stance foot, at C)
  takes a share s of the collision's total normal impulse, ``lambda_C = s Lambda`` along the ramp
  normal, while still leaving the ground; the jump conditions gain the angular impulse of
  ``lambda_C e_z`` at C (about D for the whole walker, about the hip axis for the trailing leg).
  The impulse on a foot that lifts off does work, so admissibility (no energy gain, non-negative
  normal impulses at both feet) is not automatic: it holds over the bounds for the states tested
  (tests/model/test_effects.py), and every step checks it (:class:`toywalk.model.Walker`).
- ``impact_spin_arrest``: the landing strip meets the ramp on a patch, not a point, and grips: an
  impulsive couple about the ramp normal arrests a fraction k of the landing foot's spin (the
  steer rate the toy does not show). The post-collision rates blend, with weight k, the law above
  (with its trailing share) and the law in which the gripping landing patch takes the whole
  impulse and enforces ``omega_landing . e_z = 0`` (:class:`Arrest`). That law is a plastic
  projection (Carnot), so the blend gains no energy where the law it starts from gains none.
  Gripping needs a compressive normal impulse: near the shipped walkers' gaits it has one, far
  from them (and on point feet, which have no patch) it can need a pull, which the step refuses.
  Chosen over a restitution coefficient because a bouncing foot leaves the ramp, which the
  rolling-contact model cannot follow, and because spin is the rate that the seed's point contact
  leaves free and in which the toy shows "no visible variation" (Coleman & Ruina 1998).
- ``impact_lean_arrest`` (port-only, the heel-strike port's ``lean_loss``): as the spin arrest,
  about the heading axis h = Rz(phi) e_x instead of the ramp normal: the strip's width grips
  sideways and arrests a fraction k of the landing foot's lean rate (``omega_landing . h = psi'``).
  With the spin arrest on too, the collision blends the four laws (neither, either, both
  constraints; :class:`Arrest`), each plastic, so it gains no energy either.
"""

from __future__ import annotations

from .base import Arrest, Effect

__all__ = ["ImpactLeanArrest", "ImpactSpinArrest", "ImpactTrailingShare"]


class ImpactTrailingShare(Effect):
    """The trailing foot's share of the collision's normal impulse (dimensionless)."""

    name = "impact_trailing_share"
    unit = "1"
    null = 0.0
    typical = 0.1
    bounds = (0.0, 0.3)
    enters = "collision law"
    physics = ("the trailing foot takes a share s of the heel strike's normal impulse during a "
               "short double support, then leaves the ramp")

    def trailing_impulse(self, k, ctx):
        return k


class ImpactSpinArrest(Effect):
    """The fraction of the landing foot's spin (about the ramp normal) arrested at heel strike."""

    name = "impact_spin_arrest"
    unit = "1"
    null = 0.0
    typical = 0.5
    bounds = (0.0, 1.0)
    enters = "collision law"
    physics = ("the landing foot's contact patch grips: an impulsive couple about the ramp normal "
               "arrests a fraction k of its spin")

    def arrest(self, k, ctx):
        # In the planar reduction there is no spin: the arrested law is the seed's plastic law.
        return Arrest(strength=k, axis=ctx.ez)


class ImpactLeanArrest(Effect):
    """The fraction of the landing foot's lean rate (about the heading axis) arrested at heel
    strike."""

    name = "impact_lean_arrest"
    unit = "1"
    null = 0.0
    # impact_spin_arrest's; the stable toy leans little, so it acts on the gait's stability: the
    # largest eigenvalue 0.967 to 0.987 (docs/effects.md).
    typical = 0.5
    bounds = (0.0, 1.0)
    enters = "collision law"
    physics = ("the landing foot's strip grips sideways: an impulsive couple about the heading axis "
               "arrests a fraction k of its lean rate")
    port_only = True

    def arrest(self, k, ctx):
        # In the planar reduction there is no lean: the arrested law is the seed's plastic law.
        return Arrest(strength=k, axis=ctx.heading)
