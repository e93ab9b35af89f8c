"""Gradients through rollouts, against independent references.

The rollout's derivatives come from closed-form rules (:mod:`jaxskid.runtime._implicit`): the symbolic
vector-Jacobian product of inverse dynamics in reverse mode, the implicit-function derivative in forward
mode. They are checked against central differences of the rollout itself, and against complex-step
derivatives (Squire & Trapp, SIAM Review 40, 1998: ``f'(x) = Im f(x + i h) / h``, exact to rounding) of a
separate rollout: RK4 written here over the numeric recursive Newton-Euler and CRBA of
:mod:`jaxskid.testing` with a dense complex solve. The closed-loop cases (a PD law with gravity compensation,
:class:`jaxskid.PDGravity`, :class:`jaxskid.ComputedTorque`, :class:`jaxskid.GroundContact`) write the law out
too, and the four-bar's loop closure is built from the chained joint poses, differentiated by forward mode.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from helpers import load

import jaxskid
from jaxskid.model._robot import symbol
from jaxskid.testing._recursive import recursive_dynamics

STEPS, DT = 12, 0.02


@pytest.fixture(scope="module")
def arm():
    robot = load("arm_3dof")
    dyn = jaxskid.lower(robot, quantities=["forward_dynamics"])
    n = dyn.n_dof
    rng = np.random.default_rng(3)
    x0 = jnp.asarray(np.r_[rng.uniform(-1, 1, n), rng.uniform(-2, 2, n)])
    u = jnp.asarray(rng.normal(size=(STEPS, n)))
    return robot, dyn, x0, u


def _loss(dyn, autodiff="reverse"):
    def loss(p, x0, u):
        x = jaxskid.rollout(dyn, x0, u, DT, STEPS, params=p, autodiff=autodiff).x
        return jnp.sum(jnp.sin(x) * jnp.arange(1, x.shape[-1] + 1)[None, :])

    return loss


def _central(f, x, h=1e-6):
    x = np.asarray(x, float)
    out = np.zeros(x.size)
    for k in range(x.size):
        e = np.zeros(x.size)
        e[k] = h
        out[k] = (f(jnp.asarray(x + e.reshape(x.shape))) - f(jnp.asarray(x - e.reshape(x.shape)))) / (2 * h)
    return out.reshape(x.shape)


def _check_against_central(loss, args: tuple, names: tuple[str, ...]):
    """``jax.grad`` of ``loss(*args)`` with respect to each argument against central differences of ``loss`` in
    that argument alone (both compiled); returns the gradients."""
    grads = jax.jit(jax.grad(loss, argnums=tuple(range(len(args)))))(*args)
    compiled = jax.jit(loss)
    for k, (g, what) in enumerate(zip(grads, names, strict=True)):
        ref = _central(lambda v: compiled(*args[:k], v, *args[k + 1:]), args[k])
        np.testing.assert_allclose(g, ref, rtol=1e-6, atol=1e-7 * np.abs(ref).max(), err_msg=what)
    return grads


def test_reverse_mode_matches_central_differences(arm):
    _, dyn, x0, u = arm
    _check_against_central(_loss(dyn), (dyn.param_vector(), x0, u), ("params", "x0", "controls"))


def test_forward_mode_equals_reverse_mode(arm):
    _, dyn, x0, u = arm
    p = dyn.param_vector()
    rev = jax.grad(_loss(dyn), argnums=(0, 1, 2))(p, x0, u)
    fwd = jax.jacfwd(_loss(dyn, "forward"), argnums=(0, 1, 2))(p, x0, u)
    for a, b in zip(rev, fwd):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())


def _complex_rk4(f, x0, dt, u):
    """The classical RK4 of ``dx/dt, tau = f(t, x, u_k)`` from ``x0`` over the rows ``u_k`` of ``u`` (held over
    each step), in complex arithmetic: the states ``(steps + 1, n)`` and each step's first-stage ``tau``."""
    def step(x, ku):
        k, u_k = ku
        t = k * dt
        k1, tau = f(t, x, u_k)
        k2, _ = f(t + dt / 2, x + dt / 2 * k1, u_k)
        k3, _ = f(t + dt / 2, x + dt / 2 * k2, u_k)
        k4, _ = f(t + dt, x + dt * k3, u_k)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x, (x, tau)

    x0 = x0.astype(complex)
    _, (xs, taus) = jax.lax.scan(step, x0, (jnp.arange(u.shape[0], dtype=complex), u))
    return jnp.concatenate([x0[None], xs]), taus


def _check_complex_step(grads, run, base, sample=None, seed=0, rtol=1e-9, atol=1e-11):
    """Each gradient ``grads[i]`` (of the loss with respect to argument i) against the complex step of ``run``
    at ``base`` (the arguments in complex): ``Im run(base + i h e_k) / h``, every entry or ``sample`` of them."""
    h, pick = 1e-30, np.random.default_rng(seed)
    for arg, g in enumerate(grads):
        entries = range(g.size) if sample is None else pick.choice(g.size, size=min(g.size, sample), replace=False)
        for k in entries:
            args = list(base)
            args[arg] = (base[arg].ravel().at[k].add(1j * h)).reshape(g.shape)
            ref = float(jnp.imag(run(*args))) / h
            np.testing.assert_allclose(np.ravel(g)[k], ref, rtol=rtol, atol=atol * float(jnp.abs(g).max()))


def _complex_rollout(rec, p, x0, u):
    """RK4 over the numeric recursive dynamics, in complex arithmetic."""
    n = x0.shape[0] // 2

    def f(t, x, tau):
        q, qd = x[:n], x[n:]
        bias = rec.inverse_dynamics(q, qd, jnp.zeros_like(q), p)
        return jnp.concatenate([qd, jnp.linalg.solve(rec.mass_matrix(q, p), tau - bias)]), tau

    x, _ = _complex_rk4(f, x0, DT, u)
    return jnp.sum(jnp.sin(x) * jnp.arange(1, x.shape[-1] + 1)[None, :])


@pytest.mark.slow
def test_gradients_match_complex_step_of_an_independent_rollout(arm):
    robot, dyn, x0, u = arm
    rec = recursive_dynamics(robot)
    p = dyn.param_vector()
    run = jax.jit(lambda p, x0, u: _complex_rollout(rec, p, x0, u))
    loss = _loss(dyn)
    base = [jnp.asarray(a, complex) for a in (p, x0, u)]  # complex throughout: one compiled reference
    np.testing.assert_allclose(loss(p, x0, u), jnp.real(run(*base)), rtol=1e-12)
    grads = jax.grad(loss, argnums=(0, 1, 2))(p, x0, u)
    _check_complex_step(grads, run, base, sample=5)  # a sample of the directions


def test_batched_gradient_is_the_sum_of_single_ones(arm):
    _, dyn, x0, u = arm
    p = dyn.param_vector()
    x0s = jnp.stack([x0, 0.5 * x0, -x0])
    ps = jnp.stack([p, 1.1 * p, 0.9 * p])

    def batched(ps):
        x = jaxskid.rollout(dyn, x0s, u, DT, STEPS, params=ps).x
        return jnp.sum(jnp.sin(x))

    def single(p, x0):
        return jnp.sum(jnp.sin(jaxskid.rollout(dyn, x0, u, DT, STEPS, params=p).x))

    got = jax.grad(batched)(ps)
    for k in range(3):
        np.testing.assert_allclose(got[k], jax.grad(single)(ps[k], x0s[k]), rtol=1e-11, atol=1e-13)


def test_vjp_of_inverse_dynamics_matches_autodiff():
    dyn = jaxskid.lower(load("prr"), quantities=["inverse_dynamics", "inverse_dynamics_vjp"])
    rng = np.random.default_rng(5)
    q, qd, qdd, w = (jnp.asarray(rng.normal(size=dyn.n_dof)) for _ in range(4))
    p = dyn.param_vector()
    _, pullback = jax.vjp(lambda q, qd, p: dyn.inverse_dynamics(q, qd, qdd, p), q, qd, p)
    ref = jnp.concatenate(pullback(w))
    got = dyn.inverse_dynamics_vjp(q, qd, qdd, w, p)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * float(jnp.abs(ref).max()))


def test_bad_autodiff_is_a_clear_error(arm):
    _, dyn, x0, u = arm
    with pytest.raises(jaxskid.RequestError, match="autodiff must be one of"):
        jaxskid.rollout(dyn, x0, u, DT, STEPS, autodiff="backward")


# ---------------------------------------------------------------- closed loop: the feedback step's backward pass


def _reference(t):
    return 0.3 * jnp.sin(3.0 * t) * jnp.asarray([1.0, -0.5, 0.8])


def _feedback_loss(dyn, autodiff="reverse"):
    """A PD law towards a moving reference with gravity compensation from the same parameters, closing over
    the gains ``kp`` and the parameters ``p``; the loss reads the states and the applied torques."""
    rnea = dyn.raw("inverse_dynamics")

    def loss(p, kp, dt):
        n = dyn.n_dof

        def policy(t, x):
            q, qd = x[:n], x[n:]
            return kp * (_reference(t) - q) - 0.2 * qd + rnea(q, jnp.zeros_like(q), jnp.zeros_like(q), p)

        traj = jaxskid.rollout(dyn, X0_FB, policy, dt, STEPS, params=p, autodiff=autodiff)
        return jnp.sum(jnp.sin(traj.x) * jnp.arange(1, 2 * n + 1)[None, :]) + 1e-3 * jnp.sum(traj.tau**2)

    return loss


X0_FB = jnp.asarray([0.4, -0.6, 0.2, 0.5, 0.0, -1.0])
KP = jnp.asarray([2.0, 1.5, 1.0])


def test_feedback_gradient_matches_central_differences_and_forward_mode(arm):
    _, dyn, _, _ = arm
    p, dt = dyn.param_vector(), jnp.asarray(DT)
    grads = _check_against_central(_feedback_loss(dyn), (p, KP, dt), ("params", "gains", "dt"))
    forward = jax.jacfwd(_feedback_loss(dyn, "forward"), argnums=(0, 1, 2))(p, KP, dt)  # stage by stage
    for a, b in zip(grads, forward):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())


def _complex_feedback_rollout(rec, p, kp, dt):
    """RK4 under the same PD law over the numeric recursive dynamics, in complex arithmetic."""
    n = 3

    def f(t, x, _):
        q, qd = x[:n], x[n:]
        tau = kp * (_reference(t) - q) - 0.2 * qd + rec.inverse_dynamics(q, 0 * q, 0 * q, p)
        bias = rec.inverse_dynamics(q, qd, jnp.zeros_like(q), p)
        return jnp.concatenate([qd, jnp.linalg.solve(rec.mass_matrix(q, p), tau - bias)]), tau

    x, taus = _complex_rk4(f, X0_FB, dt, jnp.zeros(STEPS))
    return jnp.sum(jnp.sin(x) * jnp.arange(1, 2 * n + 1)[None, :]) + 1e-3 * jnp.sum(taus**2)


@pytest.mark.slow
def test_feedback_gradient_matches_complex_step_of_an_independent_rollout(arm):
    robot, dyn, _, _ = arm
    rec = recursive_dynamics(robot)
    p, dt = dyn.param_vector(), jnp.asarray(DT)
    run = jax.jit(lambda p, kp, dt: _complex_feedback_rollout(rec, p, kp, dt))
    base = [jnp.asarray(a, complex) for a in (p, KP, dt)]
    np.testing.assert_allclose(_feedback_loss(dyn)(p, KP, dt), jnp.real(run(*base)), rtol=1e-12)
    grads = jax.grad(_feedback_loss(dyn), argnums=(0, 1, 2))(p, KP, dt)
    _check_complex_step(grads, run, base, sample=5, seed=1)


# ---------------------------------------------------------------- closed loop: the library's tracking laws


def _law_loss(dyn, law):
    """A rollout under :class:`jaxskid.PDGravity` or :class:`jaxskid.ComputedTorque` whose model parameters
    ``pc`` and gains ``kp`` are the arguments; the plant keeps its default parameters."""
    def loss(pc, kp, dt):
        control = getattr(jaxskid, law)(dyn, _reference, kp, 0.2 * jnp.ones(3), params=pc)
        traj = jaxskid.rollout(dyn, X0_FB, control, dt, STEPS)
        return jnp.sum(jnp.sin(traj.x) * jnp.arange(1, 7)[None, :]) + 1e-3 * jnp.sum(traj.tau**2)

    return loss


def _complex_law_rollout(rec, law, plant, pc, kp, dt):
    """RK4 under the law written out over the numeric recursive dynamics, in complex arithmetic, with the
    reference's derivatives in closed form."""
    n, c = 3, jnp.asarray([1.0, -0.5, 0.8])

    def f(t, x, _):
        q, qd = x[:n], x[n:]
        e, ed, ar = 0.3 * jnp.sin(3 * t) * c - q, 0.9 * jnp.cos(3 * t) * c - qd, -2.7 * jnp.sin(3 * t) * c
        if law == "PDGravity":
            tau = kp * e + 0.2 * ed + rec.inverse_dynamics(q, 0 * q, 0 * q, pc)
        else:
            tau = rec.inverse_dynamics(q, qd, ar + 0.2 * ed + kp * e, pc)
        bias = rec.inverse_dynamics(q, qd, jnp.zeros_like(q), plant)
        return jnp.concatenate([qd, jnp.linalg.solve(rec.mass_matrix(q, plant), tau - bias)]), tau

    x, taus = _complex_rk4(f, X0_FB, dt, jnp.zeros(STEPS))
    return jnp.sum(jnp.sin(x) * jnp.arange(1, 2 * n + 1)[None, :]) + 1e-3 * jnp.sum(taus**2)


@pytest.mark.parametrize("law", ["PDGravity", "ComputedTorque"])
def test_tracking_law_gradients_match_complex_step_of_an_independent_rollout(arm, law):
    """The gradient with respect to the law's model parameters (adaptive control, identification of the
    controller's model), gains and step, through the one-call feedback step, against the complex step."""
    robot, dyn, _, _ = arm
    rec = recursive_dynamics(robot)
    p, dt = dyn.param_vector(), jnp.asarray(DT)
    run = jax.jit(lambda pc, kp, dt: _complex_law_rollout(rec, law, p.astype(complex), pc, kp, dt))
    base = [jnp.asarray(a, complex) for a in (p, KP, dt)]
    loss = _law_loss(dyn, law)
    np.testing.assert_allclose(loss(p, KP, dt), jnp.real(run(*base)), rtol=1e-12)
    grads = jax.jit(jax.grad(loss, argnums=(0, 1, 2)))(p, KP, dt)
    _check_complex_step(grads, run, base)


# ---------------------------------------------------------------- closed loop: compliant ground contact

K_GROUND, C_GROUND, MU, SLIP = 300.0, 5.0, 0.8, 0.5


def _frame_point(robot, rec, name, q, p):
    """The origin of the frame ``name`` in the world by chaining the numeric recursion's joint poses
    (independent of the derived ``ee_pose``)."""
    frame = robot.frame(name)
    offset = sp.lambdify([symbol(n) for n in robot.parameters], frame.offset, modules="jax")(*p)
    poses = rec._kinematics(q, p)[0]
    chain, body = [], frame.body
    while body >= 0:
        chain.append(body)
        body = rec.parents[body]
    rot, pos = jnp.eye(3, dtype=q.dtype), jnp.zeros(3, q.dtype)
    for i in reversed(chain):
        r_i, p_i = (jnp.asarray([[jnp.asarray(e, q.dtype) for e in row] for row in poses[i][0]]),
                    jnp.stack([jnp.asarray(e, q.dtype) for e in poses[i][1]]))
        rot, pos = rot @ r_i, rot @ p_i + pos
    return rot @ jnp.asarray(offset, q.dtype)[:3, 3] + pos


def _contact_loss(dyn, height):
    """PD towards the reference, the gripper pressed into and sliding on the ground at ``height``: a loss of
    the model parameters (the kinematics' lengths included) and the ground's stiffness."""
    def loss(p, k, dt):
        def hold(t, x):
            return KP * (_reference(t) - x[:3]) - 0.2 * x[3:]

        law = jaxskid.GroundContact(dyn, ["gripper"], stiffness=k, damping=C_GROUND, friction=MU, slip=SLIP,
                                    height=height, inner=hold, params=p)
        traj = jaxskid.rollout(dyn, X0_FB, law, dt, STEPS, params=p)
        return jnp.sum(jnp.sin(traj.x) * jnp.arange(1, 7)[None, :])

    return loss


def _complex_contact_rollout(robot, rec, height, p, k, dt):
    """The same rollout over the numeric recursion, the contact law written out with J = d(point)/dq by
    forward mode of the chained poses, in complex arithmetic (branches on real parts)."""
    n = 3

    def f(t, x, _):
        q, qd = x[:n], x[n:]
        point = _frame_point(robot, rec, "gripper", q, p)
        jac = jax.jacfwd(lambda q: _frame_point(robot, rec, "gripper", q, p), holomorphic=True)(q)
        vel = jac @ qd
        depth = height - point[2]
        push = k * depth - C_GROUND * vel[2]
        normal = jnp.where((jnp.real(depth) > 0) & (jnp.real(push) > 0), push, 0.0)
        slide = vel[:2]
        force = jnp.concatenate([-MU * normal / jnp.sqrt(jnp.sum(slide**2) + SLIP**2) * slide, normal[None]])
        tau = KP * (_reference(t) - q) - 0.2 * qd + jac.T @ force
        bias = rec.inverse_dynamics(q, qd, jnp.zeros_like(q), p)
        return jnp.concatenate([qd, jnp.linalg.solve(rec.mass_matrix(q, p), tau - bias)]), tau

    x, _ = _complex_rk4(f, X0_FB, dt, jnp.zeros(STEPS))
    return jnp.sum(jnp.sin(x) * jnp.arange(1, 2 * n + 1)[None, :])


@pytest.mark.slow
def test_contact_gradients_match_complex_step_of_an_independent_rollout():
    """Reverse mode through :class:`jaxskid.GroundContact` (the kinematics' pullbacks inside the one-call
    feedback step) with respect to every parameter (link lengths included) and the ground's stiffness."""
    robot = load("arm_3dof")
    dyn = jaxskid.lower(robot, ["forward_dynamics", "ee_pose", "ee_hybrid_twist", "external_torques"])
    rec = recursive_dynamics(robot)
    p, dt, k = dyn.param_vector(), jnp.asarray(DT), jnp.asarray(K_GROUND)
    start = _frame_point(robot, rec, "gripper", X0_FB[:3], p)
    np.testing.assert_allclose(start, dyn.ee_pose(X0_FB[:3])[0, :3, 3], rtol=1e-12, atol=1e-12)
    height = float(start[2]) + 0.05  # pressed 5 cm into the ground at the start
    loss = _contact_loss(dyn, height)
    run = jax.jit(lambda p, k, dt: _complex_contact_rollout(robot, rec, height, p, k, dt))
    base = [jnp.asarray(a, complex) for a in (p, k, dt)]
    np.testing.assert_allclose(loss(p, k, dt), jnp.real(run(*base)), rtol=1e-12)
    grads = jax.jit(jax.grad(loss, argnums=(0, 1, 2)))(p, k, dt)
    _check_complex_step(grads, run, base)
    assert float(jnp.abs(grads[1])) > 0  # the contact acts


# ---------------------------------------------------------------- a closed loop: the four-bar


def _complex_loop_rollout(robot, rec, p, x0, u, dt, alpha=10.0, beta=10.0):
    """RK4 of the four-bar held by its loop closure with Baumgarte's stabilisation, over the numeric recursion:
    the residual is the world x and z of the coupler's far end minus those of the rocker's tip (chained
    poses), its Jacobian and drift by forward mode, the KKT system solved dense, in complex arithmetic."""
    def phi(q):
        gap = _frame_point(robot, rec, "coupler_end", q, p) - _frame_point(robot, rec, "rocker_tip", q, p)
        return gap[jnp.asarray([0, 2])]

    def f(t, x, tau):
        q, qd = x[:3], x[3:]
        a = jax.jacfwd(phi, holomorphic=True)(q)
        drift = jax.jacfwd(lambda q: jax.jacfwd(phi, holomorphic=True)(q) @ qd, holomorphic=True)(q) @ qd
        gamma = -drift - 2 * alpha * a @ qd - beta**2 * phi(q)
        kkt = jnp.block([[rec.mass_matrix(q, p), -a.T], [a, jnp.zeros((2, 2), a.dtype)]])
        rhs = jnp.concatenate([tau - rec.inverse_dynamics(q, qd, jnp.zeros_like(q), p), gamma])
        return jnp.concatenate([qd, jnp.linalg.solve(kkt, rhs)[:3]]), tau

    x, _ = _complex_rk4(f, x0, dt, u)
    return jnp.sum(x**2)


@pytest.mark.slow
def test_loop_gradients_match_complex_step_of_an_independent_rollout():
    """Reverse mode through the constrained rollout of the four-bar (``robots/four_bar.yaml``) with respect to
    its parameters, initial state and torques, against the complex step of the rollout written out here."""
    robot = load("four_bar")
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "constraint_jacobian", "constraint_drift",
                                "constraint_residual"])
    rec = recursive_dynamics(robot)  # the tree: the loop enters through phi below
    steps, dt = 40, 5e-3
    g = jnp.asarray([1.0, -1.0, 1.0])
    x0 = jnp.concatenate([0.9 * g, -0.5 * g])
    u = jnp.stack([0.5 * jnp.sin(3.0 * dt * jnp.arange(steps)), jnp.zeros(steps), jnp.zeros(steps)], axis=1)
    p = dyn.param_vector()

    def loss(p, x0, u):
        return jnp.sum(jaxskid.rollout(dyn, x0, u, dt, steps, params=p).x ** 2)

    run = jax.jit(lambda p, x0, u: _complex_loop_rollout(robot, rec, p, x0, u, dt))
    base = [jnp.asarray(a, complex) for a in (p, x0, u)]
    np.testing.assert_allclose(loss(p, x0, u), jnp.real(run(*base)), rtol=1e-11)
    grads = jax.jit(jax.grad(loss, argnums=(0, 1, 2)))(p, x0, u)
    _check_complex_step(grads, run, base, sample=6, seed=2, rtol=1e-8, atol=1e-10)
