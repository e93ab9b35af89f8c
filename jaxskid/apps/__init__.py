"""Applications of the lowered quantities: rollouts (integrators, controllers under ``lax.scan``),
parameter identification (base parameters, least squares, physically consistent fits with optax), control
laws (computed torque, PD + gravity, Slotine–Li) and the numeric self-check of a lowered model."""

from ._control import ComputedTorque, PDGravity, SlotineLi, mixed_regressor, reference_derivatives
from ._identification import (
    Adam, BaseParameters, Estimate, FitResult, GradientDescent, GradientFit, LeastSquares, LogCholesky, Standard,
    WeightedLeastSquares, base_parameters, fit, identify, physically_consistent, quantity_loss, trajectory_loss,
)
from ._selfcheck import self_check
from ._simulate import RK4, Controller, SemiImplicitEuler, Trajectory, rollout
