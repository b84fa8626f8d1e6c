"""The walker model: parameters, equations of motion, collision, step map, gaits, simulation.

The names below load their module on first use (PEP 562), so that a tool that only reads files
(``toywalk.model.trajectory``, ``toywalk.model.files``) does not import CasADi.
"""

import importlib

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
    "can_stand": "statics",
    "describe_scuffs": "walker",
    "find_gait": "gait",
    "load_params": "parameters",
    "parameter_unit": "parameters",
    "save_params": "parameters",
    "simulate": "simulate",
    "solve_fixed_point": "gait",
    "static_margin": "statics",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
