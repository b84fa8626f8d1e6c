"""The library of physical effects that extend the seed's model (model.md section 6).

Each effect is a small unit (:class:`Effect`, one module per family) with one strength parameter
that reduces the model exactly to the seed's at its null value. :data:`EFFECTS` maps each
effect's name (its key in a parameter file's ``[effects]`` table) to the unit; the parameter
vector (:data:`toywalk.model.parameters.PARAMETER_NAMES`) and the compiled equations are built
from it, so adding an effect is one module and one line in :data:`_UNITS` below.
"""

from __future__ import annotations

from .asymmetry import Asymmetry, CrossSlope
from .base import Arrest, Context, Effect
from .contact import PivotFriction, RollingResistance
from .hip import COULOMB_SMOOTHING, HipCoulomb, HipDamping, coulomb_torque
from .impact import ImpactSpinArrest, ImpactTrailingShare

__all__ = ["COULOMB_SMOOTHING", "CONTINUOUS", "EFFECTS", "Arrest", "Context", "Effect",
           "coulomb_torque"]

_UNITS = (HipDamping(), HipCoulomb(), RollingResistance(), PivotFriction(), ImpactTrailingShare(),
          ImpactSpinArrest(), Asymmetry(), CrossSlope())

#: Registry of effects by name, in the order of the parameter vector.
EFFECTS: dict[str, Effect] = {e.name: e for e in _UNITS}

#: Names of the effects that act between collisions, in the order of the dissipation output.
CONTINUOUS: tuple[str, ...] = tuple(e.name for e in _UNITS if e.continuous)
