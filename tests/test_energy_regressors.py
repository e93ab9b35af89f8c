"""The energy regressors (kinetic and potential energy, momentum, friction power, linear in the standard
parameters) against Pinocchio and closed forms, the power balance along an RK4 rollout, and identification
from the energy balance (jaxskid.energy_balance) on simulated motions."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import FINGERS, PANDA, ROBOTS_DIR, pinocchio_urdf_model, rel_err
from pinref import to_pinocchio

import jaxskid
from jaxskid import IdentificationError, RequestError, ShapeError
from jaxskid.testing._reference import evaluate

ENERGY = ["kinetic_energy_regressor", "potential_energy_regressor", "momentum_regressor", "friction_power_regressor"]
TOL = 1e-10
EPS = 0.1  # friction smoothing of the simulated robot: tanh(qd / EPS)


def _robot(name: str, drives: bool) -> jaxskid.Robot:
    if name == "panda7":
        return jaxskid.load(PANDA, lock=FINGERS, drives=drives)
    return jaxskid.load(ROBOTS_DIR / f"{name}.yaml", drives=drives)


def _with_drives(robot: jaxskid.Robot, seed: int) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The default parameters with random drive values (if the robot has drives), and (Ia, fv, fc, fo)."""
    rng = np.random.default_rng(seed)
    n = robot.n_dof
    ia, fv, fc, fo = rng.uniform(0.01, 0.05, n), rng.uniform(0.05, 0.2, n), rng.uniform(0.05, 0.3, n), rng.normal(0, 0.2, n)
    params = robot.default_params()
    if robot.driven:
        for i, name in enumerate(robot.joint_names):
            params.update({f"{name}_Ia": ia[i], f"{name}_fv": fv[i], f"{name}_fc": fc[i], f"{name}_fo": fo[i]})
    return params, ia, fv, fc, fo


def _rows(robot: jaxskid.Robot, params: dict, q, qd, lowered: bool) -> dict:
    """The rows of ENERGY at the states: lowered to JAX, or the derived programs evaluated with NumPy
    (jaxskid.testing's interpreter, without compiling)."""
    if lowered:
        dyn = jaxskid.lower(robot, ENERGY)
        return {k: np.asarray(getattr(dyn, k)(*((q,) if k.startswith("potential") else (q, qd)), params)) for k in ENERGY}
    p = [params[k] for k in robot.parameters]
    return evaluate(jaxskid.derive(robot, ENERGY), ENERGY, {"q": q, "qd": qd}, p)


CASES = [
    pytest.param("panda7", True, True, marks=pytest.mark.slow, id="panda7-drives-lowered"),
    pytest.param("panda7", False, False, id="panda7-derived"),
    pytest.param("arm_3dof", True, True, id="arm_3dof-drives-lowered"),
    pytest.param("arm_3dof", False, False, id="arm_3dof-derived"),
]


@pytest.mark.parametrize("name, drives, lowered", CASES)
def test_energy_regressors_match_pinocchio(name, drives, lowered):
    """row @ pi: K against pin.computeKineticEnergy and 1/2 qd^T M qd (pin.crba), U against
    pin.computePotentialEnergy, the momentum against crba @ qd, all with ``model.armature`` = Ia; the friction
    power against qd . (fv qd + fc sign(qd) + fo). Shapes: p = 10 n + 4 n_driven columns."""
    robot = _robot(name, drives)
    params, ia, fv, fc, fo = _with_drives(robot, 1)
    pi = jaxskid.standard_params(robot, params)
    model = pinocchio_urdf_model(PANDA, FINGERS) if name == "panda7" else to_pinocchio(robot, params)[0]
    data = model.createData()
    rng = np.random.default_rng(2)
    q, qd = rng.uniform(-np.pi, np.pi, (5, robot.n_dof)), rng.normal(size=(5, robot.n_dof))
    rigid = [pin.computeKineticEnergy(model, data, q[k], qd[k]) for k in range(5)]
    rotor = 0.5 * np.sum(ia * qd**2, axis=1) if drives else np.zeros(5)
    if drives:
        model.armature = ia
        data = model.createData()
    rows = _rows(robot, params, q, qd, lowered)
    assert len(pi) == 10 * robot.n_dof + (4 * robot.n_dof if drives else 0)
    assert rows["momentum_regressor"].shape == (5, robot.n_dof, len(pi))
    kinetic, potential, momentum, friction = (rows[k] @ pi for k in ENERGY)
    for k in range(5):
        m = pin.crba(model, data, q[k])
        m = np.triu(m) + np.triu(m, 1).T
        energy = rigid[k] + rotor[k]
        assert abs(kinetic[k] - energy) <= TOL * energy
        assert abs(kinetic[k] - 0.5 * qd[k] @ m @ qd[k]) <= TOL * energy
        if name == "panda7":
            # With model.armature set, Pinocchio 4.1's computeKineticEnergy adds the rotors' 1/2 Ia qd^2 for
            # the axis-aligned revolute joints of the Panda's URDF, as jaxskid does; it leaves it out for
            # JointModelRevoluteUnaligned (the joints of pinref.to_pinocchio), while its crba counts it: there
            # the references are the rigid energy plus 1/2 Ia qd^2 and 1/2 qd^T crba qd.
            assert abs(kinetic[k] - pin.computeKineticEnergy(model, data, q[k], qd[k])) <= TOL * energy
        u = pin.computePotentialEnergy(model, data, q[k])
        assert abs(potential[k] - u) <= TOL * max(1.0, abs(u))
        assert rel_err(momentum[k], m @ qd[k]) <= TOL
    power = np.sum(qd * (fv * qd + fc * np.sign(qd) + fo), axis=1) if drives else np.zeros(5)
    assert rel_err(friction, power) <= TOL


def test_lagrange_route_has_the_energy_regressors():
    """Under Options(route="lagrange") the rows reproduce that route's own K (pseudo-inertia form), U and
    momentum dK/dqd."""
    robot = _robot("arm_3dof", True)
    params, *_ = _with_drives(robot, 3)
    pi = jaxskid.standard_params(robot, params)
    energies = ["kinetic_energy", "potential_energy", "momentum"]
    eqs = jaxskid.derive(robot, [*energies, *ENERGY], options=jaxskid.Options(route="lagrange"))
    rng = np.random.default_rng(4)
    q, qd = rng.uniform(-np.pi, np.pi, (6, 3)), rng.normal(size=(6, 3))
    names = [*energies, *(e + "_regressor" for e in energies)]
    out = evaluate(eqs, names, {"q": q, "qd": qd}, [params[k] for k in robot.parameters])
    for e in energies:
        assert rel_err(out[e + "_regressor"] @ pi, out[e]) <= TOL, e


# ---------------------------------------------------------------------------------------------- simulated data
@pytest.fixture(scope="module")
def simulated():
    """arm_3dof with drives (armature, viscous, smoothed Coulomb, offset) under multisine torques with
    damping, RK4 at 0.25 ms for 6 s: (dyn, params, pi, t, q, qd, tau, (Ia, fv, fc, fo))."""
    robot = _robot("arm_3dof", True)
    params, *drive = _with_drives(robot, 5)
    names = ["mass_matrix", "inverse_dynamics", "regressor", *ENERGY]
    dyn = jaxskid.lower(robot, names, options=jaxskid.Options(friction_smoothing=EPS))
    rng = np.random.default_rng(6)
    amp, freq, phase = (jnp.asarray(rng.uniform(lo, hi, (3, 3))) for lo, hi in ((1, 3), (0.5, 2.5), (0, 6)))

    def policy(t, x):
        return jnp.sum(amp * jnp.sin(2 * jnp.pi * freq * t + phase), axis=-1) - x[3:] - 2.0 * x[:3]

    dt, steps = 2.5e-4, 24000
    traj = jaxskid.rollout(dyn, jnp.zeros(6), policy, dt, steps, params=params)
    tau = np.asarray(jax.vmap(policy)(traj.t, traj.x))  # the torques at the samples, as a sensor reads them
    pi = jaxskid.standard_params(robot, params)
    return dyn, params, pi, np.asarray(traj.t), np.asarray(traj.q), np.asarray(traj.qd), tau, drive


def test_power_balance_along_a_rollout(simulated):
    """d/dt (K + U) by finite differences of (y_K + y_U) pi equals qd^T (tau - fv qd - fc tanh(qd/eps) - fo):
    to round-off with a 5-point stencil, and with the central difference's error shrinking 4x per halving
    of its spacing (order 2)."""
    dyn, params, pi, t, q, qd, tau, (_, fv, fc, fo) = simulated
    dt = t[1] - t[0]
    q, qd, tau = (x[_first_4s(t)] for x in (q, qd, tau))  # the batch shape energy_balance evaluates too
    h = (dyn.kinetic_energy_regressor(q, qd, params) + dyn.potential_energy_regressor(q, params)) @ pi
    friction = fv * qd + fc * np.tanh(qd / EPS) + fo
    power = np.sum(qd * (tau - friction), axis=1)
    scale = np.abs(power).max()
    five = (-h[4:] + 8 * h[3:-1] - 8 * h[1:-3] + h[:-4]) / (12 * dt)
    assert np.abs(five - power[2:-2]).max() <= 1e-7 * scale
    errors = [np.sqrt(np.mean(((h[2 * s:] - h[:-2 * s]) / (2 * s * dt) - power[s:-s]) ** 2)) for s in (1, 2)]
    assert errors[0] <= 1e-5 * scale and 3.8 <= errors[1] / errors[0] <= 4.2, errors
    # the friction power row is the power of the friction law the rollout integrated
    assert rel_err(dyn.friction_power_regressor(q, qd, params) @ pi, np.sum(qd * friction, axis=1)) <= TOL


def _first_4s(t, every: int = 1) -> slice:
    """The samples of the first 4 s (identification data; the last 2 s validate), every ``every``-th."""
    return slice(0, int(np.searchsorted(t, 4.0)) + 1, every)


def _identified(dyn, params, t, q, qd, tau, every: int, seconds: float = 0.05):
    """The base parameters (of the torque model) from the energy balance of every ``every``-th sample of the
    first 4 s, windows of ``seconds``: (base, estimate)."""
    keep = _first_4s(t, every)
    window = int(round(seconds / (t[every] - t[0]))) + 1
    balance = jaxskid.energy_balance(dyn, t[keep], q[keep], qd[keep], tau[keep], params, window=window)
    base = jaxskid.base_parameters(dyn, params)
    return base, jaxskid.identify(base.reduce(balance.y), balance.work)


def _validation_error(dyn, params, base, theta, t, q, qd, tau) -> float:
    """Relative error of the predicted torques Y_b(q, qd, qdd) theta against the applied ones at 100 samples
    of the last 2 s. Only this check uses accelerations: central differences of qd (O(dt^2), ~1e-7 here)."""
    k = np.linspace(int(np.searchsorted(t, 4.0)) + 1, len(t) - 2, 100).astype(int)
    qdd = (qd[k + 1] - qd[k - 1]) / (t[k + 1] - t[k - 1])[:, None]
    predicted = base.reduce(dyn.regressor(q[k], qd[k], qdd, params)) @ theta
    return rel_err(predicted, tau[k])


def test_energy_balance_identifies_the_base_parameters(simulated):
    """Noise-free samples: the estimate of the torque model's base parameters converges to the truth (K pi) at
    the trapezoid rule's order 2 in the sample spacing, and predicts the torques of the held-out 2 s."""
    dyn, params, pi, t, q, qd, tau, _ = simulated
    errors = []
    for every in (1, 2):
        base, estimate = _identified(dyn, params, t, q, qd, tau, every)
        truth = base.project(pi)
        errors.append(np.abs(estimate.params - truth).max() / np.abs(truth).max())
        if every == 1:
            assert _validation_error(dyn, params, base, estimate.params, t, q, qd, tau) <= 2e-5
    assert errors[0] <= 1e-4, errors
    assert 3.5 <= errors[1] / errors[0] <= 4.5, errors


def test_energy_balance_with_measurement_noise(simulated):
    """Gaussian noise on q (1e-4 rad), qd (1e-3 rad/s) and tau (1e-2 N m): the held-out torques within 2 %,
    and the covariance of the estimate covers its error."""
    dyn, params, pi, t, q, qd, tau, _ = simulated
    rng = np.random.default_rng(7)
    noisy = (q + rng.normal(0, 1e-4, q.shape), qd + rng.normal(0, 1e-3, qd.shape), tau + rng.normal(0, 1e-2, tau.shape))
    base, estimate = _identified(dyn, params, t, *noisy, every=4, seconds=0.1)
    assert _validation_error(dyn, params, base, estimate.params, t, q, qd, tau) <= 0.02
    z = (estimate.params - base.project(pi)) / np.sqrt(np.diag(estimate.covariance))
    assert np.sqrt(np.mean(z**2)) <= 3.0, z


def test_energy_balance_has_the_torque_models_base_parameters(simulated):
    """The differenced energy rows of one rich motion have exactly the torque model's base parameters; the
    energy rows at single states have more independent columns (constants no difference sees)."""
    dyn, params, pi, t, q, qd, tau, _ = simulated
    keep = _first_4s(t, 4)
    balance = jaxskid.energy_balance(dyn, t[keep], q[keep], qd[keep], tau[keep], params, window=51)
    torque = jaxskid.base_parameters(dyn, params)
    energy = jaxskid.base_parameters(balance.y)
    assert energy.n_base == torque.n_base == 25
    # the same null space: either base reduces the rows without changing their product with any parameters
    x = np.random.default_rng(8).normal(size=len(pi))
    assert rel_err(balance.y[:, 0] @ x, energy.reduce(balance.y[:, 0]) @ energy.project(x)) <= 1e-8
    assert rel_err(balance.y[:, 0] @ x, torque.reduce(balance.y[:, 0]) @ torque.project(x)) <= 1e-8
    with pytest.raises(IdentificationError, match="depend"):
        jaxskid.identify(balance.y, balance.work)
    # y_K + y_U at random states: the differences span 9 fewer directions than the torque model (fv, fc, fo of 3
    # drives enter only through the friction power), the rows themselves one more (the waist turns about the
    # vertical through the origin: its first moment's U column is the constant g)
    q1, qd1, _ = jaxskid.apps.identification._identification.random_states(3, 100, 10)
    single = np.asarray(dyn.kinetic_energy_regressor(q1, qd1, params) + dyn.potential_energy_regressor(q1, params))
    differences = jaxskid.base_parameters(single[1:] - single[:-1]).n_base
    assert differences == torque.n_base - 9
    assert jaxskid.base_parameters(single).n_base == differences + 1


def test_energy_balance_without_drives():
    """A robot without drives needs no friction_power_regressor: along q(t) = a sin(w t + b), with tau from
    inverse dynamics (Newton-Euler), each window's rows give its work to the trapezoid rule's accuracy."""
    robot = _robot("hopping_leg", False)
    dyn = jaxskid.lower(robot, ["inverse_dynamics", "kinetic_energy_regressor", "potential_energy_regressor"])
    n = robot.n_dof
    rng = np.random.default_rng(9)
    a, w, b = rng.uniform(0.5, 1.5, n), rng.uniform(1, 4, n), rng.uniform(0, 6, n)
    t = np.linspace(0, 2, 4001)[:, None]
    q, qd, qdd = a * np.sin(w * t + b), a * w * np.cos(w * t + b), -a * w**2 * np.sin(w * t + b)
    tau = np.asarray(dyn.inverse_dynamics(q, qd, qdd))
    pi = jaxskid.standard_params(robot)
    balance = jaxskid.energy_balance(dyn, t[:, 0], q, qd, tau, window=101)
    assert balance.y.shape == (40, 1, 10 * n) and balance.work.shape == (40, 1)
    assert rel_err(balance.y[:, 0] @ pi, balance.work[:, 0]) <= 1e-5


def test_energy_balance_bad_inputs(simulated):
    dyn, params, _, t, q, qd, tau, _ = simulated
    with pytest.raises(RequestError, match="window"):
        jaxskid.energy_balance(dyn, t[:10], q[:10], qd[:10], tau[:10], params, window=1)
    with pytest.raises(RequestError, match="window"):
        jaxskid.energy_balance(dyn, t[:10], q[:10], qd[:10], tau[:10], params, window=11)
    with pytest.raises(ShapeError, match=r"qd of shape \(10, 3\)"):
        jaxskid.energy_balance(dyn, t[:10], q[:10], qd[:9], tau[:10], params, window=5)
    with pytest.raises(ShapeError, match="increase"):
        jaxskid.energy_balance(dyn, t[9::-1], q[:10], qd[:10], tau[:10], params, window=5)
    lowered = jaxskid.lower(_robot("arm_3dof", True), ENERGY[:2])
    with pytest.raises(RequestError, match="friction_power_regressor"):
        jaxskid.energy_balance(lowered, t[:10], q[:10], qd[:10], tau[:10], params, window=5)


# ---------------------------------------------------------------------------------------------- momentum balance
def _momentum_identified(dyn, params, t, q, qd, tau, every: int, seconds: float = 0.05):
    keep = _first_4s(t, every)
    window = int(round(seconds / (t[every] - t[0]))) + 1
    balance = jaxskid.momentum_balance(dyn, t[keep], q[keep], qd[keep], tau[keep], params, window=window)
    base = jaxskid.base_parameters(dyn, params)
    return base, jaxskid.identify(base.reduce(balance.y), balance.work), balance


def test_momentum_balance_identifies_the_base_parameters(simulated):
    """Noise-free samples: n equations per window, the estimate converging at the trapezoid rule's order 2,
    the held-out torques predicted; and the rows' identity itself: y pi equals the impulse to O(dt^2)."""
    dyn, params, pi, t, q, qd, tau, _ = simulated
    errors = []
    for every in (1, 2):
        base, estimate, balance = _momentum_identified(dyn, params, t, q, qd, tau, every)
        assert balance.y.shape[1:] == (3, len(pi)) and balance.work.shape == balance.y.shape[:2]
        truth = base.project(pi)
        errors.append(np.abs(estimate.params - truth).max() / np.abs(truth).max())
        if every == 1:
            assert _validation_error(dyn, params, base, estimate.params, t, q, qd, tau) <= 2e-5
            assert rel_err(balance.y @ pi, balance.work) <= 1e-6
    assert errors[0] <= 1e-4, errors
    assert 3.5 <= errors[1] / errors[0] <= 4.5, errors


def test_momentum_balance_beats_the_energy_balance_under_noise(simulated):
    """The same noisy samples as the energy test: the momentum rows' held-out torques within 0.2 %, several
    times closer than the energy rows' (one equation per window against n)."""
    dyn, params, pi, t, q, qd, tau, _ = simulated
    rng = np.random.default_rng(7)
    noisy = (q + rng.normal(0, 1e-4, q.shape), qd + rng.normal(0, 1e-3, qd.shape), tau + rng.normal(0, 1e-2, tau.shape))
    base, momentum, _ = _momentum_identified(dyn, params, t, *noisy, every=4, seconds=0.1)
    _, energy = _identified(dyn, params, t, *noisy, every=4, seconds=0.1)
    error_m = _validation_error(dyn, params, base, momentum.params, t, q, qd, tau)
    error_e = _validation_error(dyn, params, base, energy.params, t, q, qd, tau)
    assert error_m <= 0.002 and error_m <= error_e / 3, (error_m, error_e)


def test_momentum_balance_bad_inputs(simulated):
    dyn, params, _, t, q, qd, tau, _ = simulated
    with pytest.raises(ShapeError, match=r"momentum_balance: expected tau of shape \(10, 3\)"):
        jaxskid.momentum_balance(dyn, t[:10], q[:10], qd[:10], tau[:9], params, window=5)
    lowered = jaxskid.lower(_robot("arm_3dof", True), ENERGY[:2])
    with pytest.raises(RequestError, match="momentum_regressor, regressor"):
        jaxskid.momentum_balance(lowered, t[:10], q[:10], qd[:10], tau[:10], params, window=5)
