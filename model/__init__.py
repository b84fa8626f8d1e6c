"""The walker model: parameters, equations of motion, collision, step map, gaits, simulation.

The names below load their module on first use (PEP 562), so that a tool that only reads files
(``toywalk.model.trajectory``, ``toywalk.model.files``) does not import CasADi.
"""

from .exports import lazy_names

#: Each public name and the submodule that defines it.
_WHERE = {
    "Cycle": "walker",
    "EFFECTS": "effects",
    "Effect": "effects",
    "Gait": "gait",
    "GaitNotFound": "gait",
    "PARAMETER_NAMES": "parameters",
    "ParameterError": "parameters",
    "Params": "parameters",
    "STATE_NAMES": "walker",
    "StandingReport": "statics",
    "Step": "walker",
    "StepFailure": "walker",
    "Trajectory": "simulate",
    "Walker": "walker",
    "all_gaits": "gait_search",
    "basin_radius": "basin",
    "can_stand": "statics",
    "describe_scuffs": "walker",
    "find_gait": "gait",
    "hand_launch": "basin",
    "load_params": "parameters",
    "parameter_unit": "parameters",
    "recovers": "basin",
    "recovery_curve": "basin",
    "save_params": "parameters",
    "simulate": "simulate",
    "solve_fixed_point": "gait",
    "static_margin": "statics",
    "strike_resolution": "gait",
}

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_names(__name__, _WHERE, globals())
