"""Joint limits read from URDF (against the XML read by xml.etree) and kept out of every cache key; finite
Fourier excitation trajectories (derivatives against jax.jacfwd and finite differences, periodicity, amplitude
bounds against a fine grid); excitation design (its criterion recomputed with NumPy, its limits checked on a fine
grid, its condition number against random trajectories of the same size)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from helpers import FINGERS, PANDA, ROBOTS_DIR, URDFS

import jaxskid
from jaxskid import FourierTrajectory, JointLimits, ModelError, RequestError, ShapeError
from jaxskid._api import module_key
from jaxskid.apps.identification._excitation import _stacked_regressor


def _random_fourier(rng, n, harmonics, period, scale=1.0) -> FourierTrajectory:
    return FourierTrajectory(jnp.asarray(rng.normal(size=n)), jnp.asarray(scale * rng.normal(size=(n, harmonics))),
                             jnp.asarray(scale * rng.normal(size=(n, harmonics))), period)


# ---------------------------------------------------------------------------------------- joint limits
def _xml_limits(path, names) -> np.ndarray:
    """(lower, upper, velocity, effort) per named joint from the URDF's XML: +-inf where not given, and no
    position limits for a continuous joint."""
    joints = {el.get("name"): el for el in ET.parse(path).getroot().findall("joint")}
    rows = []
    for name in names:
        el, limit = joints[name], joints[name].find("limit")
        get = (lambda key, default: float(limit.get(key, default))) if limit is not None else (lambda k, d: float(d))
        bounded = el.get("type") != "continuous"
        rows.append([get("lower", "-inf") if bounded else -math.inf, get("upper", "inf") if bounded else math.inf,
                     get("velocity", "inf"), get("effort", "inf")])
    return np.array(rows).T


@pytest.mark.parametrize("name", ["ur5", "panda7", "solo12", "double_pendulum_continuous"])
def test_limits_from_urdf_match_the_xml(name):
    path = PANDA if name == "panda7" else URDFS[name]
    robot = jaxskid.load(path, lock=FINGERS) if name == "panda7" else jaxskid.load(path)
    ours = np.array(robot.limits())
    assert ours.shape == (4, robot.n_dof)
    np.testing.assert_array_equal(ours, _xml_limits(path, robot.joint_names))
    for joint in robot.joints:
        assert isinstance(joint.limits, JointLimits)
    if name == "double_pendulum_continuous":  # continuous: no position limits, though velocity and effort are read
        assert np.all(np.isinf(ours[:2])) and np.all(np.isfinite(ours[2:]))


def test_limits_survive_drives_locks_and_are_no_part_of_the_cache_key():
    robot = jaxskid.load(URDFS["ur5"])
    lower, upper, velocity, effort = robot.limits()
    driven, locked = robot.with_drives(), robot.lock({"wrist_3_joint": 0.2})
    np.testing.assert_array_equal(np.array(driven.limits()), np.array(robot.limits()))
    np.testing.assert_array_equal(np.array(locked.limits())[:, :5], np.array(robot.limits())[:, :5])
    assert locked.n_dof == 5
    other = robot._recreate(joints=[replace(j, limits=JointLimits(-1.0, 1.0, 0.5, 2.0)) for j in robot.joints])
    assert np.all(other.limits()[0] == -1.0) and np.all(other.limits()[2] == 0.5)
    assert other.fingerprint() == robot.fingerprint()
    assert module_key(other, ["regressor"]) == module_key(robot, ["regressor"])
    none = robot._recreate(joints=[replace(j, limits=None) for j in robot.joints])
    assert none.fingerprint() == robot.fingerprint()
    np.testing.assert_array_equal(none.limits()[0], np.full(6, -np.inf))
    np.testing.assert_array_equal(none.limits()[2], np.full(6, np.inf))


def test_bad_limits_are_model_errors(tmp_path):
    robot = jaxskid.load(URDFS["ur5"])
    with pytest.raises(ModelError, match=r"joints\[0\]\.limits\.lower: expected lower <= upper"):
        robot._recreate(joints=[replace(robot.joints[0], limits=JointLimits(1.0, -1.0)), *robot.joints[1:]])
    with pytest.raises(ModelError, match=r"joints\[1\]\.limits\.velocity: expected a non-negative"):
        robot._recreate(joints=[robot.joints[0], replace(robot.joints[1], limits=JointLimits(velocity=-1.0)),
                                *robot.joints[2:]])
    with pytest.raises(ModelError, match=r"joints\[0\]\.limits: expected a JointLimits or None, got tuple"):
        robot._recreate(joints=[replace(robot.joints[0], limits=(0, 1)), *robot.joints[1:]])
    text = URDFS["ur5"].read_text().replace('lower="-3.14159265359" upper="3.14159265359"',
                                           'lower="3.14159265359" upper="-3.14159265359"')
    (tmp_path / "ur5.urdf").write_text(text)
    with pytest.raises(ModelError, match=r"ur5\.urdf: joint\[name=elbow_joint\]\.limit\.lower: expected lower <="):
        jaxskid.load(tmp_path / "ur5.urdf")


# ---------------------------------------------------------------------------------------- Fourier series
def test_fourier_derivatives_periodicity_and_bounds():
    traj = _random_fourier(np.random.default_rng(0), n=3, harmonics=4, period=2.5)
    t = np.random.default_rng(1).uniform(-3.0, 7.0, size=(4, 5))
    q, qd, qdd = traj.evaluate(t)
    assert q.shape == qd.shape == qdd.shape == (4, 5, 3)
    position = jax.vmap(lambda s: traj.evaluate(s)[0])
    velocity = jax.vmap(lambda s: traj.evaluate(s)[1])
    flat = jnp.asarray(t.reshape(-1))
    for k, derivative in ((0, qd), (1, qdd)):
        exact = jax.vmap(jax.jacfwd(lambda s, k=k: traj.evaluate(s)[k]))(flat)
        np.testing.assert_allclose(exact, derivative.reshape(-1, 3), rtol=1e-12, atol=1e-12)
    h = 1e-5  # central differences: error O(h^2 * max |d^3 q / dt^3|)
    np.testing.assert_allclose((position(flat + h) - position(flat - h)) / (2 * h), qd.reshape(-1, 3), atol=1e-7)
    np.testing.assert_allclose((velocity(flat + h) - velocity(flat - h)) / (2 * h), qdd.reshape(-1, 3), atol=1e-6)
    for a, b in zip(traj.evaluate(0.0), traj.evaluate(traj.period)):  # starts and ends in the same state
        np.testing.assert_allclose(a, b, atol=1e-12)
    for a, b in zip(traj.evaluate(t), traj.evaluate(t + 3 * traj.period)):
        np.testing.assert_allclose(a, b, atol=1e-11)
    grid = np.linspace(0.0, traj.period, 20001)
    qg, qdg, qddg = (np.asarray(x) for x in traj.evaluate(grid))
    q0 = np.asarray(traj.q0)
    np.testing.assert_allclose(qg[:-1].mean(axis=0), q0, atol=1e-12)  # q0 is the mean over a period
    bound_q, bound_v, bound_a = (np.asarray(x) for x in traj.amplitude_bounds())
    assert np.all(np.abs(qg - q0).max(axis=0) <= bound_q)
    assert np.all(np.abs(qdg).max(axis=0) <= bound_v) and np.all(np.abs(qddg).max(axis=0) <= bound_a)
    one = replace(traj, a=traj.a[:, :1], b=traj.b[:, :1])  # one harmonic: the bounds are the amplitudes
    q1, qd1, qdd1 = (np.asarray(x) for x in one.evaluate(grid))
    np.testing.assert_allclose(np.abs(qd1).max(axis=0), np.hypot(np.asarray(one.a)[:, 0], np.asarray(one.b)[:, 0]),
                               rtol=1e-6)
    np.testing.assert_allclose(np.abs(qd1).max(axis=0), np.asarray(one.amplitude_bounds()[1]), rtol=1e-6)
    with pytest.raises(ShapeError, match="expected q0 \\(n,\\), a and b \\(n, H\\)"):
        replace(traj, b=traj.b[:2]).evaluate(0.0)


# ---------------------------------------------------------------------------------------- gradients
@pytest.fixture(scope="module")
def pendulum():
    """The double pendulum with drives and its lowered regressor and base parameters."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml", drives=True)
    dyn = jaxskid.lower(robot, ["regressor"])
    return robot, dyn, jaxskid.base_parameters(dyn)


def test_regressor_gradient_batched_and_the_stacked_vjp(pendulum):
    """jax.grad through dyn.regressor on a batch against central differences, and the stacked regressor's
    custom VJP (forward-mode state Jacobian) against jax.grad through dyn.regressor."""
    _, dyn, base = pendulum
    rng = np.random.default_rng(3)
    q, qd, qdd = (jnp.asarray(rng.normal(size=(7, 2))) for _ in range(3))
    weights = jnp.asarray(rng.normal(size=dyn.regressor(q, qd, qdd).shape))

    def loss(q, qd, qdd):
        return jnp.sum(weights * dyn.regressor(q, qd, qdd) ** 2)

    grads = jax.grad(loss, argnums=(0, 1, 2))(q, qd, qdd)
    h = 1e-6
    for k, g in enumerate(grads):
        for index in [(0, 0), (3, 1), (6, 0)]:
            args = [q, qd, qdd]
            plus = [x.at[index].add(h) if i == k else x for i, x in enumerate(args)]
            minus = [x.at[index].add(-h) if i == k else x for i, x in enumerate(args)]
            fd = (loss(*plus) - loss(*minus)) / (2 * h)
            assert abs(float(g[index]) - float(fd)) <= 1e-6 * max(1.0, abs(float(fd)))
    stack = _stacked_regressor(dyn.raw("regressor"), np.asarray(base.independent), dyn.param_vector(None))
    cot = jnp.asarray(rng.normal(size=(7, 2, base.n_base)))
    ours = jax.grad(lambda *x: jnp.sum(cot * stack(*x)), argnums=(0, 1, 2))(q, qd, qdd)
    ref = jax.grad(lambda *x: jnp.sum(cot * base.reduce(dyn.regressor(*x))), argnums=(0, 1, 2))(q, qd, qdd)
    for a, b in zip(ours, ref):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10)


# ---------------------------------------------------------------------------------------- design
def _check_within(traj, lower, upper, velocity, acceleration, points=20001):
    q, qd, qdd = (np.asarray(x) for x in traj.evaluate(np.linspace(0.0, traj.period, points)))
    assert np.all(q >= lower) and np.all(q <= upper)
    assert np.all(np.abs(qd) <= velocity) and np.all(np.abs(qdd) <= acceleration)


def _criterion(dyn, base, traj, times, criterion="cond") -> float:
    """cond(W) or log det(W^T W) of the stacked base regressor, with NumPy."""
    w = np.asarray(base.reduce(dyn.regressor(*traj.evaluate(times)))).reshape(-1, base.n_base)
    return float(np.linalg.cond(w)) if criterion == "cond" else float(np.linalg.slogdet(w.T @ w)[1])


PENDULUM_LIMITS = {"lower": -2.0, "upper": 2.5, "velocity": 3.0, "acceleration": 8.0}


@pytest.mark.slow
def test_logdet_design_on_the_pendulum(pendulum):
    robot, dyn, base = pendulum
    out = jaxskid.design_excitation(dyn, 3, 4.0, 12, limits=PENDULUM_LIMITS, starts=3, steps=60, criterion="logdet")
    assert out.history.shape == (3, 61) and out.times.shape == (12,)
    assert out.value == pytest.approx(_criterion(dyn, base, out.trajectory, out.times, "logdet"), rel=1e-9)
    assert out.value > out.initial_best + 1.0  # log det grew by more than a factor e
    assert out.history.max() == pytest.approx(out.value, rel=1e-8)  # the best of every start and step
    _check_within(out.trajectory, -2.0, 2.5, 3.0, 8.0)


@pytest.mark.slow
def test_lbfgs_design_on_the_pendulum(pendulum):
    robot, dyn, base = pendulum
    lbfgs = jaxskid.design_excitation(dyn, 3, 4.0, 12, limits=PENDULUM_LIMITS, starts=2, steps=15,
                                      optimizer=optax.lbfgs(), normalize=True)
    w = np.asarray(base.reduce(dyn.regressor(*lbfgs.trajectory.evaluate(lbfgs.times)))).reshape(-1, base.n_base)
    assert lbfgs.value == pytest.approx(np.linalg.cond(w / np.linalg.norm(w, axis=0)), rel=1e-9)
    assert lbfgs.value < lbfgs.initial_best
    _check_within(lbfgs.trajectory, -2.0, 2.5, 3.0, 8.0)


def test_design_rejects_bad_requests(pendulum):
    robot, dyn, _ = pendulum
    limits = {"velocity": 2.0}
    with pytest.raises(RequestError, match="lowered with the quantity regressor"):
        jaxskid.design_excitation(jaxskid.lower(robot, ["gravity_torques"]), 3, 4.0, 12, limits=limits)
    with pytest.raises(RequestError, match="unknown limit\\(s\\) speed"):
        jaxskid.design_excitation(dyn, 3, 4.0, 12, limits={"speed": 1.0})
    with pytest.raises(ShapeError, match="limits\\['velocity'\\]: expected a number or shape \\(2,\\)"):
        jaxskid.design_excitation(dyn, 3, 4.0, 12, limits={"velocity": [1.0, 2.0, 3.0]})
    with pytest.raises(RequestError, match="a finite position range, velocity or acceleration limit"):
        jaxskid.design_excitation(dyn, 3, 4.0, 12)
    with pytest.raises(RequestError, match="expected lower < upper for every joint"):
        jaxskid.design_excitation(dyn, 3, 4.0, 12, limits={**limits, "lower": 1.0, "upper": [2.0, 0.5]})
    with pytest.raises(RequestError, match="samples \\* n_dof >= "):
        jaxskid.design_excitation(dyn, 3, 4.0, 2, limits=limits)
    with pytest.raises(RequestError, match="criterion one of cond, logdet"):
        jaxskid.design_excitation(dyn, 3, 4.0, 12, limits=limits, criterion="trace")
    with pytest.raises(RequestError, match="positive finite period"):
        jaxskid.design_excitation(dyn, 3, -1.0, 12, limits=limits)
    with pytest.raises(RequestError, match="robot= the Robot of dyn"):
        jaxskid.design_excitation(dyn, 3, 4.0, 12, robot=jaxskid.load(URDFS["ur5"]), limits=limits)
    continuous = jaxskid.load(URDFS["double_pendulum_continuous"], drives=True)  # its URDF says velocity="0"
    with pytest.raises(RequestError, match="a positive velocity limit for every joint"):
        jaxskid.design_excitation(jaxskid.lower(continuous, ["regressor"]), 3, 4.0, 12, robot=continuous)


@pytest.mark.slow
def test_optimised_ur5_trajectory_beats_random_ones_tenfold():
    """UR5 with drives (58 base parameters), 5 harmonics, 10 samples (60 rows): the optimised trajectory's
    cond(W) is at least 10 times below the median of random Fourier trajectories of the same size, scaled into
    the same limits, and it keeps the URDF's position and velocity limits and the acceleration limit."""
    robot = jaxskid.load(URDFS["ur5"], drives=True)
    dyn = jaxskid.lower(robot, ["regressor"])
    base = jaxskid.base_parameters(dyn)
    harmonics, period, samples, acceleration = 5, 10.0, 10, 10.0
    out = jaxskid.design_excitation(dyn, harmonics, period, samples, robot=robot, limits={"acceleration": acceleration},
                                    starts=4, steps=300, base=base, seed=0)
    lower, upper, velocity, _ = robot.limits()
    _check_within(out.trajectory, lower, upper, velocity, acceleration)
    optimised = _criterion(dyn, base, out.trajectory, out.times)
    assert out.value == pytest.approx(optimised, rel=1e-8)
    rng, grid, random = np.random.default_rng(7), np.linspace(0.0, period, 4001), []
    for _ in range(16):  # random coefficients, scaled on a fine grid to touch the tightest limit
        traj = _random_fourier(rng, robot.n_dof, harmonics, period)
        q, qd, qdd = (np.asarray(x) for x in replace(traj, q0=0 * traj.q0).evaluate(grid))
        scale = np.minimum.reduce([velocity / np.abs(qd).max(0), acceleration / np.abs(qdd).max(0),
                                   0.5 * (upper - lower) / np.abs(q).max(0)])
        traj = FourierTrajectory(jnp.asarray(0.5 * (upper + lower)), traj.a * scale[:, None], traj.b * scale[:, None],
                                 period)
        _check_within(traj, lower, upper, velocity * (1 + 1e-9), acceleration * (1 + 1e-9), points=4001)
        random.append(_criterion(dyn, base, traj, out.times))
    assert optimised * 10 <= np.median(random)
    assert out.history.min() == pytest.approx(out.value, rel=1e-8)
    assert out.value < out.initial_best <= out.initial_median
