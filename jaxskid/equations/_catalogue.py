"""The catalogue: every quantity jaxskid can derive, declared here and only here, in a fixed order.

The order of :data:`QUANTITIES` is the canonical order of a request (:func:`jaxskid.equations.resolve`),
and through it part of the cache key of every generated module: append new quantities at the end.
Each entry names the arguments, the output shape and the builder: a function of a
:class:`jaxskid.symbolic.Derivation` that returns the outputs, flat and row-major. Shapes are in the robot's
velocity space: ``nv = 6 + n`` with a floating base (its twist or wrench first), ``n`` otherwise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import MappingProxyType

from .. import symbolic as sym
from ..model._robot import Robot
from ..model._constraint import n_rows
from ..model._standard import n_standard
from ..symbolic import Derivation, Terms


@dataclass(frozen=True)
class QuantitySpec:
    """How to derive a quantity: arguments, shape and a builder over a :class:`~jaxskid.symbolic.Derivation`."""

    name: str
    args: tuple[str, ...]
    shape: Callable[[Robot], tuple[int, ...]]
    build: Callable[[Derivation], list]
    equation: str
    doc: str
    needs_end_effector: bool = False
    derivatives: tuple[str, ...] = ()
    """Quantities the runtime differentiates this one with; :func:`jaxskid.lower` adds them to a request."""
    lagrange: Callable[[Derivation], list] | None = None
    """The builder of the Euler-Lagrange route (``Options(route="lagrange")``), where that route derives the
    quantity its own way; ``None``: both routes build it with ``build``."""
    needs_constraints: bool = False
    """Whether it exists only for a robot with constraints (:attr:`Robot.constraints`)."""
    pullback_of: str | None = None
    """For a pullback (``<name>_vjp``): the quantity it differentiates; :func:`~jaxskid.equations.derive` builds
    it from that quantity's outputs, by the same route (:func:`~jaxskid.symbolic.pullback`)."""
    needs_inertia: bool = True
    """Whether it depends on the bodies' mass-inertia; ``False`` for the kinematic quantities, which a robot
    with bodies :attr:`~jaxskid.Robot.without_inertia` still has."""

    def builder(self, route: str) -> Callable[[Derivation], list]:
        """The builder of ``route`` (``"screw"`` or ``"lagrange"``)."""
        return self.lagrange if route == "lagrange" and self.lagrange is not None else self.build


# ---------------------------------------------------------------------------------------------- builders
def _flat(rows) -> list:
    out = []
    for r in rows:
        if isinstance(r, (list, tuple)):
            out.extend(_flat(r))
        else:
            out.append(r)
    return out


def _matrix(m) -> list:
    return _flat(m.tolist())


def _pose_entries(r, p) -> list:
    return [*r[0], p[0], *r[1], p[1], *r[2], p[2], 0, 0, 0, 1]


def _bodies(d: Derivation, fn) -> list:
    """``fn(d, i)`` for every body, stacked."""
    return _flat([fn(d, i) for i in range(d.n)])


def _end_effectors(d: Derivation, fn) -> list:
    """``fn(d, name)`` for every end-effector, stacked."""
    return _flat([fn(d, name) for name in d.robot.end_effectors])


def _ee_matrices(d: Derivation, fn) -> list:
    """``fn(d, name)``, nv columns of 6, as a 6 x nv matrix for every end-effector, stacked."""
    out = []
    for name in d.robot.end_effectors:
        cols = fn(d, name)
        out.append([[c[k] for c in cols] for k in range(6)])
    return _flat(out)


def _parent_body(fn) -> Callable[[Derivation, str], list]:
    """``fn`` of the body an end-effector is attached to (its ``ee_parent``: a link, or the base), given the
    end-effector's name."""
    def of_parent(d: Derivation, name: str) -> list:
        body = d.robot.frame(name).body
        return fn(d, d.robot.base if body < 0 else d.robot.joints[body].link)
    return of_parent


def _wrenches(d: Derivation, order: int) -> dict:
    """The end-effector wrench symbols of a time-derivative order, by end-effector name."""
    return {name: list(d.inputs.wrenches[order][e]) for e, name in enumerate(d.robot.end_effectors)}


# ---------------------------------------------------------------------------------------------- shapes
def _square(r: Robot) -> tuple[int, ...]:
    return (r.nv, r.nv)


def _vector(r: Robot) -> tuple[int, ...]:
    return (r.nv,)


def _per_body(r: Robot) -> tuple[int, ...]:
    return (r.n_bodies, 6)


def _per_ee(r: Robot) -> tuple[int, ...]:
    return (len(r.end_effectors), 6)


def _ee_jacobian(r: Robot) -> tuple[int, ...]:
    return (len(r.end_effectors), 6, r.nv)


def _system(r: Robot) -> tuple[int, ...]:
    return (6 * (r.n_bodies + r.floating_base), r.nv)


def _poses(r: Robot) -> tuple[int, ...]:
    return (len(r.frame_names), 4, 4)


def _scalar(r: Robot) -> tuple[int, ...]:
    return ()


def _vjp(r: Robot) -> tuple[int, ...]:
    return (r.nq + r.nv + len(r.parameters),)


def _argument_size(r: Robot, arg: str) -> int:
    """Entries of one state of a state or wrench argument: ``nq`` for ``q``, ``6 n_ee`` for a wrench, else ``nv``."""
    return r.nq if arg == "q" else 6 * len(r.end_effectors) if arg.startswith("wrench") else r.nv


def _pullback_shape(args: tuple[str, ...]) -> Callable[[Robot], tuple[int, ...]]:
    return lambda r: (sum(_argument_size(r, a) for a in args) + len(r.parameters),)


def _pullback(base: str, args: tuple[str, ...], cotangent: str, matrix: str, needs: str = "inertia") -> QuantitySpec:
    """The pullback of ``base`` (arguments ``args``): the gradients of ``<W, base>`` with respect to its state
    arguments and the parameters, concatenated. The runtime differentiates ``base`` with it in reverse mode.
    ``needs`` is what ``base`` needs of the robot: ``"inertia"``, ``"end_effector"`` (a kinematic quantity of
    the end-effectors) or ``"constraints"``."""
    wrt = ", ".join(f"d/d{a}" for a in (*args, "p"))
    return QuantitySpec(
        f"{base}_vjp", (*args, cotangent), _pullback_shape(args), _no_builder,
        f"({wrt}) of sum W * {matrix}",
        f"Vector-Jacobian product of {base} with W = {cotangent}: the gradients of the weighted sum of its "
        f"entries with respect to {', '.join(args)} and the parameters, concatenated (nq entries for q, 6 per "
        "end-effector for a wrench, nv for the others, then one per parameter), by a symbolic reverse sweep of its "
        f"program. It gives jax.grad through {base} at a few times the cost of {base} itself.",
        pullback_of=base, needs_inertia=needs == "inertia", needs_end_effector=needs == "end_effector",
        needs_constraints=needs == "constraints",
    )


def _no_builder(d: Derivation) -> list:
    raise AssertionError("a pullback is built from its quantity's outputs by derive()")


def _regressor(r: Robot) -> tuple[int, ...]:
    return (r.nv, n_standard(r))


def _standard_row(r: Robot) -> tuple[int, ...]:
    return (n_standard(r),)


def _centroidal(rows: int) -> Callable[[Robot], tuple[int, ...]]:
    return lambda r: (rows, r.nv)


# ---------------------------------------------------------------------------------------------- time derivatives
def _time_derivatives(k: int) -> tuple[QuantitySpec, ...]:
    """The k-th time derivatives (k = 1: ``_dot``, k = 2: ``_ddot``) of M, C, Q_grav, tau and Q_ext."""
    suffix, word, dt = {1: ("_dot", "First", "d/dt"), 2: ("_ddot", "Second", "d^2/dt^2")}[k]
    state = ("q", "qd", "qdd", "q3d", "q4d")
    wrenches = ("wrench", "wrench_d", "wrench_dd")[: k + 1]
    return (
        QuantitySpec(
            "mass_matrix" + suffix, state[: k + 1], _square, lambda d: _matrix(sym.mass_matrix_derivative(d, k)),
            f"{dt} M(q)",
            f"{word} time derivative of the mass matrix: composite-rigid-body pass over the derivatives of the "
            "composite inertias (Müller & Kumar 2021); dM/dt = C + C^T.",
        ),
        QuantitySpec(
            "coriolis_matrix" + suffix, state[: k + 2], _square,
            lambda d: _matrix(sym.coriolis_matrix_derivative(d, k)),
            f"{dt} C(q, qd)",
            f"{word} time derivative of the Coriolis matrix of coriolis_matrix (in the factorisation of "
            "Options.coriolis).",
        ),
        QuantitySpec(
            "gravity_torques" + suffix, state[: k + 1], _vector,
            lambda d: sym.newton_euler_derivative(d, k, Terms.GRAVITY),
            f"{dt} Q_grav(q)",
            f"{word} time derivative of the generalized gravity forces (differentiated Newton-Euler pass).",
        ),
        QuantitySpec(
            "inverse_dynamics" + suffix, state[: k + 3], _vector,
            lambda d: sym.newton_euler_derivative(d, k, Terms.INVERSE_DYNAMICS),
            f"{dt} tau = {dt} (M qdd + C qd + Q_grav)",
            f"{word} time derivative of the joint forces along a motion with jerk q3d"
            + (" and jounce q4d" if k == 2 else "") + " (differentiated Newton-Euler pass).",
        ),
        QuantitySpec(
            "external_torques" + suffix, (*state[: k + 1], *wrenches), _vector,
            lambda d: sym.external_torques_derivative(d, [_wrenches(d, r) for r in range(k + 1)], k),
            f"{dt} Q_ext = {dt} sum_e J_e^T W_e",
            f"{word} time derivative of the generalized end-effector forces, from the wrenches and their "
            f"time derivatives ({', '.join(wrenches[1:])}), (moment, force) in each end-effector's frame.",
            needs_end_effector=True, needs_inertia=False,
        ),
    )


# ---------------------------------------------------------------------------------------------- the catalogue
_CATALOGUE = (
    QuantitySpec(
        "mass_matrix", ("q",), _square, lambda d: _matrix(sym.mass_matrix(d)),
        "M(q) = J^T diag(M_i) J", "Joint-space mass (inertia) matrix, symmetric positive definite.",
        lagrange=lambda d: _matrix(sym.lagrange.mass_matrix(d)), derivatives=("mass_matrix_vjp",),
    ),
    QuantitySpec(
        "coriolis_matrix", ("q", "qd"), _square, lambda d: _matrix(sym.coriolis_matrix(d)),
        "C(q, qd) = J^T (diag(M_i) dJ/dt + B(V) J)",
        "Coriolis/centrifugal matrix; C qd are the Coriolis forces. Options.coriolis picks B: 'christoffel' "
        "(default; dM/dt - 2C is skew-symmetric, Pinocchio's C) or 'skidy' (B(V) = -ad(V)^T M, Skidy's C).",
        derivatives=("coriolis_matrix_vjp",),
    ),
    QuantitySpec(
        "coriolis_torques", ("q", "qd"), _vector, sym.coriolis_torques,
        "C(q, qd) qd", "Coriolis and centrifugal generalized forces (recursive Newton-Euler).",
        lagrange=sym.lagrange.coriolis_torques, derivatives=("coriolis_torques_vjp",),
    ),
    QuantitySpec(
        "gravity_torques", ("q",), _vector, sym.gravity_torques,
        "Q_grav(q)", "Generalized gravity forces: the torques that hold the robot still.",
        lagrange=sym.lagrange.gravity_torques, derivatives=("gravity_torques_vjp",),
    ),
    QuantitySpec(
        "inverse_dynamics", ("q", "qd", "qdd"), _vector, sym.inverse_dynamics,
        "tau = M(q) qdd + C(q, qd) qd + Q_grav(q)",
        "Joint forces for a motion (recursive Newton-Euler); add external_torques for end-effector loads.",
        lagrange=sym.lagrange.inverse_dynamics, derivatives=("inverse_dynamics_vjp", "mass_matrix"),
    ),
    QuantitySpec(
        "external_torques", ("q", "wrench"), _vector, lambda d: sym.external_torques(d, _wrenches(d, 0)),
        "Q_ext = sum_e J_e(q)^T W_e",
        "Generalized forces of end-effector wrenches W_e (moment, force) in each end-effector's frame; "
        "W_e is what the end-effector exerts on its environment, so tau = M qdd + C qd + Q_grav + Q_ext.",
        needs_end_effector=True, needs_inertia=False, derivatives=("external_torques_vjp",),
    ),
    QuantitySpec(
        "forward_kinematics", ("q",), _poses,
        lambda d: _flat([_pose_entries(*sym.frame_pose(d, name)) for name in d.robot.frame_names]),
        "C_f(q) = C_body(q) T_f", "World pose of every named frame (bodies, merged links, end-effectors).",
        needs_inertia=False,
    ),
    QuantitySpec(
        "body_jacobian", ("q",), _ee_jacobian, lambda d: _ee_matrices(d, sym.body_jacobian),
        "V_e = J_e(q) qd, body-fixed", "Body Jacobian of each end-effector: twist (omega, v) in its own frame.",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "hybrid_jacobian", ("q",), _ee_jacobian, lambda d: _ee_matrices(d, sym.hybrid_jacobian),
        "V_e^h = J_e^h(q) qd", "Hybrid Jacobian of each end-effector: (omega, velocity of the origin) in world axes.",
        needs_end_effector=True, needs_inertia=False,
    ),
    *_time_derivatives(1),
    *_time_derivatives(2),
    QuantitySpec(
        "body_twist", ("q", "qd"), _per_body, lambda d: _bodies(d, sym.twist),
        "V_i^ = C_i^-1 dC_i/dt, (omega, v)", "Body twist of every moving body, in its own frame.",
        needs_inertia=False,
    ),
    QuantitySpec(
        "hybrid_twist", ("q", "qd"), _per_body, lambda d: _bodies(d, sym.body_hybrid_twist),
        "V_i^h = (R_i omega_i, dp_i/dt)",
        "Hybrid twist of every moving body: angular velocity and velocity of the frame origin, world axes.",
        needs_inertia=False,
    ),
    QuantitySpec(
        "body_acceleration", ("q", "qd", "qdd"), _per_body,
        lambda d: _bodies(d, lambda d_, i: sym.acceleration(d_, i, Terms.MOTION)),
        "dV_i/dt", "Time derivative of the body twist of every moving body (Pinocchio's LOCAL spatial "
        "acceleration); gravity not included.",
        needs_inertia=False,
    ),
    QuantitySpec(
        "hybrid_acceleration", ("q", "qd", "qdd"), _per_body, lambda d: _bodies(d, sym.body_hybrid_acceleration),
        "dV_i^h/dt = (domega_i/dt, d^2p_i/dt^2)",
        "Time derivative of the hybrid twist of every moving body: angular acceleration and classical "
        "acceleration of the frame origin, world axes; gravity not included.",
        needs_inertia=False,
    ),
    QuantitySpec(
        "ee_body_twist", ("q", "qd"), _per_ee, lambda d: _end_effectors(d, lambda d_, f: sym.frame_motion(d_, f, 0)),
        "V_e = J_e qd", "Body twist (omega, v) of each end-effector, in its own frame.",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "ee_hybrid_twist", ("q", "qd"), _per_ee, lambda d: _end_effectors(d, sym.frame_hybrid_twist),
        "V_e^h = J_e^h qd = (omega, dp_e/dt)", "Hybrid twist of each end-effector (world axes, at its origin).",
        needs_end_effector=True, needs_inertia=False, derivatives=("ee_hybrid_twist_vjp",),
    ),
    QuantitySpec(
        "ee_body_acceleration", ("q", "qd", "qdd"), _per_ee,
        lambda d: _end_effectors(d, lambda d_, f: sym.frame_motion(d_, f, 1)),
        "dV_e/dt = J_e qdd + dJ_e/dt qd", "Time derivative of each end-effector's body twist; gravity not included.",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "ee_hybrid_acceleration", ("q", "qd", "qdd"), _per_ee,
        lambda d: _end_effectors(d, sym.frame_hybrid_acceleration),
        "dV_e^h/dt = J_e^h qdd + dJ_e^h/dt qd = (domega/dt, d^2p_e/dt^2)",
        "Time derivative of each end-effector's hybrid twist (classical acceleration of its origin, world axes).",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "system_jacobian", ("q",), _system, lambda d: _flat(sym.system_jacobian(d)),
        "V = J qd, J = (I - A)^-1 X",
        "Body-fixed system Jacobian: block row i is body i's body Jacobian (rows (omega, v) in body i's frame); "
        "a floating base's block row (I_6, 0) comes first.",
        needs_inertia=False,
    ),
    QuantitySpec(
        "system_jacobian_dot", ("q", "qd"), _system, lambda d: _flat(sym.system_jacobian_dot(d)),
        "dJ/dt, dV/dt = J qdd + dJ/dt qd", "Time derivative of the body-fixed system Jacobian.",
        needs_inertia=False,
    ),
    QuantitySpec(
        "body_jacobian_dot", ("q", "qd"), _ee_jacobian, lambda d: _ee_matrices(d, sym.body_jacobian_dot),
        "dJ_e/dt", "Time derivative of each end-effector's body Jacobian.",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "hybrid_jacobian_dot", ("q", "qd"), _ee_jacobian, lambda d: _ee_matrices(d, sym.hybrid_jacobian_dot),
        "dJ_e^h/dt = blockdiag(R, R) (omega~ J_e + dJ_e/dt)",
        "Time derivative of each end-effector's hybrid Jacobian.",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "forward_dynamics", ("q", "qd", "tau"), _vector, lambda d: sym.forward_dynamics(d, d.inputs.tau),
        "qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q))",
        "Forward dynamics in closed form: M = L^T D L factored symbolically with the tree's sparsity "
        "(Featherstone 2005), then solved by substitution. End-effector wrenches: pass tau - Q_ext.",
        derivatives=("mass_matrix", "inverse_dynamics", "inverse_dynamics_vjp"),
    ),
    QuantitySpec(
        "regressor", ("q", "qd", "qdd"), _regressor, lambda d: _flat(sym.regressor(d)),
        "tau = Y(q, qd, qdd) pi",
        "Inertial-parameter regressor: tau is Y times the standard parameters pi, 10 columns per body in the "
        "order m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (inertia about the body frame origin; Pinocchio's "
        "order; Skidy's swaps Iyy and Ixz), then the drives' Ia, fv, fc, fo; see jaxskid.standard_params.",
    ),
    QuantitySpec(
        "inverse_dynamics_vjp", ("q", "qd", "qdd", "cotangent"), _vjp, sym.inverse_dynamics_vjp,
        "(w^T dtau/dq, w^T dtau/dqd, w^T dtau/dp)",
        "Vector-Jacobian product of inverse dynamics at fixed qdd, w = cotangent: the gradients of w^T tau "
        "with respect to q, qd and the parameters, concatenated (nq + nv + n_params entries), by a symbolic "
        "reverse sweep of the Newton-Euler program. It differentiates forward dynamics in rollouts.",
    ),
    QuantitySpec(
        "kinetic_energy", ("q", "qd"), _scalar, lambda d: [sym.with_rotor_energy(d, sym.kinetic_energy(d))],
        "K(q, qd) = 1/2 sum_i V_i^T M_i V_i = 1/2 qd^T M(q) qd",
        "Kinetic energy of the robot (a scalar).",
        lagrange=lambda d: [sym.lagrange.kinetic_energy(d)],
    ),
    QuantitySpec(
        "potential_energy", ("q",), _scalar, lambda d: [sym.potential_energy(d)],
        "U(q) = -sum_i m_i g^T c_i, dU/dq = Q_grav(q)",
        "Gravitational potential energy of the robot (a scalar), zero with every centre of mass at the world "
        "origin.",
    ),
    QuantitySpec(
        "momentum", ("q", "qd"), _vector, lambda d: sym.with_rotor_momentum(d, sym.momentum(d)),
        "p(q, qd) = dK/dqd = M(q) qd", "Generalized momentum: the body momenta carried to the joints.",
        lagrange=sym.lagrange.momenta,
    ),
    # The energy regressors serve both routes: they are rows of the same energies, not equations of motion.
    QuantitySpec(
        "kinetic_energy_regressor", ("q", "qd"), _standard_row, sym.kinetic_energy_regressor,
        "K(q, qd) = y_K(q, qd) pi",
        "Kinetic energy (with the rotors' 1/2 Ia qd^2) as a row in the standard parameters pi of "
        "jaxskid.standard_params, the columns of regressor: linear in each body's (m, m c, I).",
    ),
    QuantitySpec(
        "potential_energy_regressor", ("q",), _standard_row, sym.potential_energy_regressor,
        "U(q) = y_U(q) pi", "Gravitational potential energy as a row in the standard parameters pi.",
    ),
    QuantitySpec(
        "momentum_regressor", ("q", "qd"), _regressor, lambda d: _flat(sym.momentum_regressor(d)),
        "M(q) qd = Y_p(q, qd) pi",
        "Generalized momentum (with the rotors' Ia qd) as a regressor in the standard parameters pi.",
    ),
    QuantitySpec(
        "friction_power_regressor", ("q", "qd"), _standard_row, sym.friction_power_regressor,
        "qd^T (fv qd + fc sign(qd) + fo) = y_P(qd) pi",
        "Power of the drives' friction and offset as a row in the standard parameters pi (zero for the "
        "bodies' and the armature's columns): d/dt (K + U) = qd^T tau - y_P pi.",
    ),
    QuantitySpec(
        "constraint_jacobian", ("q",), lambda r: (n_rows(r.constraints), r.nv),
        lambda d: _flat(sym.constraint_jacobian(d)),
        "A(q) qd = dphi/dt, A = J^h_a - J^h_b on the constrained axes",
        "Constraint Jacobian: one row per constrained world axis (rx, ry, rz, x, y, z) of each constraint "
        "(jaxskid.PointContact, FrameContact, LoopClosure), one column per velocity coordinate; M qdd + h = "
        "tau + A^T lambda, lambda the constraint wrenches (moment, force) in world axes.",
        needs_constraints=True,
        needs_inertia=False, derivatives=("constraint_jacobian_vjp",),
    ),
    QuantitySpec(
        "constraint_drift", ("q", "qd"), lambda r: (n_rows(r.constraints),), sym.constraint_drift,
        "Adot(q, qd) qd", "Drift term of the constraints: A qdd + Adot qd = d^2 phi/dt^2 (the frames' classical "
        "accelerations at qdd = 0, without gravity).", needs_constraints=True,
        needs_inertia=False, derivatives=("constraint_drift_vjp",),
    ),
    QuantitySpec(
        "constraint_residual", ("q",), lambda r: (n_rows(r.constraints),), sym.constraint_residual,
        "phi(q)", "Position residual of the constraints, zero where they hold: p_a - p_b along the translations, "
        "the axis of the skew part of R_a R_b^T (sin(angle) axis) about the rotations.", needs_constraints=True,
        needs_inertia=False, derivatives=("constraint_residual_vjp",),
    ),
    QuantitySpec(
        "center_of_mass", ("q",), lambda r: (3,), sym.center_of_mass,
        "c(q) = sum_i (m_i p_i + R_i h_i) / m", "Centre of mass of the moving bodies in the world frame.",
    ),
    QuantitySpec(
        "center_of_mass_jacobian", ("q",), _centroidal(3), lambda d: _flat(sym.center_of_mass_jacobian(d)),
        "dc/dt = J_c(q) qd", "Jacobian of the centre of mass (world axes), 3 x nv.",
    ),
    QuantitySpec(
        "centroidal_momentum_matrix", ("q",), _centroidal(6), lambda d: _flat(sym.centroidal_momentum_matrix(d)),
        "h_G = A_G(q) qd",
        "Centroidal momentum matrix (Orin, Goswami & Lee 2013): the angular momentum about the centre of mass "
        "and the linear momentum, in world axes, 6 x nv (angular rows first).",
    ),
    QuantitySpec(
        "ee_pose", ("q",), lambda r: (len(r.end_effectors), 4, 4),
        lambda d: _flat([_pose_entries(*sym.frame_pose(d, name)) for name in d.robot.end_effectors]),
        "C_e(q) = C_body(q) T_e", "World pose of each end-effector: forward_kinematics of those frames alone.",
        needs_end_effector=True, needs_inertia=False, derivatives=("ee_pose_vjp",),
    ),
    QuantitySpec(
        "ee_parent_hybrid_jacobian", ("q",), _ee_jacobian, lambda d: _ee_matrices(d, _parent_body(sym.hybrid_jacobian)),
        "V_p^h = J_p^h(q) qd, J_p^h = blockdiag(R_p, R_p) J_p",
        "Hybrid Jacobian of the body each end-effector is attached to (its ee_parent): angular velocity and "
        "velocity of the body frame's origin, world axes (Skidy's hybrid_jacobian_matrix).",
        needs_end_effector=True, needs_inertia=False,
    ),
    QuantitySpec(
        "ee_parent_hybrid_jacobian_dot", ("q", "qd"), _ee_jacobian,
        lambda d: _ee_matrices(d, _parent_body(sym.hybrid_jacobian_dot)),
        "dJ_p^h/dt = blockdiag(R_p, R_p) (omega~ J_p + dJ_p/dt)",
        "Time derivative of ee_parent_hybrid_jacobian (Skidy's hybrid_jacobian_matrix_dot).",
        needs_end_effector=True, needs_inertia=False,
    ),
    _pullback("mass_matrix", ("q",), "cotangent_matrix", "M(q)"),
    _pullback("coriolis_matrix", ("q", "qd"), "cotangent_matrix", "C(q, qd)"),
    _pullback("gravity_torques", ("q",), "cotangent", "Q_grav(q)"),
    _pullback("coriolis_torques", ("q", "qd"), "cotangent", "C(q, qd) qd"),
    _pullback("ee_pose", ("q",), "cotangent_pose", "C_e(q)", needs="end_effector"),
    _pullback("ee_hybrid_twist", ("q", "qd"), "cotangent_ee", "V_e^h(q, qd)", needs="end_effector"),
    _pullback("external_torques", ("q", "wrench"), "cotangent", "Q_ext(q, W_e)", needs="end_effector"),
    _pullback("constraint_jacobian", ("q",), "cotangent_constraint", "A(q)", needs="constraints"),
    _pullback("constraint_drift", ("q", "qd"), "cotangent_rows", "Adot(q, qd) qd", needs="constraints"),
    _pullback("constraint_residual", ("q",), "cotangent_rows", "phi(q)", needs="constraints"),
)

QUANTITIES: MappingProxyType[str, QuantitySpec] = MappingProxyType({spec.name: spec for spec in _CATALOGUE})
"""Every quantity jaxskid can derive, by name, in the canonical order (read-only)."""

DEFAULT_QUANTITIES = (
    "mass_matrix",
    "coriolis_matrix",
    "coriolis_torques",
    "gravity_torques",
    "inverse_dynamics",
    "forward_dynamics",
    "forward_kinematics",
    "constraint_jacobian",
    "constraint_drift",
    "constraint_residual",
)
"""What :func:`jaxskid.lower` derives when no quantity is named (the constraint quantities only for a robot with
constraints)."""
