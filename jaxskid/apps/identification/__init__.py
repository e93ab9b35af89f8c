"""Inertial-parameter identification: base parameters, least squares and gradient fits (``_identification``),
parameterizations and physical consistency (``_parameterizations``, ``_consistent``), identification from the
energy and momentum balances (``_energy_id``), excitation trajectories (``_excitation``), the states estimated
from sampled positions (``_signals``) and cross-validation of the identified parameters (``_validation``).

A trajectory loss rolls the model out (:func:`jaxskid.apps.simulation.rollout`): identification uses the
simulation's public names, never its modules."""

from ._energy_id import EnergyBalance, energy_balance, momentum_balance
from ._excitation import ExcitationResult, FourierTrajectory, design_excitation
from ._identification import (
    Adam,
    BaseParameters,
    Estimate,
    FitResult,
    GradientDescent,
    GradientFit,
    LeastSquares,
    PhysicallyConsistent,
    WeightedLeastSquares,
    base_parameters,
    fit,
    identify,
    quantity_loss,
    trajectory_loss,
)
from ._parameterizations import LogCholesky, Standard, nearest_consistent, physically_consistent
from ._signals import estimate_derivatives, lowpass, parallel_filter, quantize
from ._validation import Validation, plot_validation, validate

__all__ = [
    "Adam", "BaseParameters", "EnergyBalance", "Estimate", "ExcitationResult", "FitResult", "FourierTrajectory",
    "GradientDescent", "GradientFit", "LeastSquares", "LogCholesky", "PhysicallyConsistent", "Standard",
    "Validation", "WeightedLeastSquares", "base_parameters", "design_excitation", "energy_balance",
    "estimate_derivatives", "fit", "identify", "lowpass", "momentum_balance", "nearest_consistent",
    "parallel_filter", "physically_consistent", "plot_validation", "quantity_loss", "quantize",
    "trajectory_loss", "validate",
]
