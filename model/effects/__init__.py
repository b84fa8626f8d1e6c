"""The library of physical effects that extend the seed's model (docs/model.md section 6).

Each effect is a small unit (:class:`Effect`, one module per family) with one strength parameter
that reduces the model exactly to the seed's at its null value. :data:`EFFECTS` maps each
effect's name (its key in a parameter file's ``[effects]`` table) to the unit; the parameter
vector (:data:`toywalk.model.parameters.PARAMETER_NAMES`) and the compiled equations are built
from it, so adding an effect is one module and one line in :data:`_UNITS` below.
"""

from __future__ import annotations

from .asymmetry import Asymmetry, CrossSlope
from .base import Arrest, Context, Effect
from .contact import (
    PitchCoulomb,
    PitchDamping,
    PitchStiffness,
    PivotFriction,
    RollCoulomb,
    RollDamping,
    RollingResistance,
    RollStiffness,
    SpinCoulomb,
)
from .hip import (
    COULOMB_SMOOTHING,
    HingeBias,
    HingeCubicStiffness,
    HingeStiffness,
    HipCoulomb,
    HipDamping,
    coulomb_torque,
)
from .impact import ImpactLeanArrest, ImpactSpinArrest, ImpactTrailingShare
from .ports import PORTS, Port
from .soft import SoftHeel

__all__ = ["COULOMB_SMOOTHING", "CONTINUOUS", "EFFECTS", "LIBRARY", "PORTS", "Arrest", "Context",
           "Effect", "Port", "coulomb_torque"]

# The library's effects, then the port-only terms of the dictionary of generalised forces
# (:data:`toywalk.model.effects.ports.PORTS`), after them so that the library's parameter and
# dissipation indices stay where they were; effects added later go at the end for the same reason.
_UNITS = (HipDamping(), HipCoulomb(), RollingResistance(), PivotFriction(), ImpactTrailingShare(),
          ImpactSpinArrest(), Asymmetry(), CrossSlope(),
          HingeStiffness(), HingeCubicStiffness(), HingeBias(), RollDamping(), RollCoulomb(),
          RollStiffness(), PitchDamping(), PitchCoulomb(), PitchStiffness(), SpinCoulomb(),
          ImpactLeanArrest(), SoftHeel())

#: Registry of effects by name, in the order of the parameter vector.
EFFECTS: dict[str, Effect] = {e.name: e for e in _UNITS}

#: Names of the effects that act between collisions, in the order of the dissipation output.
CONTINUOUS: tuple[str, ...] = tuple(e.name for e in _UNITS if e.continuous)

#: Names of the library's effects proper: the causes the discrepancy analysis tries by default
#: (the registry less the port-only terms, :attr:`Effect.port_only`, and the effects not screened
#: by default yet, :attr:`Effect.screened`).
LIBRARY: tuple[str, ...] = tuple(e.name for e in _UNITS if not e.port_only and e.screened)
