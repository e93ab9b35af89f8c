"""The symbolic stage: closed-form kinematics and dynamics as a straight-line SymPy program.

A :class:`Derivation` holds the robot, its :class:`Inputs` (the symbols of q, qd, ..., tau, the wrenches
and the parameters), the :class:`Tape` every intermediate is named on and the memo that lets quantities
derived together share their work. Each algorithm is a function of the derivation, one per module:

* ``_kinematics``: relative and world poses, body twists and accelerations (:class:`Terms` chooses which);
* ``_frames``: named frames: poses, motion, hybrid quantities, loads;
* ``_rnea``: recursive Newton-Euler (tau, C qd, Q_grav, Q_ext);
* ``_crba``: composite-rigid-body algorithm (M);
* ``_jacobians``: body, hybrid and system Jacobians and their time derivatives;
* ``_constraints``: the constraints' Jacobian, drift and residual (contacts, loop closures);
* ``_coriolis``: the Christoffel-consistent Coriolis matrix;
* ``_time_kinematics`` and ``_time_dynamics``: closed-form time derivatives (Müller & Kumar 2021);
* ``_regressor``: the inertial-parameter regressor;
* ``_drives``: the joints' drives (armature, friction, offset) that M, tau, the bias and the regressor add;
* ``_forward``: forward dynamics by the symbolic sparse ``L^T D L`` of M;
* ``_adjoint``: differentiation of the tape, reverse mode (the vector-Jacobian product of inverse dynamics)
  and forward mode;
* ``_energy``: kinetic and potential energy;
* ``_centroidal``: the centre of mass, its Jacobian and the centroidal momentum matrix;
* ``_energy_regressor``: the energies, the momentum and the friction power as rows in the standard parameters;
* ``_lagrange``: the Euler-Lagrange route to M, C qd, Q_grav and tau, from the link energies.

The spatial algebra they share is :mod:`jaxskid.model._spatial`. A floating base is body ``-1`` of every
recursion, a joint with screw matrix ``I_6`` (:mod:`._derivation`, :mod:`._kinematics`).
"""

from . import _lagrange as lagrange
from ._adjoint import inverse_dynamics_vjp, jvp, pullback, vjp
from ._centroidal import center_of_mass, center_of_mass_jacobian, centroidal_momentum_matrix
from ._constraints import constraint_drift, constraint_jacobian, constraint_residual
from ._coriolis import coriolis_matrix
from ._crba import mass_matrix
from ._derivation import COTANGENTS, STATE_ORDERS, WRENCH_ORDERS, Derivation, Inputs, memoized
from ._drives import with_rotor_energy, with_rotor_momentum
from ._energy import kinetic_energy, momentum, potential_energy
from ._energy_regressor import (
    friction_power_regressor, kinetic_energy_regressor, momentum_regressor, potential_energy_regressor,
)
from ._forward import forward_dynamics
from ._frames import (
    body_hybrid_acceleration, body_hybrid_twist, frame_hybrid_acceleration, frame_hybrid_twist, frame_motion,
    frame_pose,
)
from ._jacobians import (
    body_jacobian, body_jacobian_dot, hybrid_jacobian, hybrid_jacobian_dot, system_jacobian, system_jacobian_dot,
)
from ._kinematics import Terms, absolute, acceleration, twist
from ._regressor import N_STANDARD, regressor
from ._rnea import coriolis_torques, external_torques, gravity_torques, inverse_dynamics
from ._tape import Tape
from ._time_dynamics import (
    coriolis_matrix_derivative, external_torques_derivative, mass_matrix_derivative, newton_euler_derivative,
)

__all__ = [
    "N_STANDARD",
    "STATE_ORDERS",
    "WRENCH_ORDERS",
    "COTANGENTS",
    "Derivation",
    "Inputs",
    "Tape",
    "Terms",
    "absolute",
    "acceleration",
    "body_hybrid_acceleration",
    "body_hybrid_twist",
    "body_jacobian",
    "body_jacobian_dot",
    "center_of_mass",
    "center_of_mass_jacobian",
    "centroidal_momentum_matrix",
    "constraint_drift",
    "constraint_jacobian",
    "constraint_residual",
    "coriolis_matrix",
    "coriolis_matrix_derivative",
    "coriolis_torques",
    "external_torques",
    "external_torques_derivative",
    "forward_dynamics",
    "inverse_dynamics_vjp",
    "jvp",
    "kinetic_energy",
    "kinetic_energy_regressor",
    "friction_power_regressor",
    "momentum_regressor",
    "potential_energy_regressor",
    "lagrange",
    "potential_energy",
    "frame_hybrid_acceleration",
    "frame_hybrid_twist",
    "frame_motion",
    "frame_pose",
    "gravity_torques",
    "hybrid_jacobian",
    "hybrid_jacobian_dot",
    "inverse_dynamics",
    "mass_matrix",
    "mass_matrix_derivative",
    "momentum",
    "memoized",
    "newton_euler_derivative",
    "regressor",
    "system_jacobian",
    "system_jacobian_dot",
    "twist",
    "pullback",
    "vjp",
    "with_rotor_energy",
    "with_rotor_momentum",
]
