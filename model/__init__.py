"""The walker model: parameters, equations of motion, collision, step map, gaits, simulation."""

from .effects import EFFECTS, Effect
from .gait import Gait, GaitNotFound, find_gait, solve_fixed_point
from .parameters import PARAMETER_NAMES, ParameterError, Params, load_params, save_params
from .simulate import Trajectory, simulate
from .statics import StandingReport, can_stand, static_margin
from .walker import STATE_NAMES, Cycle, Step, StepFailure, Walker

__all__ = [
    "EFFECTS",
    "PARAMETER_NAMES",
    "STATE_NAMES",
    "Cycle",
    "Effect",
    "Gait",
    "GaitNotFound",
    "ParameterError",
    "Params",
    "StandingReport",
    "Step",
    "StepFailure",
    "Trajectory",
    "Walker",
    "can_stand",
    "find_gait",
    "load_params",
    "save_params",
    "simulate",
    "solve_fixed_point",
    "static_margin",
]
