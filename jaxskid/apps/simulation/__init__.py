"""Rollouts of a lowered :class:`~jaxskid.Dynamics`: the equations of motion as a first-order system driven by
torques, a policy or a :class:`Controller` (``_field``), fixed-step integrators (``_integrators``) and diffrax
solvers (``_diffrax``), the ``lax.scan`` loops (``_loop``) that keep the states a :class:`SaveAt` names and
checkpoint the reverse pass (``_saving``), :func:`rollout` itself (``_rollout``), compliant ground contact
(``_contact``), DC motors (``_motor``) and the check that a fixed step integrates the closed loop stably
(``_health``)."""

from ._contact import GroundContact
from ._field import Controller, HeldInput, vector_field
from ._health import RolloutWarning, StepStability, step_stability
from ._integrators import RK4, SemiImplicitEuler
from ._motor import DCMotors
from ._rollout import Trajectory, rollout
from ._saving import Checkpoint, SaveAt

__all__ = [
    "RK4", "Checkpoint", "Controller", "DCMotors", "GroundContact", "HeldInput", "RolloutWarning", "SaveAt",
    "SemiImplicitEuler", "StepStability", "Trajectory", "rollout", "step_stability", "vector_field",
]
