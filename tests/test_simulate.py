"""Rollouts against textbook energy, measured orders, central differences and the unsharded computation.

References: the double pendulum's closed-form energy, the convergence order measured on a sequence of steps,
central differences, the unsharded computation for the sharded one, and rollouts through the numeric forward
dynamics for those through the closed-form quantity (forward dynamics itself: tests/test_forward_dynamics.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import lowered

REPO = Path(__file__).resolve().parents[1]


def pendulum_energy(x, p):
    """Closed form (robots/double_pendulum.yaml): point masses at the link ends plus I1, I2, hanging at q=0."""
    q1, q2, d1, d2 = (x[..., k] for k in range(4))
    m1, m2, l1, l2, i1, i2, g = (p[k] for k in ("m1", "m2", "l1", "l2", "I1", "I2", "g"))
    m11 = i1 + i2 + m1 * l1**2 + m2 * (l1**2 + l2**2 + 2 * l1 * l2 * np.cos(q2))
    m12 = i2 + m2 * (l2**2 + l1 * l2 * np.cos(q2))
    m22 = i2 + m2 * l2**2
    kinetic = 0.5 * (m11 * d1 * d1 + 2 * m12 * d1 * d2 + m22 * d2 * d2)
    return kinetic - (m1 + m2) * g * l1 * np.cos(q1) - m2 * g * l2 * np.cos(q1 + q2)


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
