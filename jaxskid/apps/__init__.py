"""Applications of the lowered quantities: rollouts (integrators, controllers under ``lax.scan``, the states
saved and checkpointed, diffrax solvers), parameter identification (base parameters, least squares,
physically consistent fits with optax), control laws (computed torque, PD + gravity, Slotine–Li) and the
numeric self-check of a lowered model."""

from ._control import (
    ComputedTorque,
    PDGravity,
    SlotineLi,
    mixed_regressor,
    reference_derivatives,
)
from ._field import Controller, vector_field
from ._identification import (
    Adam,
    BaseParameters,
    Estimate,
    FitResult,
    GradientDescent,
    GradientFit,
    LeastSquares,
    LogCholesky,
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
from ._saving import Checkpoint, SaveAt
from ._selfcheck import self_check
from ._simulate import Trajectory, rollout

__all__ = [
    "RK4", "Adam", "BaseParameters", "Checkpoint", "ComputedTorque", "Controller", "Estimate", "FitResult",
    "GradientDescent", "GradientFit", "LeastSquares", "LogCholesky", "PDGravity", "SaveAt", "SemiImplicitEuler",
    "SlotineLi", "Standard", "Trajectory", "WeightedLeastSquares", "base_parameters", "fit", "identify",
    "mixed_regressor", "physically_consistent", "quantity_loss", "reference_derivatives", "rollout", "self_check",
    "trajectory_loss", "vector_field",
]
