"""The core pipeline against Pinocchio: M, C qd, C, Q_grav, tau and link poses on real robots and random trees."""

from __future__ import annotations

import numpy as np
import jax
import jax.numpy as jnp
import pinocchio as pin
import pytest

import jaxskid
from helpers import FINGERS, ROBOTS_DIR, URDFS, load, pinocchio_urdf_model, rel_err
from pinref import to_pinocchio
from randrobot import random_robot

QUANTITIES = ["mass_matrix", "coriolis_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics", "forward_kinematics"]
N_STATES = 200
TOL = 1e-9


def pinocchio_model(name: str):
    if name == "panda7":
        return pinocchio_urdf_model(URDFS["panda"], FINGERS)
    return pinocchio_urdf_model(URDFS[name])


def references(model, q, qd, qdd):
    data = model.createData()
    out = {k: [] for k in ("M", "C", "Cqd", "g", "tau", "poses")}
    for a, b, c in zip(q, qd, qdd):
        m = pin.crba(model, data, a)
        out["M"].append(np.triu(m) + np.triu(m, 1).T)
        out["C"].append(pin.computeCoriolisMatrix(model, data, a, b).copy())
        g = pin.computeGeneralizedGravity(model, data, a).copy()
        out["g"].append(g)
        out["Cqd"].append(pin.nonLinearEffects(model, data, a, b) - g)
        out["tau"].append(pin.rnea(model, data, a, b, c).copy())
        pin.framesForwardKinematics(model, data, a)
        out["poses"].append({f.name: data.oMf[k].homogeneous.copy() for k, f in enumerate(model.frames)})
    return out


@pytest.fixture(scope="module", params=["panda", "panda7", "ur5", "solo12", "double_pendulum"])
def real_robot(request):
    robot = load(request.param)
    model = pinocchio_model(request.param)
    dyn = jaxskid.lower(robot, QUANTITIES)
    return request.param, robot, model, dyn


def test_joint_order_matches_pinocchio(real_robot):
    _, robot, model, _ = real_robot
    assert robot.joint_names == tuple(model.names[1:])


def test_dynamics_match_pinocchio(real_robot):
    name, robot, model, dyn = real_robot
    rng = np.random.default_rng(7)
    n = robot.n_dof
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)
    q = rng.uniform(lo, hi, size=(N_STATES, n))
    qd, qdd = rng.normal(size=(2, N_STATES, n)) * 2.0
    ref = references(model, q, qd, qdd)
    got = {
        "M": dyn.mass_matrix(q),
        "Cqd": dyn.coriolis_torques(q, qd),
        "g": dyn.gravity_torques(q),
        "tau": dyn.inverse_dynamics(q, qd, qdd),
    }
    if name != "panda":  # the full C of the 9-DOF arm (81 entries) is the slowest compile; panda7 covers it
        got["C"] = dyn.coriolis_matrix(q, qd)
    for key, value in got.items():
        errs = [rel_err(value[k], ref[key][k]) for k in range(N_STATES) if np.linalg.norm(ref[key][k]) > 1e-12]
        assert max(errs) <= TOL, f"{name} {key}: relative error {max(errs):.3g}"
    poses = dyn.forward_kinematics(q)
    assert set(robot.link_names) <= set(poses)
    checked = 0
    for frame, values in poses.items():
        if frame not in ref["poses"][0]:
            continue  # an end-effector frame of our own
        for k in range(N_STATES):
            assert np.abs(np.asarray(values[k]) - ref["poses"][k][frame]).max() <= TOL, (name, frame)
        checked += 1
    urdf_links = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
    assert urdf_links <= set(poses), f"links missing from forward_kinematics: {urdf_links - set(poses)}"
    assert checked >= len(urdf_links)


# the 9-DOF Panda is left out here: panda7 covers the arm, and jvp of its M is the slowest compile in the suite
@pytest.mark.parametrize("real_robot", ["panda7", "ur5", "solo12", "double_pendulum"], indirect=True)
def test_mass_matrix_spd_and_skew_property(real_robot):
    name, robot, _, dyn = real_robot
    rng = np.random.default_rng(3)
    q, qd = rng.uniform(-np.pi, np.pi, size=(2, 64, robot.n_dof))
    m = np.asarray(dyn.mass_matrix(q))
    np.testing.assert_allclose(m, np.swapaxes(m, 1, 2), atol=1e-12)
    assert np.linalg.eigvalsh(m).min() > 0
    mdot = jax.vmap(lambda a, b: jax.jvp(lambda x: dyn.mass_matrix(x), (a,), (b,))[1])(jnp.asarray(q), jnp.asarray(qd))
    s = np.asarray(mdot) - 2 * np.asarray(dyn.coriolis_matrix(q, qd))
    assert np.abs(s + np.swapaxes(s, 1, 2)).max() <= 1e-9 * max(1.0, np.abs(s).max())


@pytest.mark.parametrize("seed", range(4))
def test_random_trees_match_pinocchio(seed):
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(1, 7))
    robot = random_robot(rng, n, tree=seed % 2 == 0)
    model, frames = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    dyn = jaxskid.lower(robot, QUANTITIES)
    q, qd, qdd = rng.normal(size=(3, 20, n))
    m = dyn.mass_matrix(q)
    c = dyn.coriolis_matrix(q, qd)
    tau = dyn.inverse_dynamics(q, qd, qdd)
    g = dyn.gravity_torques(q)
    poses = dyn.forward_kinematics(q)
    for k in range(20):
        mp = pin.crba(model, data, q[k])
        assert rel_err(m[k], np.triu(mp) + np.triu(mp, 1).T) <= TOL
        assert rel_err(c[k], pin.computeCoriolisMatrix(model, data, q[k], qd[k])) <= TOL
        assert rel_err(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k])) <= TOL
        assert rel_err(g[k], pin.computeGeneralizedGravity(model, data, q[k])) <= TOL
        pin.framesForwardKinematics(model, data, q[k])
        for f in frames:
            assert np.abs(np.asarray(poses[f][k]) - data.oMf[model.getFrameId(f)].homogeneous).max() <= TOL


@pytest.fixture(scope="module")
def panda_tau():
    robot = load("panda7")
    return robot, jaxskid.lower(robot, ["inverse_dynamics"])


def test_grad_wrt_inertial_parameters_matches_finite_differences(panda_tau):
    robot, dyn = panda_tau
    assert len(dyn.parameters) == 10 * robot.n_dof
    rng = np.random.default_rng(0)
    q, qd, qdd = (jnp.asarray(rng.normal(size=(32, 7))) for _ in range(3))
    params = {k: jnp.asarray(v) for k, v in robot.default_params().items()}
    target = dyn.inverse_dynamics(q, qd, qdd, params) + jnp.asarray(rng.normal(size=(32, 7)))

    def loss(p):
        return jnp.sum((dyn.inverse_dynamics(q, qd, qdd, p) - target) ** 2)

    grad = jax.jit(jax.grad(loss))(params)  # one program: called eagerly, JAX compiles its two halves apart (2x slower)
    assert all(np.isfinite(float(v)) for v in grad.values())
    loss = jax.jit(loss)  # the differences: one compiled program, called twice per parameter
    for name in dyn.parameters:
        h = 1e-6 * max(1.0, abs(float(params[name])))
        up = dict(params, **{name: params[name] + h})
        dn = dict(params, **{name: params[name] - h})
        fd = (float(loss(up)) - float(loss(dn))) / (2 * h)
        assert abs(float(grad[name]) - fd) <= 1e-6 * max(1.0, abs(fd)), name


def test_vmap_over_1024_states_matches_unbatched(panda_tau):
    robot, dyn = panda_tau
    rng = np.random.default_rng(1)
    q, qd, qdd = (jnp.asarray(rng.normal(size=(1024, 7))) for _ in range(3))
    p = dyn.param_vector()
    batched = jax.vmap(dyn.inverse_dynamics, in_axes=(0, 0, 0, None))(q, qd, qdd, p)
    single = np.stack([np.asarray(dyn.inverse_dynamics(q[k], qd[k], qdd[k], p)) for k in range(0, 1024, 97)])
    np.testing.assert_allclose(np.asarray(batched)[::97], single, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dyn.inverse_dynamics(q, qd, qdd)), np.asarray(batched), rtol=1e-13, atol=1e-12)


def test_float32_and_float64(panda_tau):
    robot, dyn = panda_tau
    rng = np.random.default_rng(2)
    q, qd, qdd = rng.normal(size=(3, 64, 7))
    t64 = dyn.inverse_dynamics(q, qd, qdd)
    t32 = dyn.inverse_dynamics(q.astype(np.float32), qd.astype(np.float32), qdd.astype(np.float32))
    assert t64.dtype == jnp.float64 and t32.dtype == jnp.float32
    assert rel_err(t32, t64) < 1e-5


def test_jvp_through_generated_functions(panda_tau):
    robot, dyn = panda_tau
    rng = np.random.default_rng(4)
    q, qd, qdd, dq = (jnp.asarray(rng.normal(size=7)) for _ in range(4))
    _, tangent = jax.jvp(lambda x: dyn.inverse_dynamics(x, qd, qdd), (q,), (dq,))
    h = 1e-6
    fd = (dyn.inverse_dynamics(q + h * dq, qd, qdd) - dyn.inverse_dynamics(q - h * dq, qd, qdd)) / (2 * h)
    assert rel_err(tangent, fd) < 1e-7


def test_requests_are_checked(panda_tau):
    robot, dyn = panda_tau
    with pytest.raises(jaxskid.RequestError, match="coriolis_matrix.*was not lowered"):
        dyn.coriolis_matrix(np.zeros(7), np.zeros(7))
    with pytest.raises(jaxskid.RequestError, match="unknown quantity 'mass_matrx'"):
        jaxskid.lower(robot, ["mass_matrx"])
    with pytest.raises(jaxskid.ShapeError, match=r"q: expected shape \(7,\)"):
        dyn.inverse_dynamics(np.zeros(6), np.zeros(7), np.zeros(7))
    with pytest.raises(jaxskid.RequestError, match="unknown parameter 'panda_link1_mass'.*'panda_link1_m'"):
        dyn.inverse_dynamics(np.zeros(7), np.zeros(7), np.zeros(7), {"panda_link1_mass": 1.0})


def test_symbolic_subset_and_assignments():
    robot = jaxskid.load(URDFS["double_pendulum"])
    keep = [p for p in robot.parameters if p.endswith("_m")]
    dyn = jaxskid.lower(robot, ["inverse_dynamics"], symbolic=keep)
    assert dyn.parameters == tuple(keep)
    full = jaxskid.lower(robot, ["inverse_dynamics"])
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.normal(size=(3, 2))
    np.testing.assert_allclose(dyn.inverse_dynamics(q, qd, qdd), full.inverse_dynamics(q, qd, qdd), rtol=1e-12)
    heavier = dict(robot.default_params(), **{keep[0]: 2 * robot.default_params()[keep[0]]})
    np.testing.assert_allclose(
        dyn.inverse_dynamics(q, qd, qdd, {k: heavier[k] for k in keep}),
        full.inverse_dynamics(q, qd, qdd, heavier),
        rtol=1e-12,
    )


def test_generated_functions_inside_a_users_jit(panda_tau):
    robot, dyn = panda_tau
    rng = np.random.default_rng(6)
    q, qd, qdd = (jnp.asarray(rng.normal(size=(16, 7))) for _ in range(3))
    inside = jax.jit(lambda a, b, c, p: dyn.inverse_dynamics(a, b, c, p) * 2.0)(q, qd, qdd, dyn.param_vector())
    np.testing.assert_allclose(np.asarray(inside), 2.0 * np.asarray(dyn.inverse_dynamics(q, qd, qdd)), rtol=1e-13, atol=1e-13)


def test_jit_helper_at_top_level_and_inside_a_callers_trace():
    """jaxskid.jit compiles with jaxskid's compiler options from Python, and is a plain jit inside another
    trace (JAX accepts compiler options only on a top-level jit)."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml")
    dyn = jaxskid.lower(robot, ["mass_matrix", "gravity_torques"])
    q = jnp.asarray([[0.3, -0.7], [1.1, 0.2]])

    @jaxskid.jit
    def energy_like(q):
        return jnp.sum(dyn.mass_matrix(q)) + jnp.sum(dyn.gravity_torques(q))

    ref = float(jnp.sum(dyn.mass_matrix(q)) + jnp.sum(dyn.gravity_torques(q)))
    assert float(energy_like(q)) == pytest.approx(ref, rel=1e-14)
    outer = jax.jit(lambda q: energy_like(q) * 2.0)  # nested: must not pass compiler options again
    assert float(outer(q)) == pytest.approx(2 * ref, rel=1e-14)
    grad = jax.grad(energy_like)(q)
    eps = 1e-6
    num = (energy_like(q.at[0, 1].add(eps)) - energy_like(q.at[0, 1].add(-eps))) / (2 * eps)
    assert float(grad[0, 1]) == pytest.approx(float(num), rel=1e-7)
    scaled = jaxskid.jit(lambda q, k: dyn.gravity_torques(q) * k, static_argnames=("k",))
    np.testing.assert_allclose(np.asarray(scaled(q, k=3)), 3 * np.asarray(dyn.gravity_torques(q)), rtol=1e-14)


def test_the_wrench_is_keyword_only(pendulum):
    """``inverse_dynamics(q, qd, qdd, params=None, *, wrench=None)``: the wrench by keyword adds
    ``external_torques``; passed where ``params`` goes, the error says to pass it by keyword."""
    robot, _ = pendulum
    dyn = jaxskid.lower(robot, ["inverse_dynamics", "external_torques", "mass_matrix"])
    rng = np.random.default_rng(11)
    q, qd, qdd = rng.normal(size=(3, 2))
    w = rng.normal(size=(len(dyn.end_effectors), 6))
    p = dyn.param_vector()
    expected = np.asarray(dyn.inverse_dynamics(q, qd, qdd)) + np.asarray(dyn.external_torques(q, w))
    np.testing.assert_allclose(np.asarray(dyn.inverse_dynamics(q, qd, qdd, wrench=w)), expected, rtol=1e-13)
    np.testing.assert_allclose(np.asarray(dyn.inverse_dynamics(q, qd, qdd, p, wrench=w)), expected, rtol=1e-13)
    np.testing.assert_allclose(np.asarray(dyn.inverse_dynamics(q, qd, qdd, params=p, wrench=w)), expected, rtol=1e-13)
    with pytest.raises(jaxskid.ShapeError, match=r"shape of the end-effector wrenches.*by keyword.*"
                                                  r"inverse_dynamics\(q, qd, qdd, params=None, \*, wrench=None, out=None\)"):
        dyn.inverse_dynamics(q, qd, qdd, w)
    with pytest.raises(jaxskid.ShapeError, match=r"expected inverse_dynamics\(q, qd, qdd, params=None, \*, "
                                                  r"wrench=None, out=None\), got 5 positional"):
        dyn.inverse_dynamics(q, qd, qdd, p, w)
    with pytest.raises(jaxskid.ShapeError, match="mass_matrix takes no wrench"):
        dyn.mass_matrix(q, wrench=w)
    with pytest.raises(TypeError):
        dyn.forward_dynamics(q, qd, qdd, p, w)
