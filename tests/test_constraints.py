"""Constraints with multipliers: contacts and loop closures (jaxskid.PointContact, FrameContact, LoopClosure).

Independent references: the four-bar's one-coordinate model derived here by Euler-Lagrange in SymPy from the
links' geometry (robots/four_bar.yaml is a parallelogram); a KKT solve built on Pinocchio's crba,
nonLinearEffects, LOCAL_WORLD_ALIGNED frame Jacobians and classical frame accelerations; central finite
differences; and the constraint equations themselves along a rollout.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import sympy as sp
import yaml
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

import jaxskid
from jaxskid.runtime._constrained import constrained
from helpers import FINGERS, PANDA, ROBOTS_DIR, load, pinocchio_urdf_model, rel_err
from pinref import jac_to_omega_v, to_pinocchio

FOUR_BAR = ROBOTS_DIR / "four_bar.yaml"
CONSTRAINED = ["mass_matrix", "inverse_dynamics", "constraint_jacobian", "constraint_drift", "constraint_residual"]
G = np.array([1.0, -1.0, 1.0])  # the parallelogram's q = G theta


@pytest.fixture(scope="module")
def four_bar():
    robot = jaxskid.load(FOUR_BAR)
    return robot, jaxskid.lower(robot, CONSTRAINED)


@pytest.fixture(scope="module")
def general():
    """A four-bar that is no parallelogram (the coupler's far end raised by e: rocker a - e long), its loop
    equation solved numerically for a start at crank angle 0.5."""
    d = yaml.safe_load(FOUR_BAR.read_text())
    d["ee"] = [{"xyzrpy": ["d", 0, "e", 0, 0, 0]}, {"xyzrpy": [0, 0, "e - a", 0, 0, 0]}]
    d["assignments"]["e"] = 0.1
    robot = jaxskid.parse_description(d, source="general_four_bar.yaml")
    dyn = jaxskid.lower(robot, CONSTRAINED)
    z = fsolve(lambda z: np.asarray(dyn.constraint_residual(np.array([0.5, *z]))), [0.0, 0.0], xtol=1e-12)
    q0 = np.array([0.5, *z])
    assert np.abs(np.asarray(dyn.constraint_residual(q0))).max() < 1e-15
    return robot, dyn, q0


# ---------------------------------------------------------------------------------------------- one coordinate
def one_coordinate_model(p: dict):
    """``theta'' = f(theta, theta', Q)`` of the parallelogram by Euler-Lagrange from its links: crank and rocker
    (uniform rods of length a) turn by theta about their pivots (0, 0, 0) and (d, 0, 0), the coupler (a rod of
    length d) translates with the crank's end; Q = tau . dq/dtheta is the generalized force."""
    th, thd, thdd, q_gen = sp.symbols("theta thetad thetadd Q", real=True)
    a, d, m1, m2, m3, g = (p[k] for k in ("a", "d", "m1", "m2", "m3", "g"))
    ry = sp.Matrix([[sp.cos(th), 0, sp.sin(th)], [0, 1, 0], [-sp.sin(th), 0, sp.cos(th)]])
    down = sp.Matrix([0, 0, -1])
    links = [  # (mass, centre of mass, angle, inertia about the centre across the rod)
        (m1, ry * down * a / 2, th, m1 * a**2 / 12),
        (m2, ry * down * a + sp.Matrix([d / 2, 0, 0]), 0, m2 * d**2 / 12),
        (m3, sp.Matrix([d, 0, 0]) + ry * down * a / 2, th, m3 * a**2 / 12),
    ]
    kinetic = sum(m * (c.diff(th) * thd).dot(c.diff(th) * thd) / 2 + i * (sp.diff(phi, th) * thd) ** 2 / 2
                  for m, c, phi, i in links)
    potential = sum(m * g * c[2] for m, c, _, _ in links)
    lagrangian = kinetic - potential
    dldthd = sp.diff(lagrangian, thd)
    inertia = dldthd.diff(thd)  # d/dt dL/dtheta' - dL/dtheta = Q: inertia theta'' + rest = Q
    rest = dldthd.diff(th) * thd - sp.diff(lagrangian, th)
    accel = sp.lambdify((th, thd, q_gen), (q_gen - rest) / inertia, "numpy")
    force = sp.lambdify((th, thd, thdd), inertia * thdd + rest, "numpy")
    return accel, force


def test_four_bar_accelerations_match_the_one_coordinate_model(four_bar):
    robot, dyn = four_bar
    accel, _ = one_coordinate_model(robot.default_params())
    rng = np.random.default_rng(0)
    th, thd = rng.uniform(-1.2, 1.2, 16), rng.uniform(-3, 3, 16)
    tau = rng.uniform(-2, 2, (16, 3))
    qdd, lam = dyn.constrained_forward_dynamics(th[:, None] * G, thd[:, None] * G, tau)
    expected = accel(th, thd, tau @ G)[:, None] * G
    assert rel_err(qdd, expected) < 1e-12
    assert lam.shape == (16, 2)


def test_four_bar_rollout_matches_the_one_coordinate_model(four_bar):
    """A batch of two 1 s RK4 rollouts (1 ms steps, the default Baumgarte gains), the crank driven by 0.5 N m,
    against the one-coordinate model solved by DOP853 at 1e-13; and the diffrax vector field."""
    robot, dyn = four_bar
    accel, _ = one_coordinate_model(robot.default_params())
    starts = [(0.9, -0.5), (-0.3, 2.0)]
    x0 = np.array([np.concatenate([th * G, thd * G]) for th, thd in starts])
    tau = np.broadcast_to([0.5, 0.0, 0.0], (1000, 3))
    traj = jaxskid.rollout(dyn, x0, tau, 1e-3, 1000, saveat=jaxskid.SaveAt(every=100))
    for k, start in enumerate(starts):
        ref = solve_ivp(lambda t, y: [y[1], accel(y[0], y[1], 0.5)], (0, 1), start, method="DOP853",
                        t_eval=np.asarray(traj.t), rtol=1e-13, atol=1e-13)
        assert np.abs(np.asarray(traj.q[k]) - ref.y[0][:, None] * G).max() < 1e-10
        assert np.abs(np.asarray(traj.qd[k]) - ref.y[1][:, None] * G).max() < 1e-9
    field = jaxskid.vector_field(dyn, lambda t, x: jnp.asarray([0.5, 0.0, 0.0]), stabilization=None)
    assert rel_err(field(0.0, x0[1], None)[3:], accel(-0.3, 2.0, 0.5) * G) < 1e-12


# ---------------------------------------------------------------------------------------------- violation
def _violation(dyn, traj) -> tuple[float, float]:
    q, qd = np.asarray(traj.q), np.asarray(traj.qd)
    phi = np.abs(np.asarray(dyn.constraint_residual(q))).max()
    velocity = np.abs(np.einsum("kij,kj->ki", np.asarray(dyn.constraint_jacobian(q)), qd)).max()
    return phi, velocity


@pytest.mark.slow
def test_violation_stays_below_1e_8_over_10_s_of_rk4_with_baumgarte(general):
    """dt = 1 ms, RK4, Baumgarte alpha = beta = 10/s (the defaults); the general four-bar swings from rest at
    crank angle 0.5. Measured: |phi| 5e-12, |A qd| 7e-11; without stabilisation |phi| drifts to 2e-9."""
    _, dyn, q0 = general
    x0 = np.concatenate([q0, np.zeros(3)])
    kw = dict(saveat=jaxskid.SaveAt(every=10))
    stabilised = jaxskid.rollout(dyn, x0, np.zeros((10000, 3)), 1e-3, 10000, stabilization=jaxskid.Baumgarte(), **kw)
    phi, velocity = _violation(dyn, stabilised)
    assert phi < 1e-8 and velocity < 1e-8
    assert np.ptp(np.asarray(stabilised.q)[:, 0]) > 1.0  # it swings
    drifting = jaxskid.rollout(dyn, x0, np.zeros((10000, 3)), 1e-3, 10000, stabilization=None, **kw)
    assert _violation(dyn, drifting)[0] > 10 * phi


# ---------------------------------------------------------------------------------------------- against Pinocchio
def _kkt(m, h, jac, drift, tau):
    """``[[M, -J^T], [J, 0]] [qdd, lambda] = [tau - h, -drift]``."""
    n, k = m.shape[0], jac.shape[0]
    sol = np.linalg.solve(np.block([[m, -jac.T], [jac, np.zeros((k, k))]]), np.concatenate([tau - h, -drift]))
    return sol[:n], sol[n:]


def _pinocchio_frame(model, data, q, qd, fid):
    """(LOCAL_WORLD_ALIGNED Jacobian (omega, v), classical acceleration (domega, d^2p) at qdd = 0, pose)."""
    pin.computeJointJacobians(model, data, q)
    pin.forwardKinematics(model, data, q, qd, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    jac = jac_to_omega_v(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED))
    acc = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    return jac, np.concatenate([acc.angular, acc.linear]), data.oMf[fid]


def _dynamics(model, data, q, qd):
    m = pin.crba(model, data, q)
    return np.triu(m) + np.triu(m, 1).T, pin.nonLinearEffects(model, data, q, qd).copy()


@pytest.mark.slow
def test_panda_with_its_hand_held_matches_a_kkt_solve_on_pinocchio():
    """The Panda (fingers locked) with its TCP held: rotations by a FrameContact, the point by a PointContact."""
    robot = load("panda7").with_constraints([jaxskid.FrameContact("panda_hand_tcp", axes=["rz", "rx", "ry"]),
                                             jaxskid.PointContact("panda_hand_tcp")])
    dyn = jaxskid.lower(robot, CONSTRAINED)
    model = pinocchio_urdf_model(PANDA, FINGERS)
    data, fid = model.createData(), model.getFrameId("panda_hand_tcp")
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    anchor = data.oMf[fid].copy()  # a contact without anchor holds its frame where it is at q = 0
    rng = np.random.default_rng(3)
    q, qd, tau = rng.uniform(-1.5, 1.5, (3, 4, 7))
    qdd, lam = dyn.constrained_forward_dynamics(q, qd, tau)
    a, drift, phi = dyn.constraint_jacobian(q), dyn.constraint_drift(q, qd), dyn.constraint_residual(q)
    for k in range(4):
        jac, acc, pose = _pinocchio_frame(model, data, q[k], qd[k], fid)
        m, h = _dynamics(model, data, q[k], qd[k])
        e = pose.rotation @ anchor.rotation.T
        rot = 0.5 * np.array([e[2, 1] - e[1, 2], e[0, 2] - e[2, 0], e[1, 0] - e[0, 1]])
        assert rel_err(a[k], jac) < 1e-12 and rel_err(drift[k], acc) < 1e-12
        assert rel_err(phi[k], np.concatenate([rot, pose.translation - anchor.translation])) < 1e-12
        ref_qdd, ref_lam = _kkt(m, h, jac, acc, tau[k])
        assert rel_err(qdd[k], ref_qdd) < 1e-9 and rel_err(lam[k], ref_lam) < 1e-9


def test_four_bar_loop_closure_matches_a_kkt_solve_on_pinocchio(four_bar):
    """At states that break the loop (the KKT system does not need them to hold it)."""
    robot, dyn = four_bar
    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    ids = [model.getFrameId(name) for name in ("coupler_end", "rocker_tip")]
    rows = [3, 5]  # x and z, after the rotations
    rng = np.random.default_rng(4)
    q, qd, tau = rng.uniform(-1.5, 1.5, (3, 6, 3))
    qdd, lam = dyn.constrained_forward_dynamics(q, qd, tau)
    for k in range(6):
        (ja, aa, pa), (jb, ab, pb) = (_pinocchio_frame(model, data, q[k], qd[k], f) for f in ids)
        jac, drift = (ja - jb)[rows], (aa - ab)[rows]
        assert rel_err(dyn.constraint_residual(q[k]), (pa.translation - pb.translation)[[0, 2]]) < 1e-12
        ref_qdd, ref_lam = _kkt(*_dynamics(model, data, q[k], qd[k]), jac, drift, tau[k])
        assert rel_err(qdd[k], ref_qdd) < 1e-9 and rel_err(lam[k], ref_lam) < 1e-9


# ---------------------------------------------------------------------------------------------- inverse dynamics
def test_closed_chain_inverse_dynamics_drives_the_motion_back(four_bar):
    robot, dyn = four_bar
    _, force = one_coordinate_model(robot.default_params())
    rng = np.random.default_rng(5)
    th, thd, thdd = rng.uniform(-1.2, 1.2, (3, 8))
    q, qd, qdd = (x[:, None] * G for x in (th, thd, thdd))
    tau_a, lam = dyn.constrained_inverse_dynamics(q, qd, qdd, ["crank_joint"])
    assert rel_err(tau_a[:, 0], force(th, thd, thdd)) < 1e-12  # the crank alone drives the linkage
    tau = np.concatenate([np.asarray(tau_a), np.zeros((8, 2))], axis=1)
    qdd_back, lam_back = dyn.constrained_forward_dynamics(q, qd, tau)
    assert rel_err(qdd_back, qdd) < 1e-10 and rel_err(lam_back, lam) < 1e-10


def test_general_four_bar_inverse_dynamics_by_the_rocker(general):
    """A consistent motion of the general four-bar (the accelerations some torques give), driven by the rocker."""
    _, dyn, q0 = general
    qd = np.asarray(dyn.constraint_jacobian(q0))
    qd = np.linalg.svd(qd)[2][-1] * 1.3  # a velocity in the null space of A
    qdd, _ = dyn.constrained_forward_dynamics(q0, qd, np.array([0.4, -0.2, 0.3]))
    tau_a, lam = dyn.constrained_inverse_dynamics(q0, qd, qdd, [2])
    qdd_back, lam_back = dyn.constrained_forward_dynamics(q0, qd, np.array([0.0, 0.0, float(tau_a[0])]))
    assert rel_err(qdd_back, qdd) < 1e-10 and rel_err(lam_back, lam) < 1e-10


# ---------------------------------------------------------------------------------------------- transformations
@pytest.mark.slow
def test_gradients_match_central_differences(four_bar):
    """Parameters, q and qd, at a state off the constraints, with Baumgarte terms (phi, A qd) in play."""
    _, dyn = four_bar
    q, qd, tau = np.array([0.4, -0.3, 0.5]), np.array([0.7, -0.2, 0.4]), np.array([0.3, -0.1, 0.2])
    stab = jaxskid.Baumgarte(3.0, 4.0)
    w = np.array([1.0, -2.0, 0.5, 0.3, -0.7])

    def loss(q, qd, p):
        qdd, lam = dyn.constrained_forward_dynamics(q, qd, tau, p, stabilization=stab)
        return jnp.concatenate([qdd, lam]) @ w

    p = dyn.param_vector()
    grads = jax.grad(loss, argnums=(0, 1, 2))(q, qd, p)
    for x, g, i in zip((q, qd, p), grads, range(3)):
        h = 1e-6 * np.maximum(1.0, np.abs(x))
        fd = [(loss(*[x + h[j] * e if k == i else y for k, y in enumerate((q, qd, p))])
               - loss(*[x - h[j] * e if k == i else y for k, y in enumerate((q, qd, p))])) / (2 * h[j])
              for j, e in enumerate(np.eye(len(x)))]
        assert rel_err(g, fd) < 1e-7
    forward = jax.jacfwd(lambda p: dyn.constrained_forward_dynamics(q, qd, tau, p, stabilization=stab)[0])(p)
    reverse = jax.jacrev(lambda p: dyn.constrained_forward_dynamics(q, qd, tau, p, stabilization=stab)[0])(p)
    assert rel_err(forward, reverse) < 1e-12
    # second order in the parameters: forward mode over the reverse rule (jax.hessian) and the reverse rule
    # differentiated in reverse, against each other and against central differences of the gradient
    hessian = jax.hessian(loss, argnums=2)(q, qd, p)
    assert rel_err(jax.jacrev(jax.grad(loss, argnums=2), argnums=2)(q, qd, p), hessian) < 1e-9
    grad_p = jax.jit(jax.grad(loss, argnums=2))
    h = 1e-5 * np.maximum(1.0, np.abs(p))
    fd = np.stack([(grad_p(q, qd, p + h[j] * e) - grad_p(q, qd, p - h[j] * e)) / (2 * h[j])
                   for j, e in enumerate(np.eye(len(p)))])
    assert rel_err(hessian, fd) < 1e-6


def _native_kkt_errors(dyn, q, qd, tau, stabilization=None, regularization: float = 0.0) -> tuple[float, float]:
    """The reverse-mode gradient of a weighted sum of constrained forward dynamics' (qdd, lambda) with respect to
    (q, qd, tau, p), computed with the native backward step (``kkt_vjp``, which must be in the compiled program)
    against the same rule traced in JAX, and its projections on two random directions against forward mode
    (``jax.jvp``, the tangent rule): their largest relative errors."""
    p = dyn.param_vector()
    rows = dyn.signature("constraint_jacobian")[1][0]
    rng = np.random.default_rng(3)
    w = rng.normal(size=dyn.nv + rows)

    def gradient(target):
        """The gradient through a freshly traced rule, with ``dyn.native_target`` as ``target``."""
        solve = constrained(dyn, stabilization, regularization)

        def loss(*x):
            return jax.numpy.concatenate(solve(*x)) @ w

        built = dyn.native_target
        try:
            dyn.native_target = target(built)
            grad = jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3)))
            return loss, grad(*x), grad.lower(*x).as_text()
        finally:
            del dyn.native_target

    x = (q, qd, tau, p)
    loss, native, text = gradient(lambda built: built)
    assert "jaxskid_kkt_vjp" in text
    _, traced, text = gradient(lambda built: lambda name="fd_vjp": None if name == "kkt_vjp" else built(name))
    assert "jaxskid_kkt_vjp" not in text
    forward = []
    for _ in range(2):
        v = [rng.normal(size=np.shape(a)) for a in x]
        along = jax.jvp(loss, x, tuple(v))[1]
        forward.append(rel_err(sum(np.dot(np.asarray(g), d) for g, d in zip(native, v)), along))
    return max(rel_err(a, b) for a, b in zip(native, traced)), max(forward)


def test_native_backward_step(four_bar):
    """The constrained backward step in one native call (jaxskid_kkt_vjp) gives the gradients of the rule traced
    in JAX and of forward mode, without stabilisation, with Baumgarte's terms, and with a regularisation."""
    _, dyn = four_bar
    assert dyn.report()["kkt_vjp"] == "native kernel"
    q, qd, tau = np.array([0.4, -0.3, 0.5]), np.array([0.7, -0.2, 0.4]), np.array([0.3, -0.1, 0.2])
    for stab, eps in ((None, 0.0), (jaxskid.Baumgarte(3.0, 4.0), 0.0), (jaxskid.Baumgarte(), 1e-3)):
        traced, forward = _native_kkt_errors(dyn, q, qd, tau, stab, eps)
        assert traced < 1e-12 and forward < 1e-12


def test_native_backward_step_with_a_floating_base():
    """The same with a floating base (nq = nv + 1: the base's quaternion): the 3-DOF arm on a free-flying base
    with its gripper held by a point contact, Baumgarte's terms in play."""
    d = yaml.safe_load((ROBOTS_DIR / "arm_3dof.yaml").read_text())
    d["floating_base"] = True
    d["base_inertia"] = {"mass": 2.0, "com": [0, 0, 0], "inertia": {"Ixx": 0.02, "Iyy": 0.03, "Izz": 0.04}}
    robot = jaxskid.parse_description(d, source="floating_arm.yaml")
    dyn = jaxskid.lower(robot.with_constraints([jaxskid.PointContact("gripper")]), CONSTRAINED)
    assert dyn.report()["kkt_vjp"] == "native kernel"
    rng = np.random.default_rng(4)
    quat = rng.normal(size=4)
    q = np.concatenate([rng.normal(0, 0.1, 3), quat / np.linalg.norm(quat), rng.normal(0, 0.5, 3)])
    qd, tau = rng.normal(0, 1.0, robot.nv), np.concatenate([np.zeros(6), rng.normal(0, 2.0, 3)])
    traced, forward = _native_kkt_errors(dyn, q, qd, tau, jaxskid.Baumgarte())
    assert traced < 1e-12 and forward < 1e-12


def test_jit_and_vmap_agree_with_single_calls(four_bar):
    _, dyn = four_bar
    rng = np.random.default_rng(6)
    q, qd, tau = rng.uniform(-1, 1, (3, 5, 3))
    batch = dyn.constrained_forward_dynamics(q, qd, tau)
    mapped = jax.jit(jax.vmap(lambda q, qd, tau: dyn.constrained_forward_dynamics(q, qd, tau)))(q, qd, tau)
    for ours, theirs in zip(batch, mapped):
        assert rel_err(ours, theirs) < 1e-13
    single = dyn.constrained_forward_dynamics(q[2], qd[2], tau[2])
    assert rel_err(single[0], batch[0][2]) < 1e-13 and rel_err(single[1], batch[1][2]) < 1e-13


@pytest.mark.slow
def test_redundant_constraints_need_the_regularization(four_bar):
    """A 3-D point closure of the planar linkage has an identically zero y row: A M^-1 A^T is singular, and a
    small regularisation solves it exactly (lambda_y = 0)."""
    robot, dyn = four_bar
    point = jaxskid.lower(robot.with_constraints([jaxskid.LoopClosure("coupler_end", "rocker_tip")]), CONSTRAINED)
    rng = np.random.default_rng(7)
    q, qd, tau = rng.uniform(-1, 1, (3, 4, 3))
    qdd, lam = dyn.constrained_forward_dynamics(q, qd, tau)
    assert np.isnan(np.asarray(point.constrained_forward_dynamics(q, qd, tau)[0])).all()
    qdd3, lam3 = point.constrained_forward_dynamics(q, qd, tau, regularization=1e-13)
    assert rel_err(qdd3, qdd) < 1e-11 and rel_err(lam3[:, [0, 2]], lam) < 1e-11
    assert np.abs(np.asarray(lam3[:, 1])).max() == 0.0


# ---------------------------------------------------------------------------------------------- bad inputs
def _error(fn, *args, **kwargs) -> str:
    with pytest.raises(jaxskid.JaxskidError) as info:
        fn(*args, **kwargs)
    return str(info.value)


def test_bad_constraints_name_the_key(four_bar):
    robot, dyn = four_bar
    message = _error(robot.with_constraints, [jaxskid.PointContact("nope")])
    assert message.startswith("constraints[0].frame: unknown frame 'nope'")
    message = _error(robot.with_constraints, [jaxskid.LoopClosure("rocker_tip", "rocker")])
    assert message.startswith("constraints[0]: frames 'rocker_tip' and 'rocker' are both on body 'rocker'")
    message = _error(robot.with_constraints, [jaxskid.LoopClosure("coupler_end", "rocker_tip", kind="planar")])
    assert message.startswith("constraints[0].kind: expected 'point', 'frame' or a list of axes")
    message = _error(robot.with_constraints, [jaxskid.PointContact("coupler_end", position=(5, 0, 0))])
    assert message.startswith("constraints[0]: frame 'coupler_end' cannot reach its anchor")
    message = _error(robot.with_constraints, [jaxskid.PointContact("rocker", at={"elbow": 1.0})])
    assert message.startswith("constraints[0].at.elbow: unknown joint 'elbow'")
    message = _error(robot.with_constraints, [jaxskid.PointContact("world")])
    assert message.startswith("constraints[0].frame: frame 'world' is fixed to the world")
    assert "need constraints" in _error(jaxskid.derive, load("arm_2r"), ["constraint_jacobian"])
    assert "constraint_jacobian" in _error(jaxskid.lower(robot, ["mass_matrix"]).constrained_forward_dynamics,
                                           np.zeros(3), np.zeros(3), np.zeros(3))
    assert "Baumgarte: alpha" in _error(jaxskid.Baumgarte, -1.0)
    assert "regularization" in _error(dyn.constrained_forward_dynamics, np.zeros(3), np.zeros(3), np.zeros(3),
                                      regularization=-1.0)
    assert "actuated" in _error(dyn.constrained_inverse_dynamics, np.zeros(3), np.zeros(3), np.zeros(3), ["knee"])


@pytest.mark.parametrize("change, expected", [
    ({"constraints": [{"loop_closure": ["coupler_end", "rocker_tipp"]}]},
     "four_bar.yaml: constraints[0].loop_closure[1]: unknown frame 'rocker_tipp'"),
    ({"constraints": [{"loop_closure": ["coupler_end", "coupler"]}]},
     "four_bar.yaml: constraints[0]: frames 'coupler_end' and 'coupler' are both on body 'coupler'"),
    ({"ee": [{"xyzrpy": ["d", 0, 0, 0, 0, 0]}, {"xyzrpy": [0, 0, -5, 0, 0, 0]}]},
     "four_bar.yaml: constraints[0]: frames 'coupler_end' and 'rocker_tip' cannot meet on the axes x, z"),
    ({"constraints": [{"point_contact": "rocker_tip", "axes": ["x", "rz"]}]},
     "four_bar.yaml: constraints[0].axes[1]: unknown axis 'rz'; expected some of x, y, z"),
    ({"constraints": [{"point_contact": "rocker_tip", "position": [0, 0]}]},
     "four_bar.yaml: constraints[0].position: expected 3 values, got 2"),
    ({"constraints": [{"frame_contact": "rocker_tip", "at": {"crank_joint": 0.1}}]},
     None),
    ({"constraints": {"loop_closure": ["coupler_end", "rocker_tip"]}},
     "four_bar.yaml: constraints: expected a list of point_contact, frame_contact or loop_closure entries"),
    ({"constraints": [{"hinge": "rocker_tip"}]},
     "four_bar.yaml: constraints[0]: expected a mapping with one of the keys point_contact, frame_contact"),
])
def test_yaml_constraint_errors_name_the_file_and_key(change, expected):
    data = {**yaml.safe_load(FOUR_BAR.read_text()), **change}
    if expected is None:  # the frame contact at crank angle 0.1 holds the rocker where it is at q = 0
        assert jaxskid.parse_description(data, source="four_bar.yaml").constraints[0].pose is not None
        return
    with pytest.raises(jaxskid.ModelError) as info:
        jaxskid.parse_description(data, source="four_bar.yaml")
    assert str(info.value).startswith(expected)
