"""jaxskid: closed-form rigid-body equations of motion, derived in SymPy and lowered to JAX."""

from ._errors import (
    DescriptionWarning, IdentificationError, IdentificationWarning, JaxskidError, ModelError, RequestError, ShapeError,
)
from .model._lie import pose, pose_xyzrpy, rot_axis_angle, rot_quaternion, rot_rpy, screw, spatial_inertia
from .model._drive import Drive
from .model._robot import Frame, Joint, JointLimits, Mimic, Robot, spatial_to_body, symbol
from .model._constraint import FrameContact, LoopClosure, PointContact
from .model._standard import params_from_standard, standard_parameter_names, standard_params
from .equations import DEFAULT_QUANTITIES, QUANTITIES, Equations, Options, derive
from .lowering._cache import cache_dir
from .runtime._dynamics import Dynamics
from .runtime._jit import compiler_options, jit, prefer_classic_emitters
from .lowering._xla_cache import compilation_cache
from ._api import compile_native, load, lower
from .lowering._native import BuildError
from .runtime._native import NativeDynamics
from . import codegen
from .description._urdf import read_urdf
from .runtime._forward import forward_dynamics, mass_matrix_condition
from .runtime._constrained import Baumgarte, constrained_forward_dynamics, constrained_inverse_dynamics
from .apps._field import Controller, vector_field
from .apps._integrators import RK4, SemiImplicitEuler
from .apps._saving import Checkpoint, SaveAt
from .apps._simulate import Trajectory, rollout
from .apps._field import HeldInput
from .apps._motor import DCMotors
from .apps._identification import (
    Adam, BaseParameters, Estimate, FitResult, GradientDescent, GradientFit, LeastSquares, LogCholesky,
    PhysicallyConsistent, Standard, WeightedLeastSquares, base_parameters, fit, identify, physically_consistent,
    quantity_loss, trajectory_loss,
)
from .apps._energy_id import EnergyBalance, energy_balance, momentum_balance
from .apps._control import ComputedTorque, PDGravity, SlotineLi, mixed_regressor, reference_derivatives
from .apps._contact import GroundContact
from .apps._excitation import ExcitationResult, FourierTrajectory, design_excitation
from .apps._parameterizations import nearest_consistent
from .apps._signals import estimate_derivatives, lowpass, parallel_filter, quantize
from .apps._validation import Validation, plot_validation, validate
from .description._yaml_schema import DescriptionExtras, parse_description, read_description, read_extras
from .description._yaml_writer import robot_to_dict, write_description
from .description._dh import DH, dh_robot
from .description._urdf_writer import write_urdf
from .description._report import describe, draw_tree

from ._version import __version__

prefer_classic_emitters()

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
