"""The parameter rule, at every entry point that takes ``params``.

The rule: ``None`` means the defaults; in a dict, missing names take their defaults and an unknown name is
an error that names it and the closest valid names; leading batch axes of the parameters broadcast against
those of the states. References: the same call with the complete vector, a loop over single calls, and
the gradient with respect to the vector.
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid

REPO = Path(__file__).resolve().parents[1]
PENDULUM = REPO / "robots/double_pendulum.yaml"
ERD = Path(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))


@pytest.fixture(scope="module")
def pendulum():
    robot = jaxskid.load(PENDULUM)
    return robot, jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "gravity_torques"])


def states(n, batch, seed):
    rng = np.random.default_rng(seed)
    return tuple(rng.uniform(-1, 1, size=(*batch, n)) for _ in range(3))


def varied(dyn, batch, seed):
    """``(*batch, n_params)`` parameter vectors, each within 30 % of the defaults."""
    rng = np.random.default_rng(seed)
    return np.asarray(dyn.param_vector()) * rng.uniform(0.7, 1.3, size=(*batch, len(dyn.parameters)))


def with_vector(dyn, vector) -> dict:
    return dict(zip(dyn.parameters, map(float, vector)))


# ------------------------------------------------------------------------------------------ dicts
def test_partial_dict_takes_the_defaults_for_missing_names(pendulum):
    robot, dyn = pendulum
    q, qd, qdd = states(2, (), 0)
    full = dict(robot.default_params(), m2=2.5, l1=0.7)
    partial = {"m2": 2.5, "l1": 0.7}
    for fn, args in ((dyn.mass_matrix, (q,)), (dyn.inverse_dynamics, (q, qd, qdd)), (dyn.gravity_torques, (q,))):
        np.testing.assert_array_equal(np.asarray(fn(*args, partial)), np.asarray(fn(*args, full)))
    np.testing.assert_array_equal(np.asarray(dyn.param_vector(partial)), np.asarray(dyn.param_vector(full)))
    np.testing.assert_array_equal(np.asarray(jaxskid.forward_dynamics(dyn, q, qd, qdd, partial)),
                                  np.asarray(jaxskid.forward_dynamics(dyn, q, qd, qdd, full)))
    x0 = np.concatenate([q, qd])
    a = jaxskid.rollout(dyn, x0, np.zeros((20, 2)), 0.01, 20, params=partial)
    b = jaxskid.rollout(dyn, x0, np.zeros((20, 2)), 0.01, 20, params=full)
    np.testing.assert_array_equal(np.asarray(a.x), np.asarray(b.x))


def test_unknown_name_is_named_with_the_closest_valid_ones(pendulum):
    robot, dyn = pendulum
    q, qd, qdd = states(2, (), 1)
    bad = dict(robot.default_params(), m_2=2.0)  # a complete dict with one mistyped key
    calls = {
        "mass_matrix": lambda: dyn.mass_matrix(q, bad),
        "inverse_dynamics": lambda: dyn.inverse_dynamics(q, qd, qdd, bad),
        "param_vector": lambda: dyn.param_vector(bad),
        "forward_dynamics": lambda: jaxskid.forward_dynamics(dyn, q, qd, qdd, bad),
        "rollout": lambda: jaxskid.rollout(dyn, np.zeros(4), np.zeros((5, 2)), 0.01, 5, params=bad),
        "grad": lambda: jax.grad(lambda p: jnp.sum(dyn.gravity_torques(q, p)))({"m_2": jnp.asarray(2.0)}),
    }
    for where, call in calls.items():
        with pytest.raises(jaxskid.RequestError, match=r"unknown parameter 'm_2' \(did you mean 'm2'") as info:
            call()
        assert len(str(info.value)) < 200, where  # names the culprit, not every parameter


@pytest.mark.slow
def test_ur5_partial_dict_and_mistyped_key():
    """The UR5 as a new user meets it: a partial dict is filled from the defaults, a mistyped key is named."""
    robot = jaxskid.load(ERD / "ur_description/urdf/ur5_robot.urdf")
    dyn = jaxskid.lower(robot, ["inverse_dynamics"])
    q, qd, qdd = states(robot.n_dof, (), 2)
    name = next(k for k in dyn.parameters if k.endswith("_m"))
    heavier = {name: 2 * dyn.defaults[name]}
    np.testing.assert_array_equal(np.asarray(dyn.inverse_dynamics(q, qd, qdd, heavier)),
                                  np.asarray(dyn.inverse_dynamics(q, qd, qdd, dict(dyn.defaults, **heavier))))
    typo = name[:-2] + "_mass"
    with pytest.raises(jaxskid.RequestError, match=f"unknown parameter '{typo}' \\(did you mean '{name}'"):
        dyn.inverse_dynamics(q, qd, qdd, dict(dyn.defaults, **{typo: 1.0}))


def test_dict_and_vector_and_none_agree(pendulum):
    robot, dyn = pendulum
    q, qd, qdd = states(2, (5,), 3)
    p = varied(dyn, (), 4)
    named = with_vector(dyn, p)
    for fn, args in ((dyn.mass_matrix, (q,)), (dyn.inverse_dynamics, (q, qd, qdd))):
        for state in (args, tuple(a[0] for a in args)):  # a batch and one state
            np.testing.assert_array_equal(np.asarray(fn(*state, named)), np.asarray(fn(*state, p)))
            np.testing.assert_array_equal(np.asarray(fn(*state)), np.asarray(fn(*state, robot.default_params())))
            np.testing.assert_array_equal(np.asarray(fn(*state, None)), np.asarray(fn(*state, dyn.param_vector())))
    np.testing.assert_array_equal(np.asarray(jaxskid.forward_dynamics(dyn, q, qd, qdd, named)),
                                  np.asarray(jaxskid.forward_dynamics(dyn, q, qd, qdd, p)))


def test_a_dict_changed_between_calls_is_read_again(pendulum):
    """A dict equal to the last one reuses its packed vector; a changed one (in place) does not."""
    robot, dyn = pendulum
    q, qd, qdd = states(2, (), 13)
    named = robot.default_params()
    before = np.asarray(dyn.mass_matrix(q, named))
    named["m2"] = 3.0
    after = np.asarray(dyn.mass_matrix(q, named))
    np.testing.assert_array_equal(after, np.asarray(dyn.mass_matrix(q, {"m2": 3.0})))
    assert not np.allclose(after, before)
    np.testing.assert_array_equal(np.asarray(dyn.param_vector(named))[dyn.parameters.index("m2")], 3.0)
    batched = dict(named, m1=np.array([1.0, 2.0]))  # equal keys, an array value: packed inside, not reused
    assert dyn.inverse_dynamics(q, qd, qdd, batched).shape == (2, 2)
    lighter = dict(named, m1=0.5)
    inside = jax.jit(lambda q: dyn.mass_matrix(q, lighter))(q)  # a new plain dict inside a caller's jit
    np.testing.assert_array_equal(np.asarray(dyn.mass_matrix(q, lighter)), np.asarray(inside))  # nothing leaked


def test_parameter_without_default_must_be_given(tmp_path):
    text = PENDULUM.read_text().replace("  g: 9.81\n", "")
    path = tmp_path / "pendulum_no_g.yaml"
    path.write_text(text)
    robot = jaxskid.load(path)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "gravity_torques"])
    assert "g" in dyn.parameters and "g" not in dyn.defaults
    q, qd, qdd = states(2, (), 5)
    for call in (lambda: dyn.gravity_torques(q), lambda: dyn.gravity_torques(q, {"m1": 2.0}),
                 lambda: dyn.param_vector(), lambda: jaxskid.forward_dynamics(dyn, q, qd, qdd)):
        with pytest.raises(jaxskid.RequestError, match="no value for g"):
            call()
    np.testing.assert_allclose(np.asarray(dyn.gravity_torques(q, {"g": 0.0})), 0.0, atol=1e-15)


# ------------------------------------------------------------------------------------------ batches
def test_batch_of_parameter_vectors_equals_a_loop(pendulum):
    _, dyn = pendulum
    q, qd, qdd = states(2, (6,), 6)
    p = varied(dyn, (6,), 7)
    batched = {
        "mass_matrix": dyn.mass_matrix(q, p),
        "inverse_dynamics": dyn.inverse_dynamics(q, qd, qdd, p),
        "forward_dynamics": jaxskid.forward_dynamics(dyn, q, qd, qdd, p),
    }
    loops = {
        "mass_matrix": [dyn.mass_matrix(q[k], p[k]) for k in range(6)],
        "inverse_dynamics": [dyn.inverse_dynamics(q[k], qd[k], qdd[k], p[k]) for k in range(6)],
        "forward_dynamics": [jaxskid.forward_dynamics(dyn, q[k], qd[k], qdd[k], p[k]) for k in range(6)],
    }
    for name, out in batched.items():
        np.testing.assert_allclose(np.asarray(out), np.stack(loops[name]), rtol=1e-13, atol=1e-13, err_msg=name)
    x0 = np.concatenate([q, qd], axis=-1)
    traj = jaxskid.rollout(dyn, x0, np.zeros((30, 2)), 0.01, 30, params=p)
    for k in range(6):
        one = jaxskid.rollout(dyn, x0[k], np.zeros((30, 2)), 0.01, 30, params=p[k])
        np.testing.assert_allclose(np.asarray(traj.x[k]), np.asarray(one.x), rtol=1e-12, atol=1e-12)


def test_parameter_batch_broadcasts_against_the_state_batch(pendulum):
    _, dyn = pendulum
    q, _, _ = states(2, (), 8)
    p = varied(dyn, (2, 3), 9)
    sweep = dyn.mass_matrix(q, p)  # one state, a (2, 3) grid of parameter sets
    assert sweep.shape == (2, 3, 2, 2)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(np.asarray(sweep[i, j]), np.asarray(dyn.mass_matrix(q, p[i, j])), rtol=1e-13)
    qs = np.stack([q, -q, 0.5 * q])  # (3, n) states against (2, 3) parameter sets: batch (2, 3)
    both = dyn.gravity_torques(qs, p)
    assert both.shape == (2, 3, 2)
    np.testing.assert_allclose(np.asarray(both[1, 2]), np.asarray(dyn.gravity_torques(qs[2], p[1, 2])), rtol=1e-13)
    with pytest.raises(jaxskid.ShapeError, match=r"params: batch \(4,\) does not broadcast"):
        dyn.mass_matrix(np.zeros((3, 2)), varied(dyn, (4,), 10))


def test_dict_of_batched_values(pendulum):
    robot, dyn = pendulum
    q, qd, qdd = states(2, (4,), 11)
    masses = np.array([0.5, 1.0, 2.0, 4.0])
    out = dyn.inverse_dynamics(q, qd, qdd, {"m2": masses})
    for k in range(4):
        np.testing.assert_allclose(np.asarray(out[k]), np.asarray(dyn.inverse_dynamics(q[k], qd[k], qdd[k], {"m2": masses[k]})),
                                   rtol=1e-13)
    vectors = dyn.param_vector({"m2": masses, "l1": 0.6})
    assert vectors.shape == (4, len(dyn.parameters))
    np.testing.assert_allclose(np.asarray(jaxskid.forward_dynamics(dyn, q, qd, qdd, {"m2": jnp.asarray(masses)})),
                               np.asarray(jaxskid.forward_dynamics(dyn, q, qd, qdd, dyn.param_vector({"m2": masses}))),
                               rtol=1e-13)


# ------------------------------------------------------------------------------------------ gradients
def test_grad_with_respect_to_a_dict_equals_grad_with_respect_to_the_vector(pendulum):
    robot, dyn = pendulum
    q, qd, qdd = states(2, (8,), 12)

    def loss(p):
        return jnp.sum(dyn.inverse_dynamics(q, qd, qdd, p) ** 2) + jnp.sum(jaxskid.forward_dynamics(dyn, q, qd, qdd, p) ** 2)

    named = {k: jnp.asarray(v) for k, v in robot.default_params().items()}
    by_name = jax.grad(loss)(named)
    by_vector = jax.grad(loss)(dyn.param_vector())
    np.testing.assert_allclose(np.array([by_name[k] for k in dyn.parameters]), np.asarray(by_vector), rtol=1e-12)
    partial = jax.grad(loss)({"m2": jnp.asarray(1.0)})  # only m2 is a variable; the rest are defaults
    np.testing.assert_allclose(float(partial["m2"]), float(by_vector[dyn.parameters.index("m2")]), rtol=1e-12)
