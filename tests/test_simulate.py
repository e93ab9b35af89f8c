"""Forward dynamics and rollouts against Pinocchio (aba, ABA derivatives), textbook energy, measured orders.

References: Pinocchio's ``aba`` and ``computeABADerivatives`` (its articulated-body algorithm, not a
factorisation of M), the double pendulum's closed-form energy, the convergence order measured on a sequence
of steps, central differences, and the unsharded computation for the sharded one.
"""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from jaxskid.apps._identification import random_states
from pinref import to_pinocchio
from randrobot import random_robot

REPO = Path(__file__).resolve().parents[1]
ROBOTS = Path(
    importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots")
)
FD = ["mass_matrix", "inverse_dynamics"]
ROUTES = pytest.mark.parametrize("closed", [False, True], ids=["numeric", "closed-form"])


def lowered(robot, closed, extra=()):
    """Forward dynamics from M and tau (numeric L D L^T) or from the closed-form quantity."""
    return jaxskid.lower(robot, [*FD, *extra, *(["forward_dynamics"] if closed else [])])


@pytest.fixture(scope="module", params=[False, True], ids=["numeric", "closed-form"])
def panda(request):
    lock = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    path = ROBOTS / "panda_description/urdf/panda.urdf"
    robot = jaxskid.read_urdf(path, lock=lock)
    model = pin.buildModelFromUrdf(str(path))
    model = pin.buildReducedModel(model, [model.getJointId(k) for k in lock], pin.neutral(model))
    return robot, lowered(robot, request.param), model


@pytest.fixture(scope="module")
def pendulum():
    robot = jaxskid.load(REPO / "robots/double_pendulum.yaml")
    return robot, jaxskid.lower(robot, FD)


def pendulum_energy(x, p):
    """Closed form (robots/double_pendulum.yaml): point masses at the link ends plus I1, I2, hanging at q=0."""
    q1, q2, d1, d2 = (x[..., k] for k in range(4))
    m1, m2, l1, l2, i1, i2, g = (p[k] for k in ("m1", "m2", "l1", "l2", "I1", "I2", "g"))
    m11 = i1 + i2 + m1 * l1**2 + m2 * (l1**2 + l2**2 + 2 * l1 * l2 * np.cos(q2))
    m12 = i2 + m2 * (l2**2 + l1 * l2 * np.cos(q2))
    m22 = i2 + m2 * l2**2
    kinetic = 0.5 * (m11 * d1 * d1 + 2 * m12 * d1 * d2 + m22 * d2 * d2)
    return kinetic - (m1 + m2) * g * l1 * np.cos(q1) - m2 * g * l2 * np.cos(q1 + q2)


# ------------------------------------------------------------------------------------------ forward dynamics
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
    wrench = rng.normal(size=(batch, len(robot.end_effectors), 6))
    qdd = np.asarray(jaxskid.forward_dynamics(dyn, q, qd, tau, pvec, wrench))
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


# ------------------------------------------------------------------------------------------ rollouts
def test_energy_conserved_rk4_double_pendulum(pendulum):
    robot, dyn = pendulum
    x0 = jnp.array([1.2, -0.8, 0.5, 1.5])
    traj = jaxskid.rollout(dyn, x0, np.zeros((10_000, 2)), 1e-3, 10_000, jaxskid.RK4())
    energy = pendulum_energy(np.asarray(traj.x), robot.default_params())
    drift = np.abs(energy - energy[0]).max() / abs(energy[0])
    assert drift < 1e-6
    assert traj.x.shape == (10_001, 4) and traj.t[-1] == pytest.approx(10.0)
    assert np.abs(traj.x).max() > 1.0  # it moved


@pytest.mark.parametrize("integrator", [jaxskid.SemiImplicitEuler(), jaxskid.RK4()], ids=lambda i: type(i).__name__)
def test_measured_convergence_order(pendulum, integrator):
    """Global error at t = 1 s against a 4x finer RK4 solution; slope of log(error) over log(dt)."""
    _, dyn = pendulum
    x0 = jnp.array([1.0, -0.5, 0.2, 0.3])

    def policy(t, x):
        return jnp.array([0.5, -0.3]) * jnp.sin(3.0 * t)

    reference = jaxskid.rollout(dyn, x0, policy, 1.0 / 2048, 2048, jaxskid.RK4()).x[-1]
    steps = [32, 64, 128] if integrator.order == 4 else [256, 512, 1024]
    errors = [float(jnp.abs(jaxskid.rollout(dyn, x0, policy, 1.0 / s, s, integrator).x[-1] - reference).max())
              for s in steps]
    order = np.polyfit(np.log(1.0 / np.array(steps)), np.log(errors), 1)[0]
    assert abs(order - integrator.order) < 0.2, (errors, order)


def test_batched_rollout_equals_single_rollouts_and_vmap(pendulum):
    """A batch with per-rollout params and controls equals rollouts one by one, and jax.vmap of rollout."""
    robot, dyn = pendulum
    rng = np.random.default_rng(3)
    x0 = rng.normal(size=(3, 4))
    params = np.array([[robot.default_params()[k] * (1 + 0.1 * i) for k in dyn.parameters] for i in range(3)])
    controls = rng.normal(size=(3, 50, 2))
    batch = jaxskid.rollout(dyn, x0, controls, 0.01, 50, params=params)
    assert batch.x.shape == (3, 51, 4) and batch.tau.shape == (3, 50, 2)
    for i in range(3):
        one = jaxskid.rollout(dyn, x0[i], controls[i], 0.01, 50, params=params[i])
        np.testing.assert_allclose(np.asarray(batch.x[i]), np.asarray(one.x), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(batch.tau[i]), controls[i])
    mapped = jax.vmap(lambda x, p, u: jaxskid.rollout(dyn, x, u, 0.01, 50, params=p).x)(x0, params, controls)
    np.testing.assert_allclose(np.asarray(mapped), np.asarray(batch.x), rtol=0, atol=1e-12)
    named = {k: params[:, j] for j, k in enumerate(dyn.parameters)}  # a dict of batched values
    np.testing.assert_allclose(np.asarray(jaxskid.rollout(dyn, x0, controls, 0.01, 50, params=named).x),
                               np.asarray(batch.x), rtol=0, atol=1e-12)


def test_gradient_through_rollout_matches_central_differences(pendulum):
    _, dyn = pendulum
    x0 = jnp.array([0.3, 0.2, 0.0, 0.0])

    def final_angle(x0):
        return jaxskid.rollout(dyn, x0, np.zeros((100, 2)), 0.01, 100).x[-1, 1]

    g = np.asarray(jax.grad(final_angle)(x0))
    h = 1e-6
    fd = [(final_angle(x0.at[k].add(h)) - final_angle(x0.at[k].add(-h))) / (2 * h) for k in range(4)]
    np.testing.assert_allclose(g, np.asarray(fd), rtol=1e-6, atol=1e-8)


def test_rollout_rejects_bad_shapes(pendulum):
    _, dyn = pendulum
    with pytest.raises(jaxskid.ShapeError, match="x0"):
        jaxskid.rollout(dyn, np.zeros(3), np.zeros((5, 2)), 0.01, 5)
    with pytest.raises(jaxskid.ShapeError, match="controls"):
        jaxskid.rollout(dyn, np.zeros(4), np.zeros((4, 2)), 0.01, 5)


SHARDED = textwrap.dedent("""
    import os, sys, json
    os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=2"
    import jax
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_numpy_rank_promotion", "raise")
    import numpy as np
    import jaxskid
    assert len(jax.devices()) == 2, jax.devices()
    robot = jaxskid.load(sys.argv[1])
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    rng = np.random.default_rng(0)
    x0 = rng.normal(size=(7, 4))  # odd: padded to a multiple of the device count
    params = np.array([[robot.default_params()[k] * (1 + 0.05 * i) for k in dyn.parameters] for i in range(7)])
    both = jaxskid.rollout(dyn, x0, np.zeros((40, 2)), 0.01, 40, params=params)
    one = jaxskid.rollout(dyn, x0, np.zeros((40, 2)), 0.01, 40, params=params, devices=jax.devices()[:1])
    print(json.dumps({"diff": float(np.abs(np.asarray(both.x) - np.asarray(one.x)).max()),
                      "devices": len(both.x.sharding.device_set), "shape": list(both.x.shape)}))
""")


def test_sharded_rollout_equals_unsharded(tmp_path):
    """In a fresh process with two host devices (XLA_FLAGS set before jax is imported)."""
    env = {**os.environ, "JAXSKID_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", SHARDED, str(REPO / "robots/double_pendulum.yaml")],
                         capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    import json

    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["shape"] == [7, 41, 4]
    assert result["diff"] < 1e-12
    assert result["devices"] == 2


def test_closed_form_forward_dynamics_on_the_tape():
    """The symbolic sparse L^T D L forward dynamics (jaxskid.symbolic._forward), evaluated in floating point by
    SymPy (no lowering, no Newton reciprocal), equals Pinocchio's aba on a random tree."""
    import sympy as sp

    from jaxskid.symbolic._forward import forward_dynamics_outputs
    from jaxskid.symbolic._kinematics import Kinematics, Tape

    rng = np.random.default_rng(14)
    robot = random_robot(rng, 5, tree=True, prismatic=0.3)
    params = robot.default_params()
    kin = Kinematics(robot, Tape())
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
    from jaxskid.runtime._forward import ldl_solve

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


def test_closed_form_rollouts_equal_numeric_rollouts():
    """RK4 rollouts through the closed-form quantity equal those through M and tau, single and batched
    (the batched path maps the broadcast form, the single path the plain one)."""
    robot = jaxskid.load(REPO / "robots/arm_3dof.yaml")
    closed, numeric = lowered(robot, True), lowered(robot, False)
    x0 = np.random.default_rng(3).uniform(-1, 1, (4, 6))
    controls = np.random.default_rng(4).normal(size=(4, 200, 3))
    for x, u in ((x0[0], controls[0]), (x0, controls)):
        a = jaxskid.rollout(closed, x, u, 2e-3, 200).x
        b = jaxskid.rollout(numeric, x, u, 2e-3, 200).x
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-10 * np.abs(np.asarray(b)).max())
