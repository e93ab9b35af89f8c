"""Applications of the lowered quantities, one subpackage per purpose:

* :mod:`~jaxskid.apps.simulation`: rollouts (integrators, controllers under ``lax.scan``, the states saved and
  checkpointed, diffrax solvers, ground contact, DC motors);
* :mod:`~jaxskid.apps.identification`: parameter identification (base parameters, least squares, physically
  consistent fits with optax, excitation trajectories, signal processing, validation);
* :mod:`~jaxskid.apps.control`: control laws (computed torque, PD + gravity, Slotine–Li);

and the numeric self-check of a lowered model (``_selfcheck``). Identification and control build on the
simulation's public names and not on each other (the import-linter contracts in ``pyproject.toml``)."""

from ._selfcheck import self_check
from .control import ComputedTorque, PDGravity, SlotineLi, mixed_regressor, reference_derivatives
from .identification import (
    Adam,
    BaseParameters,
    EnergyBalance,
    Estimate,
    ExcitationResult,
    FitResult,
    FourierTrajectory,
    GradientDescent,
    GradientFit,
    LeastSquares,
    LogCholesky,
    PhysicallyConsistent,
    Standard,
    Validation,
    WeightedLeastSquares,
    base_parameters,
    design_excitation,
    energy_balance,
    estimate_derivatives,
    fit,
    identify,
    lowpass,
    momentum_balance,
    nearest_consistent,
    parallel_filter,
    physically_consistent,
    plot_validation,
    quantity_loss,
    quantize,
    trajectory_loss,
    validate,
)
from .simulation import (
    RK4,
    Checkpoint,
    Controller,
    DCMotors,
    GroundContact,
    HeldInput,
    SaveAt,
    SemiImplicitEuler,
    Trajectory,
    rollout,
    vector_field,
)

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
