"""``lower(..., checks="debug")``: NaN and inf in the states of calls inside ``jit``, ``grad`` and ``vmap`` fail the
compiled program with the argument and its first bad index named, as the top-level checks do
(tests/test_guard_rails.py); finite inputs give the plain results."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import URDFS

import jaxskid

QUANTITIES = ["mass_matrix", "inverse_dynamics", "forward_dynamics"]


@pytest.fixture(scope="module")
def ur5():
    robot = jaxskid.load(URDFS["ur5"])
    return jaxskid.lower(robot, QUANTITIES, checks="debug"), jaxskid.lower(robot, QUANTITIES)


def fails(match):
    """The compiled program's error, carrying the InputError's message."""
    return pytest.raises(jax.errors.JaxRuntimeError, match=rf"InputError: {match}")


def test_jit_names_the_argument_and_index(ur5):
    dyn, _ = ur5
    q = jnp.zeros(dyn.n_dof).at[2].set(jnp.nan)
    with fails(r"mass_matrix: q\[2\] is nan: expected finite values"):
        jax.block_until_ready(jax.jit(dyn.mass_matrix)(q))
    with fails(r"inverse_dynamics: qdd\[4\] is inf"):
        z = jnp.zeros(dyn.n_dof)
        jax.block_until_ready(jax.jit(dyn.inverse_dynamics)(z, z, z.at[4].set(jnp.inf)))


def test_vmap_names_the_batch_index(ur5):
    dyn, _ = ur5
    q = jnp.zeros((6, dyn.n_dof)).at[3, 1].set(-jnp.inf)
    with fails(r"mass_matrix: q\[3, 1\] is -inf"):
        jax.block_until_ready(jax.jit(jax.vmap(dyn.mass_matrix))(q))
    with fails(r"mass_matrix: q\[3, 1\] is -inf"):  # a batch given to the quantity itself
        jax.block_until_ready(jax.jit(dyn.mass_matrix)(q))


def test_gradients_check_the_primal_values(ur5):
    dyn, _ = ur5
    q = jnp.zeros(dyn.n_dof).at[5].set(jnp.nan)
    with fails(r"mass_matrix: q\[5\] is nan"):
        jax.block_until_ready(jax.jit(jax.grad(lambda q: jnp.sum(dyn.mass_matrix(q) ** 2)))(q))


def test_parameters_are_named(ur5):
    dyn, _ = ur5
    k = dyn.parameters.index("forearm_link_m")
    p = jnp.asarray(dyn.param_vector()).at[k].set(jnp.nan)
    with fails(rf"mass_matrix: params\[{k}\] \(forearm_link_m\) is nan"):
        jax.block_until_ready(jax.jit(dyn.mass_matrix)(jnp.zeros(dyn.n_dof), p))


def test_forward_dynamics_and_rollouts(ur5):
    dyn, _ = ur5
    n = dyn.n_dof
    z = jnp.zeros(n)
    with fails(r"forward_dynamics: tau\[0\] is nan"):
        jax.block_until_ready(jax.jit(lambda tau: jaxskid.forward_dynamics(dyn, z, z, tau))(z.at[0].set(jnp.nan)))
    x0 = jnp.zeros(2 * n).at[1].set(jnp.nan)
    with fails(r"rollout: x0\[1\] is nan"):
        jax.block_until_ready(jax.jit(lambda x0: jaxskid.rollout(dyn, x0, jnp.zeros((5, n)), 1e-3, 5).x)(x0))


def test_finite_inputs_give_the_plain_results(ur5):
    dyn, plain = ur5
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.standard_normal((3, 4, dyn.n_dof))
    np.testing.assert_allclose(jax.jit(jax.vmap(dyn.inverse_dynamics))(q, qd, qdd),
                               plain.inverse_dynamics(q, qd, qdd), rtol=1e-13, atol=1e-12)
    loss = lambda d: jax.jit(jax.grad(lambda q: jnp.sum(d.mass_matrix(q) ** 2)))(q[0])  # noqa: E731
    np.testing.assert_allclose(loss(dyn), loss(plain), rtol=1e-13, atol=1e-12)
    assert isinstance(dyn, jaxskid.Dynamics) and dyn.checks == "debug"


def test_unknown_mode_is_refused():
    with pytest.raises(jaxskid.RequestError, match=r"checks: expected True .*, False or 'debug' .*, got 'jit'"):
        jaxskid.lower(jaxskid.load(URDFS["ur5"]), ["mass_matrix"], checks="jit")
