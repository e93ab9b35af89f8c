"""Applications of the lowered quantities: rollouts (integrators, controllers under ``lax.scan``, the states
saved and checkpointed, diffrax solvers), parameter identification (base parameters, least squares,
physically consistent fits with optax, excitation trajectories), control laws (computed torque, PD + gravity, Slotine–Li) and the
numeric self-check of a lowered model."""

from ._contact import GroundContact
from ._control import (
    ComputedTorque,
    PDGravity,
    SlotineLi,
    mixed_regressor,
    reference_derivatives,
)
from ._energy_id import EnergyBalance, energy_balance, momentum_balance
from ._excitation import ExcitationResult, FourierTrajectory, design_excitation
from ._field import Controller, HeldInput, vector_field
from ._identification import (
    Adam,
    BaseParameters,
    Estimate,
    FitResult,
    GradientDescent,
    GradientFit,
    LeastSquares,
    LogCholesky,
    PhysicallyConsistent,
    Standard,
    WeightedLeastSquares,
    base_parameters,
    fit,
    identify,
    physically_consistent,
    quantity_loss,
    trajectory_loss,
)
from ._integrators import RK4, SemiImplicitEuler
from ._motor import DCMotors
from ._parameterizations import nearest_consistent
from ._saving import Checkpoint, SaveAt
from ._selfcheck import self_check
from ._signals import estimate_derivatives, lowpass, parallel_filter, quantize
from ._simulate import Trajectory, rollout
from ._validation import Validation, plot_validation, validate

__all__ = [
    "RK4", "Adam", "BaseParameters", "Checkpoint", "ComputedTorque", "Controller", "GroundContact", "DCMotors", "Estimate",
    "FitResult", "GradientDescent", "GradientFit", "HeldInput", "LeastSquares", "LogCholesky", "PDGravity",
    "PhysicallyConsistent", "SaveAt", "SemiImplicitEuler",
    "SlotineLi", "Standard", "Trajectory", "WeightedLeastSquares", "base_parameters", "fit", "identify",
    "mixed_regressor", "physically_consistent", "quantity_loss", "reference_derivatives", "rollout", "self_check",
    "trajectory_loss", "vector_field", "EnergyBalance", "energy_balance", "momentum_balance",
    "Validation", "estimate_derivatives", "lowpass", "nearest_consistent", "parallel_filter", "plot_validation",
    "quantize", "validate", "ExcitationResult", "FourierTrajectory", "design_excitation",
]
