"""jaxskid: closed-form rigid-body equations of motion, derived in SymPy and lowered to JAX.

Every public name is imported on its first use (PEP 562), so ``import jaxskid`` and the command line's
help cost a few milliseconds and a script pays for SymPy, JAX and the applications only when it uses them.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from ._errors import (
    DescriptionWarning, IdentificationError, IdentificationWarning, InputError, JaxskidError, ModelError,
    PhysicalConsistencyWarning, RequestError, ShapeError,
)
from ._version import __version__
from ._xla_flags import keep_freed_memory, prefer_classic_emitters

prefer_classic_emitters()
keep_freed_memory()

if TYPE_CHECKING:  # the same names for type checkers and editors (tests/test_layout.py checks they agree)
    from .model._lie import pose, pose_xyzrpy, rot_axis_angle, rot_quaternion, rot_rpy, screw, spatial_inertia
    from .model._drive import Drive
    from .model._robot import Frame, Joint, JointLimits, Mimic, Robot, spatial_to_body, symbol
    from .model._constraint import FrameContact, LoopClosure, PointContact
    from .model._standard import params_from_standard, standard_parameter_names, standard_params
    from .equations import DEFAULT_QUANTITIES, QUANTITIES, Equations, Options, derive
    from .lowering._cache import cache_dir
    from .runtime._dynamics import Dynamics
    from .runtime._jit import compiler_options, jit
    from .lowering._xla_cache import compilation_cache
    from ._api import compile_native, load, lower
    from .lowering._native import BuildError
    from .runtime._native import NativeDynamics
    from . import codegen
    from .description._urdf import read_urdf
    from .runtime._forward import forward_dynamics, mass_matrix_condition
    from .runtime._constrained import Baumgarte, constrained_forward_dynamics, constrained_inverse_dynamics
    from .apps.simulation._field import Controller, vector_field
    from .apps.simulation._integrators import RK4, SemiImplicitEuler
    from .apps.simulation._saving import Checkpoint, SaveAt
    from .apps.simulation._rollout import Trajectory, rollout
    from .apps.simulation._field import HeldInput
    from .apps.simulation._motor import DCMotors
    from .apps.identification._identification import (
        Adam, BaseParameters, Estimate, FitResult, GradientDescent, GradientFit, LeastSquares, PhysicallyConsistent,
        WeightedLeastSquares, base_parameters, fit, identify, quantity_loss, trajectory_loss,
    )
    from .apps.identification._energy_id import EnergyBalance, energy_balance, momentum_balance
    from .apps.control._laws import ComputedTorque, PDGravity, SlotineLi, mixed_regressor, reference_derivatives
    from .apps.simulation._contact import GroundContact
    from .apps.simulation._health import RolloutWarning, StepStability, step_stability
    from .apps.identification._excitation import ExcitationResult, FourierTrajectory, design_excitation
    from .apps.identification._parameterizations import LogCholesky, Standard, nearest_consistent, physically_consistent
    from .apps.identification._signals import estimate_derivatives, lowpass, parallel_filter, quantize
    from .apps.identification._validation import Validation, plot_validation, validate
    from .description._yaml_schema import DescriptionExtras, parse_description, read_description, read_extras
    from .description._yaml_writer import robot_to_dict, write_description
    from .description._dh import DH, dh_robot
    from .description._urdf_writer import write_urdf
    from .description._report import describe, draw_tree
    from .description._collision import ContactPoints, collision_points

_EXPORTS = {  # module -> the public names it defines (a submodule's own name: the submodule)
    ".model._lie": "pose pose_xyzrpy rot_axis_angle rot_quaternion rot_rpy screw spatial_inertia",
    ".model._drive": "Drive",
    ".model._robot": "Frame Joint JointLimits Mimic Robot spatial_to_body symbol",
    ".model._constraint": "FrameContact LoopClosure PointContact",
    ".model._standard": "params_from_standard standard_parameter_names standard_params",
    ".equations": "DEFAULT_QUANTITIES QUANTITIES Equations Options derive",
    ".lowering._cache": "cache_dir",
    ".runtime._dynamics": "Dynamics",
    ".runtime._jit": "compiler_options jit",
    ".lowering._xla_cache": "compilation_cache",
    "._api": "compile_native load lower",
    ".lowering._native": "BuildError",
    ".runtime._native": "NativeDynamics",
    ".codegen": "codegen",
    ".description._urdf": "read_urdf",
    ".runtime._forward": "forward_dynamics mass_matrix_condition",
    ".runtime._constrained": "Baumgarte constrained_forward_dynamics constrained_inverse_dynamics",
    ".apps.simulation._field": "Controller vector_field HeldInput",
    ".apps.simulation._integrators": "RK4 SemiImplicitEuler",
    ".apps.simulation._saving": "Checkpoint SaveAt",
    ".apps.simulation._rollout": "Trajectory rollout",
    ".apps.simulation._motor": "DCMotors",
    ".apps.identification._identification": "Adam BaseParameters Estimate FitResult GradientDescent GradientFit "
                                             "LeastSquares PhysicallyConsistent WeightedLeastSquares base_parameters "
                                             "fit identify quantity_loss trajectory_loss",
    ".apps.identification._energy_id": "EnergyBalance energy_balance momentum_balance",
    ".apps.control._laws": "ComputedTorque PDGravity SlotineLi mixed_regressor reference_derivatives",
    ".apps.simulation._contact": "GroundContact",
    ".apps.simulation._health": "RolloutWarning StepStability step_stability",
    ".apps.identification._excitation": "ExcitationResult FourierTrajectory design_excitation",
    ".apps.identification._parameterizations": "LogCholesky Standard nearest_consistent physically_consistent",
    ".apps.identification._signals": "estimate_derivatives lowpass parallel_filter quantize",
    ".apps.identification._validation": "Validation plot_validation validate",
    ".description._yaml_schema": "DescriptionExtras parse_description read_description read_extras",
    ".description._yaml_writer": "robot_to_dict write_description",
    ".description._dh": "DH dh_robot",
    ".description._urdf_writer": "write_urdf",
    ".description._report": "describe draw_tree",
    ".description._collision": "ContactPoints collision_points",
}
_LAZY = {name: module for module, names in _EXPORTS.items() for name in names.split()}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'jaxskid' has no attribute {name!r}")
    value = importlib.import_module(module, __name__)
    if module != f".{name}":  # a name from a module, not the submodule itself
        value = getattr(value, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "DEFAULT_QUANTITIES",
    "BuildError",
    "Dynamics",
    "compiler_options",
    "jit",
    "Equations",
    "QUANTITIES",
    "cache_dir",
    "compilation_cache",
    "codegen",
    "compile_native",
    "derive",
    "load",
    "lower",
    "Drive",
    "Frame",
    "JaxskidError",
    "DescriptionWarning",
    "Joint",
    "JointLimits",
    "Mimic",
    "PointContact",
    "FrameContact",
    "LoopClosure",
    "Baumgarte",
    "constrained_forward_dynamics",
    "constrained_inverse_dynamics",
    "ModelError",
    "InputError",
    "PhysicalConsistencyWarning",
    "NativeDynamics",
    "Options",
    "RequestError",
    "IdentificationError",
    "IdentificationWarning",
    "Robot",
    "ShapeError",
    "pose",
    "read_urdf",
    "DescriptionExtras",
    "parse_description",
    "read_description",
    "read_extras",
    "robot_to_dict",
    "write_description",
    "DH",
    "dh_robot",
    "write_urdf",
    "describe",
    "draw_tree",
    "ContactPoints",
    "collision_points",
    "pose_xyzrpy",
    "rot_axis_angle",
    "rot_quaternion",
    "rot_rpy",
    "screw",
    "spatial_inertia",
    "standard_params",
    "standard_parameter_names",
    "params_from_standard",
    "RK4",
    "SemiImplicitEuler",
    "Controller",
    "DCMotors",
    "HeldInput",
    "Trajectory",
    "forward_dynamics",
    "mass_matrix_condition",
    "rollout",
    "SaveAt",
    "Checkpoint",
    "vector_field",
    "ComputedTorque",
    "GroundContact",
    "RolloutWarning",
    "StepStability",
    "step_stability",
    "PDGravity",
    "SlotineLi",
    "mixed_regressor",
    "reference_derivatives",
    "Adam",
    "BaseParameters",
    "Estimate",
    "FitResult",
    "GradientDescent",
    "GradientFit",
    "LeastSquares",
    "LogCholesky",
    "PhysicallyConsistent",
    "Standard",
    "WeightedLeastSquares",
    "base_parameters",
    "fit",
    "identify",
    "physically_consistent",
    "nearest_consistent",
    "Validation",
    "estimate_derivatives",
    "lowpass",
    "parallel_filter",
    "quantize",
    "plot_validation",
    "validate",
    "quantity_loss",
    "trajectory_loss",
    "ExcitationResult",
    "FourierTrajectory",
    "design_excitation",
    "EnergyBalance",
    "energy_balance",
    "momentum_balance",
    "spatial_to_body",
    "symbol",
]
