"""The regressor, standard and base parameters, and identification, against Pinocchio and statistics.

References: Pinocchio's ``computeJointTorqueRegressor`` and ``rnea`` on its own URDF parser's models, its
``Inertia.toDynamicParameters`` and ``LogCholeskyParameters``; the textbook closed form of the planar 2R
arm (Lynch & Park 2017, sec. 8.1.1); the chi-square distribution of least-squares errors.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import scipy.stats

import jaxskid
from jaxskid.apps.identification._identification import random_states
from randrobot import random_robot
from helpers import FINGERS, PANDA, URDFS as ERD_URDFS, pinocchio_urdf_model, random_tree_regressor

REPO = Path(__file__).resolve().parents[1]
URDFS = {
    "panda": (PANDA, FINGERS),
    "ur5": (ERD_URDFS["ur5"], None),
    "solo12": (ERD_URDFS["solo12"], None),
}
BATCH = 100  # = base_parameters' default sample count: one compiled batch size per robot


def pin_model(name):
    """Pinocchio's own model of the URDF (its parser), locked joints removed at the same positions."""
    return pinocchio_urdf_model(*URDFS[name])


@pytest.fixture(scope="module")
def urdf_robot():
    cache = {}

    def get(name):
        if name not in cache:
            path, lock = URDFS[name]
            robot = jaxskid.read_urdf(path, lock=lock)
            cache[name] = (robot, jaxskid.lower(robot, ["regressor", "inverse_dynamics"]))
        return cache[name]

    return get


# ------------------------------------------------------------------------------------------ regressor
@pytest.mark.parametrize("name", ["panda", "solo12"])
def test_regressor_times_parameters_is_pinocchio_tau(urdf_robot, name):
    robot, dyn = urdf_robot(name)
    model = pin_model(name)
    data = model.createData()
    assert model.nv == robot.n_dof
    pi = jaxskid.standard_params(robot)
    pi_pin = np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])
    np.testing.assert_allclose(pi, pi_pin, rtol=0, atol=1e-12)
    q, qd, qdd = random_states(robot.n_dof, BATCH, seed=1, scale=2.0)
    y = np.asarray(dyn.regressor(q, qd, qdd))
    assert y.shape == (BATCH, robot.n_dof, 10 * robot.n_dof)
    for k in range(BATCH):
        tau = pin.rnea(model, data, q[k], qd[k], qdd[k])
        np.testing.assert_allclose(y[k] @ pi, tau, rtol=0, atol=1e-10 * max(1.0, np.abs(tau).max()))
        # URDF joint frames are the body frames: the regressor itself is Pinocchio's, column by column
        np.testing.assert_allclose(y[k], pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]), atol=1e-10)


def test_regressor_random_trees_with_prismatic_joints():
    """Y pi on random trees (revolute axes off the body origin, prismatic joints) equals Pinocchio's rnea."""
    robot, dyn, params, pi, model, data = random_tree_regressor(np.random.default_rng(7), 5, prismatic=0.4)
    q, qd, qdd = random_states(robot.n_dof, 8, seed=2)
    y = np.asarray(dyn.regressor(q, qd, qdd, params))
    for k in range(8):
        np.testing.assert_allclose(y[k] @ pi, pin.rnea(model, data, q[k], qd[k], qdd[k]), atol=1e-10)


def test_regressor_2r_textbook_closed_form_with_symbolic_lengths():
    """Non-default lengths and masses: Y(l1, l2, g) pi(m1, m2, l1, l2) against Lynch & Park's 2R arm."""
    robot = jaxskid.load(REPO / "robots/arm_2r.yaml")
    dyn = jaxskid.lower(robot, ["regressor"])
    m1, m2, l1, l2, g = 1.7, 0.6, 0.55, 0.35, 9.3
    params = {"m1": m1, "m2": m2, "l1": l1, "l2": l2, "g": g}
    pi = jaxskid.standard_params(robot, params)
    rng = np.random.default_rng(3)
    for _ in range(5):
        (q1, q2), (d1, d2), (a1, a2) = rng.normal(size=(3, 2))
        c2, s2 = np.cos(q2), np.sin(q2)
        m11 = m1 * l1**2 + m2 * (l1**2 + 2 * l1 * l2 * c2 + l2**2)
        m12 = m2 * (l1 * l2 * c2 + l2**2)
        m22 = m2 * l2**2
        h = m2 * l1 * l2 * s2
        tau = np.array([
            m11 * a1 + m12 * a2 - h * (2 * d1 * d2 + d2**2) + (m1 + m2) * g * l1 * np.cos(q1) + m2 * g * l2 * np.cos(q1 + q2),
            m12 * a1 + m22 * a2 + h * d1**2 + m2 * g * l2 * np.cos(q1 + q2),
        ])
        y = np.asarray(dyn.regressor(np.array([q1, q2]), np.array([d1, d2]), np.array([a1, a2]), params))
        np.testing.assert_allclose(y @ pi, tau, atol=1e-12)


def test_params_from_standard_inverts_standard_params(urdf_robot):
    robot, _ = urdf_robot("panda")
    rng = np.random.default_rng(0)
    values = {k: v * (1 + 0.1 * rng.normal()) for k, v in robot.default_params().items()}
    back = jaxskid.params_from_standard(robot, jaxskid.standard_params(robot, values))
    assert back.keys() == values.keys()
    np.testing.assert_allclose([back[k] for k in values], list(values.values()), rtol=1e-12)
    point_masses = jaxskid.load(REPO / "robots/arm_2r.yaml")  # inertias m l^2: not affine in (m, l)
    with pytest.raises(jaxskid.ModelError, match="cannot"):
        jaxskid.params_from_standard(point_masses, np.ones(20))


def test_standard_parameters_follow_the_parameter_rule(urdf_robot):
    """Standard parameters are named as the robot's own ({link}_{p}); params follow the one rule: a partial
    dict takes the defaults for the rest, an unknown name is an error naming the closest valid ones."""
    robot, _ = urdf_robot("panda")
    names = jaxskid.standard_parameter_names(robot)
    assert names[:2] == ("panda_link1_m", "panda_link1_mcx") and len(names) == 10 * robot.n_dof
    assert set(names) == set(robot.parameters)  # symbolic URDF inertias: the same names, one convention
    defaults = robot.default_params()
    partial = {"panda_link3_m": 2.5}
    np.testing.assert_array_equal(jaxskid.standard_params(robot, partial),
                                  jaxskid.standard_params(robot, {**defaults, **partial}))
    np.testing.assert_array_equal(jaxskid.standard_params(robot, [defaults[k] for k in robot.parameters]),
                                  jaxskid.standard_params(robot))
    with pytest.raises(jaxskid.RequestError, match="'panda_link3_mass'.*did you mean 'panda_link3_m"):
        jaxskid.standard_params(robot, {"panda_link3_mass": 2.5})
    with pytest.raises(jaxskid.RequestError, match="panda_link3_mass"):
        jaxskid.params_from_standard(robot, jaxskid.standard_params(robot), {"panda_link3_mass": 2.5})
    with pytest.raises(jaxskid.ShapeError, match="standard_params"):
        jaxskid.standard_params(robot, np.ones(3))


# ------------------------------------------------------------------------------------------ base parameters
@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_number_of_base_parameters_matches_pinocchio(urdf_robot, name):
    robot, dyn = urdf_robot(name)
    base = jaxskid.base_parameters(dyn, names=jaxskid.standard_parameter_names(robot))
    model = pin_model(name)
    data = model.createData()
    q, qd, qdd = random_states(robot.n_dof, 60, seed=11)
    w = np.vstack([pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]) for k in range(60)])
    assert base.n_base == np.linalg.matrix_rank(w) == {"panda": 43, "ur5": 36}[name]
    # Y = Y_b K on states the base parameters were not computed from: tau = Y_b (K pi)
    q, qd, qdd = random_states(robot.n_dof, BATCH, seed=12)
    y = np.asarray(dyn.regressor(q, qd, qdd))
    np.testing.assert_allclose(np.asarray(base.reduce(y)) @ base.projection, y, atol=1e-9)
    assert len(base.describe()) == base.n_base


@pytest.fixture(scope="module")
def panda_data(urdf_robot):
    """Regressor rows (ours) and torques (Pinocchio's rnea) on 400 random Panda states."""
    robot, dyn = urdf_robot("panda")
    base = jaxskid.base_parameters(dyn)
    model = pin_model("panda")
    data = model.createData()
    q, qd, qdd = random_states(7, 4 * BATCH, seed=5)
    tau = np.stack([pin.rnea(model, data, q[k], qd[k], qdd[k]) for k in range(4 * BATCH)])
    # in batches of one size: every new batch size compiles the 490-output regressor again (seconds)
    chunks = [dyn.regressor(*(x[k: k + BATCH] for x in (q, qd, qdd))) for k in range(0, 4 * BATCH, BATCH)]
    yb = np.asarray(base.reduce(np.concatenate(chunks)))
    return base, yb, tau, base.project(jaxskid.standard_params(robot))


def test_least_squares_recovers_base_parameters_noise_free(panda_data):
    base, yb, tau, truth = panda_data
    est = jaxskid.identify(yb, tau, jaxskid.LeastSquares())
    np.testing.assert_allclose(est.params, truth, rtol=0, atol=1e-8 * np.abs(truth).max())
    assert est.residual_std.max() < 1e-10


def _mahalanobis(est, truth):
    e = est.params - truth
    return float(e @ np.linalg.solve(est.covariance, e))


def test_least_squares_noisy_within_confidence(panda_data):
    """With noise, the error is chi-square distributed under the reported covariance (two-sided 99.8 %),
    and it shrinks like 1/sqrt(samples)."""
    base, yb, tau, truth = panda_data
    rng = np.random.default_rng(9)
    sigma = 0.05
    noisy = tau + sigma * rng.normal(size=tau.shape)
    lo, hi = scipy.stats.chi2.ppf([0.001, 0.999], base.n_base)
    errors = []
    for samples in (100, 400):
        est = jaxskid.identify(yb[:samples], noisy[:samples], jaxskid.LeastSquares())
        assert lo < _mahalanobis(est, truth) < hi
        np.testing.assert_allclose(est.residual_std, sigma, rtol=0.15)
        errors.append(np.sqrt(np.trace(est.covariance)))
    assert 1.5 < errors[0] / errors[1] < 2.7  # ~ sqrt(4)


def test_weighted_least_squares_estimates_joint_noise(panda_data):
    base, yb, tau, truth = panda_data
    rng = np.random.default_rng(10)
    sigma = np.array([0.2, 0.01, 0.1, 0.02, 0.3, 0.05, 0.01])
    noisy = tau + sigma * rng.normal(size=tau.shape)
    wls = jaxskid.identify(yb, noisy, jaxskid.WeightedLeastSquares())
    ols = jaxskid.identify(yb, noisy, jaxskid.LeastSquares())
    np.testing.assert_allclose(wls.residual_std, sigma, rtol=0.2)
    lo, hi = scipy.stats.chi2.ppf([0.001, 0.999], base.n_base)
    assert lo < _mahalanobis(wls, truth) < hi
    assert np.linalg.norm(wls.params - truth) < np.linalg.norm(ols.params - truth)
    known = jaxskid.identify(yb, noisy, jaxskid.WeightedLeastSquares(sigma))
    assert lo < _mahalanobis(known, truth) < hi


# ------------------------------------------------------------------------------------------ physical consistency
def test_log_cholesky_matches_pinocchio_and_round_trips():
    rng = np.random.default_rng(4)
    theta = rng.normal(size=(6, 10))
    pi = np.asarray(jaxskid.LogCholesky().standard(jnp.asarray(theta.reshape(-1))))
    ref = np.concatenate([pin.LogCholeskyParameters(t).toDynamicParameters() for t in theta])
    np.testing.assert_allclose(pi, ref, rtol=1e-12, atol=1e-12)
    assert jaxskid.physically_consistent(pi).all()
    np.testing.assert_allclose(np.asarray(jaxskid.LogCholesky().init(jnp.asarray(pi))), theta.reshape(-1), atol=1e-10)
    bad = pi.copy()
    bad[4] = -1.0  # negative Ixx on body 0
    assert not jaxskid.physically_consistent(bad)[0]


def test_gradient_fit_log_cholesky_stays_physical_and_fits():
    """A gradient fit of all 30 standard parameters of a 3-body chain from noisy torques: every iterate is
    physically consistent, and the identifiable (base) part converges to the least-squares answer."""
    rng = np.random.default_rng(21)
    robot = random_robot(rng, 3, tree=False, prismatic=0.0)
    dyn = jaxskid.lower(robot, ["regressor"])
    params = robot.default_params()
    base = jaxskid.base_parameters(dyn, params)
    truth = jaxskid.standard_params(robot, params)
    q, qd, qdd = random_states(3, 200, seed=22)
    y = np.asarray(dyn.regressor(q, qd, qdd, params))
    tau = y @ truth + 0.01 * rng.normal(size=(200, 3))
    init = truth * np.repeat(rng.uniform(0.6, 1.4, size=3), 10)  # scaled bodies: still physical
    method = jaxskid.GradientFit(init, jaxskid.LogCholesky(), jaxskid.Adam(3e-3), steps=3000, prior=1e-6)
    est = jaxskid.identify(y, tau, method)
    assert jaxskid.physically_consistent(est.params).all()
    assert est.history[-1] < 1e-2 * est.history[0]
    ls = jaxskid.identify(np.asarray(base.reduce(y)), tau, jaxskid.LeastSquares())
    np.testing.assert_allclose(base.project(est.params), ls.params, atol=5 * np.sqrt(np.diag(ls.covariance)).max())


# ------------------------------------------------------------------------------------------ fits through quantities
def test_fit_through_inverse_dynamics_recovers_user_parameters():
    """jax.grad through a lowered quantity with the user's own symbols (masses of the 2R arm)."""
    robot = jaxskid.load(REPO / "robots/arm_2r.yaml")
    dyn = jaxskid.lower(robot, ["inverse_dynamics"])
    truth = robot.default_params()
    q, qd, qdd = random_states(2, 64, seed=30)
    tau = np.asarray(dyn.inverse_dynamics(q, qd, qdd, truth))

    def to_params(theta):
        return {**truth, "m1": jnp.exp(theta[0]), "m2": jnp.exp(theta[1])}  # log-masses: positive

    loss = jaxskid.quantity_loss(dyn, "inverse_dynamics", (q, qd, qdd), tau, to_params)
    result = jaxskid.fit(loss, jnp.log(jnp.array([0.3, 2.0])), optimizer=jaxskid.Adam(5e-2), steps=600)
    np.testing.assert_allclose(np.exp(np.asarray(result.theta)), [truth["m1"], truth["m2"]], rtol=1e-6)
    # the gradient is jax.grad's: check it against central differences at a point
    at = jnp.array([0.1, -0.2])
    g = jax.grad(loss)(at)
    step = 1e-6 * jnp.eye(2)
    fd = [(loss(at + step[k]) - loss(at - step[k])) / 2e-6 for k in range(2)]
    np.testing.assert_allclose(np.asarray(g), fd, rtol=1e-6)


@pytest.mark.slow
def test_fit_through_simulated_trajectory():
    """Gradient through a whole rollout: the double pendulum's masses from a measured trajectory."""
    robot = jaxskid.load(REPO / "robots/double_pendulum.yaml")
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    truth = robot.default_params()
    controls = 3.0 * np.sin(np.linspace(0, 6, 100))[:, None] * np.array([[1.0, -0.7]])
    x0 = jnp.array([0.4, -0.3, 0.0, 0.0])
    measured = jaxskid.rollout(dyn, x0, controls, 0.02, 100, params=truth)

    def to_params(theta):
        return {**truth, "m1": jnp.exp(theta[0]), "m2": jnp.exp(theta[1])}

    loss = jaxskid.trajectory_loss(dyn, measured, controls, to_params)
    result = jaxskid.fit(loss, jnp.log(jnp.array([0.7, 1.3])), optimizer=jaxskid.Adam(5e-2), steps=250)
    np.testing.assert_allclose(np.exp(np.asarray(result.theta)), [truth["m1"], truth["m2"]], rtol=1e-3)
    assert result.history[-1] < 1e-6 * result.history[0]
