"""Forward dynamics, qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q) - Q_ext), by both routes: the numeric
L D L^T solve of M and tau, and the closed-form quantity (the symbolic sparse L^T D L factorisation).

References: Pinocchio's ``aba`` and ``computeABADerivatives`` (its articulated-body algorithm, not a
factorisation of M), with ``tau - J^T W`` for end-effector wrenches; SymPy's own floating-point evaluation of
the closed form; ``numpy.linalg.solve`` for the L D L^T solve.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from helpers import FINGERS, PANDA, REPO, load, lowered, pinocchio_urdf_model, users_rk4
from jaxskid.apps.identification._identification import random_states
from pinref import to_pinocchio
from randrobot import random_robot

ROUTES = pytest.mark.parametrize("closed", [False, True], ids=["numeric", "closed-form"])


@pytest.fixture(scope="module", params=[False, True], ids=["numeric", "closed-form"])
def panda(request):
    robot = load("panda7")
    return robot, lowered(robot, request.param), pinocchio_urdf_model(PANDA, FINGERS)


def test_forward_dynamics_matches_pinocchio_aba_panda(panda):
    robot, dyn, model = panda
    data = model.createData()
    q, qd, _ = random_states(7, 64, seed=1, scale=2.0)
    tau = np.random.default_rng(2).normal(scale=20.0, size=(64, 7))
    qdd = np.asarray(jaxskid.forward_dynamics(dyn, q, qd, tau))
    ref = np.stack([pin.aba(model, data, q[k], qd[k], tau[k]) for k in range(64)])
    np.testing.assert_allclose(qdd, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    one = np.asarray(jaxskid.forward_dynamics(dyn, q[3], qd[3], tau[3], robot.default_params()))
    np.testing.assert_allclose(one, ref[3], rtol=0, atol=1e-9 * np.abs(ref[3]).max())
    cond = np.asarray(jaxskid.mass_matrix_condition(dyn, q[:4]))
    np.testing.assert_allclose(cond, [np.linalg.cond(pin.crba(model, data, q[k])) for k in range(4)], rtol=1e-8)


@ROUTES
def test_forward_dynamics_random_trees_batched_params_and_wrench(closed):
    """Random trees with prismatic joints, one parameter set per state, and end-effector wrenches:
    Pinocchio's aba with tau - J^T W (J: Pinocchio's LOCAL frame Jacobian)."""
    rng = np.random.default_rng(5)
    robot = random_robot(rng, 5, tree=True, prismatic=0.4)
    dyn = lowered(robot, closed, ["external_torques"])
    base = robot.default_params()
    batch = 6
    values = [{k: v * (1 + 0.2 * rng.uniform()) if not k.endswith(("mcx", "mcy", "mcz", "Ixy", "Ixz", "Iyz")) else v
               for k, v in base.items()} for _ in range(batch)]
    pvec = np.array([[v[k] for k in dyn.parameters] for v in values])
    q, qd, _ = random_states(robot.n_dof, batch, seed=6)
    tau = rng.normal(size=(batch, robot.n_dof))
    assert robot.end_effectors, "the wrench term needs an end-effector"
    wrench = rng.normal(size=(batch, len(robot.end_effectors), 6))
    qdd = np.asarray(jaxskid.forward_dynamics(dyn, q, qd, tau, pvec, wrench=wrench))
    for k in range(batch):
        model, _ = to_pinocchio(robot, values[k])
        data = model.createData()
        pin.computeJointJacobians(model, data, q[k])
        pin.updateFramePlacements(model, data)
        ext = np.zeros(robot.n_dof)
        for e, name in enumerate(robot.end_effectors):
            jac = pin.getFrameJacobian(model, data, model.getFrameId(name), pin.LOCAL)  # rows (v, omega)
            ext += jac.T @ np.concatenate([wrench[k, e, 3:], wrench[k, e, :3]])
        ref = pin.aba(model, data, q[k], qd[k], tau[k] - ext)
        np.testing.assert_allclose(qdd[k], ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))


@ROUTES
def test_forward_dynamics_derivatives_match_pinocchio(closed):
    """jax.jacfwd of forward dynamics (through the unrolled L D L^T, or the closed form, and the Newton
    reciprocal) equals Pinocchio's analytical ABA derivatives, on a random tree with prismatic joints."""
    rng = np.random.default_rng(12)
    robot = random_robot(rng, 4, tree=True, prismatic=0.3)
    dyn = lowered(robot, closed)
    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    q, qd, _ = random_states(4, 1, seed=8)
    q, qd = q[0], qd[0]
    tau = rng.normal(size=4)
    pin.computeABADerivatives(model, data, q, qd, tau)
    fd = lambda *a: jaxskid.forward_dynamics(dyn, *a)  # noqa: E731
    dq, dv, dtau = jax.jacfwd(fd, argnums=(0, 1, 2))(q, qd, tau)
    np.testing.assert_allclose(np.asarray(dq), data.ddq_dq, atol=1e-8 * np.abs(data.ddq_dq).max())
    np.testing.assert_allclose(np.asarray(dv), data.ddq_dv, atol=1e-8 * np.abs(data.ddq_dv).max())
    minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
    np.testing.assert_allclose(np.asarray(dtau), minv, atol=1e-8 * np.abs(minv).max())
    # reverse mode through the reciprocal's custom jvp
    grad = jax.grad(lambda t: fd(q, qd, t)[2])(jnp.asarray(tau))
    np.testing.assert_allclose(np.asarray(grad), minv[2], atol=1e-8 * np.abs(minv).max())


def test_forward_dynamics_requests_missing_quantities(pendulum):
    robot, _ = pendulum
    dyn = jaxskid.lower(robot, ["mass_matrix"])
    with pytest.raises(jaxskid.RequestError, match="inverse_dynamics"):
        jaxskid.forward_dynamics(dyn, np.zeros(2), np.zeros(2), np.zeros(2))
    with pytest.raises(jaxskid.ShapeError, match=r"expected shape \(2,\)"):
        jaxskid.forward_dynamics(pendulum[1], np.zeros(3), np.zeros(3), np.zeros(3))


@ROUTES
def test_forward_dynamics_float32(closed):
    dyn = lowered(jaxskid.load(REPO / "robots/double_pendulum.yaml"), closed)
    q, qd, tau = (np.array(v, dtype=np.float32) for v in ([0.3, -1.1], [0.5, 2.0], [0.1, -0.4]))
    out = jaxskid.forward_dynamics(dyn, q, qd, tau)
    assert out.dtype == jnp.float32
    ref = jaxskid.forward_dynamics(dyn, q.astype(float), qd.astype(float), tau.astype(float))
    np.testing.assert_allclose(np.asarray(out), np.asarray(ref), rtol=1e-5, atol=1e-5)


def test_closed_form_forward_dynamics_on_the_tape():
    """The symbolic sparse L^T D L forward dynamics (jaxskid.symbolic._forward), evaluated in floating point by
    SymPy (no lowering, no Newton reciprocal), equals Pinocchio's aba on a random tree."""
    import sympy as sp

    from jaxskid.symbolic import Derivation, Inputs
    from jaxskid.symbolic import forward_dynamics as forward_dynamics_outputs

    rng = np.random.default_rng(14)
    robot = random_robot(rng, 5, tree=True, prismatic=0.3)
    params = robot.default_params()
    kin = Derivation(robot, Inputs.of(robot))
    tau_syms = [sp.Symbol(f"_tau{i}", real=True) for i in range(robot.n_dof)]
    outs = forward_dynamics_outputs(kin, tau_syms)
    q, qd, _ = random_states(robot.n_dof, 1, seed=15)
    tau = rng.normal(size=robot.n_dof)
    values = {jaxskid.symbol(k): sp.Float(v) for k, v in params.items()}
    values.update({s: sp.Float(v) for s, v in zip(kin.q, q[0])})
    values.update({s: sp.Float(v) for s, v in zip(kin.qd, qd[0])})
    values.update({s: sp.Float(v) for s, v in zip(tau_syms, tau)})
    for s, e in kin.tape.defs.items():
        values[s] = sp.Float(e.xreplace(values).evalf())
    qdd = np.array([float(sp.sympify(e).xreplace(values)) for e in outs])
    model, _ = to_pinocchio(robot, params)
    np.testing.assert_allclose(qdd, pin.aba(model, model.createData(), q[0], qd[0], tau), atol=1e-10)


def test_ldl_solve_matches_numpy_and_rejects_indefinite_matrices():
    from jaxskid.runtime._ldl import ldl_solve

    rng = np.random.default_rng(7)
    a = rng.normal(size=(6, 6))
    spd = a @ a.T + 6 * np.eye(6)
    b = rng.normal(size=6)
    np.testing.assert_allclose(np.asarray(ldl_solve(jnp.asarray(spd), jnp.asarray(b))), np.linalg.solve(spd, b),
                               rtol=1e-12)
    indefinite = spd - (np.linalg.eigvalsh(spd)[0] + 1.0) * np.eye(6)  # one negative eigenvalue
    assert np.all(np.isnan(np.asarray(ldl_solve(jnp.asarray(indefinite), jnp.asarray(b)))))
    singular = np.diag([1.0, 0.0, 2.0, 3.0, 4.0, 5.0])
    assert np.all(np.isnan(np.asarray(ldl_solve(jnp.asarray(singular), jnp.asarray(b)))))


@ROUTES
def test_raw_functions_in_a_users_loop(closed):
    """``dyn.raw`` is the documented single-state function to vmap: a hand-written RK4 loop over
    ``dyn.raw("forward_dynamics")`` gives the trajectory of ``jaxskid.rollout``, its gradient with respect to
    the parameters that of the rollout (its closed-form derivative rule), and ``dyn.raw`` of a matrix quantity
    gives the public function's values."""
    robot = jaxskid.load(REPO / "robots/arm_3dof.yaml")
    dyn = lowered(robot, closed)
    n, b, steps, dt = robot.n_dof, 3, 40, 2e-3
    q0, qd0, _ = random_states(n, b, seed=9)
    u = np.random.default_rng(10).normal(scale=2.0, size=(b, steps, n))
    p = dyn.param_vector()
    rk4 = users_rk4(jax.vmap(dyn.raw("forward_dynamics"), in_axes=(0, 0, 0, None)), dt)
    loop = jax.jit(lambda q, qd, u, p: jnp.concatenate(rk4(q, qd, u, p), axis=-1))  # x = (q, qd) after each step
    mine = loop(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(u.transpose(1, 0, 2)), p).transpose(1, 0, 2)
    ref = jaxskid.rollout(dyn, np.concatenate([q0, qd0], axis=1), u, dt, steps).x[:, 1:]
    np.testing.assert_allclose(np.asarray(mine), np.asarray(ref), rtol=0, atol=1e-12)

    def loss_mine(p):
        return (loop(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(u.transpose(1, 0, 2)), p)[-1] ** 2).sum()

    def loss_ref(p):
        return (jaxskid.rollout(dyn, np.concatenate([q0, qd0], axis=1), u, dt, steps, params=p).x[:, -1] ** 2).sum()

    g_mine, g_ref = jax.jit(jax.grad(loss_mine))(p), jax.grad(loss_ref)(p)
    np.testing.assert_allclose(np.asarray(g_mine), np.asarray(g_ref), rtol=1e-9, atol=1e-9 * float(jnp.abs(g_ref).max()))
    m = jax.jit(jax.vmap(dyn.raw("mass_matrix"), in_axes=(0, None)))(jnp.asarray(q0), p)
    np.testing.assert_allclose(np.asarray(m), np.asarray(dyn.mass_matrix(q0)), rtol=1e-13, atol=1e-13)
    with pytest.raises(jaxskid.RequestError, match="regressor"):
        dyn.raw("regressor")
    with pytest.raises(jaxskid.RequestError, match="no quantity is named 'mass_matrx'"):
        dyn.raw("mass_matrx")
