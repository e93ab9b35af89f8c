"""Joint drives: armature against Pinocchio's ``model.armature``, friction and offset against their formula,
the regressor's drive columns against finite differences, the URDF ``<dynamics>`` defaults, the YAML
``drives`` key, and robots without drives left exactly as they were."""

from __future__ import annotations

import jax
import numpy as np
import pinocchio as pin
import pytest
from helpers import FINGERS, PANDA, ROBOTS_DIR, URDFS, pinocchio_urdf_model, rel_err

import jaxskid
from jaxskid._api import module_key
from jaxskid.apps import self_check
from jaxskid import ModelError

TOL = 1e-9
QUANTITIES = ["mass_matrix", "inverse_dynamics", "forward_dynamics", "regressor", "kinetic_energy", "momentum"]


def _states(n: int, samples: int, seed: int):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-np.pi, np.pi, (samples, n)), rng.normal(size=(samples, n)), rng.normal(size=(samples, n)))


def _drive_values(robot: jaxskid.Robot, seed: int) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Random drive parameters as a params dict, and (Ia, fv, fc, fo) as arrays in the order of q."""
    rng = np.random.default_rng(seed)
    n = robot.n_dof
    ia, fv, fc, fo = rng.uniform(0.01, 0.5, n), rng.uniform(0, 0.3, n), rng.uniform(0, 0.3, n), rng.normal(size=n)
    params = {}
    for i, name in enumerate(robot.joint_names):
        params.update({f"{name}_Ia": ia[i], f"{name}_fv": fv[i], f"{name}_fc": fc[i], f"{name}_fo": fo[i]})
    return params, ia, fv, fc, fo


@pytest.fixture(scope="module", params=["panda7", "solo12"])
def driven(request):
    """(robot with drives, Pinocchio model, lowered dynamics)."""
    if request.param == "panda7":
        robot, model = jaxskid.load(PANDA, lock=FINGERS, drives=True), pinocchio_urdf_model(PANDA, FINGERS)
    else:
        path = URDFS["solo12"]
        robot, model = jaxskid.load(path, drives=True), pinocchio_urdf_model(path)
    return robot, model, jaxskid.lower(robot, QUANTITIES)


@pytest.mark.slow
def test_armature_matches_pinocchio(driven):
    """M + diag(Ia), tau + Ia qdd, forward dynamics and the kinetic energy against pin.crba, pin.rnea,
    pin.aba and pin.computeKineticEnergy with ``model.armature`` (friction and offset zero); p = M qd."""
    robot, model, dyn = driven
    params, ia, *_ = _drive_values(robot, 1)
    params = {k: (v if k.endswith("_Ia") else 0.0) for k, v in params.items()}
    model.armature = ia
    data = model.createData()
    q, qd, qdd = _states(robot.n_dof, 5, 2)
    m, tau = dyn.mass_matrix(q, params), dyn.inverse_dynamics(q, qd, qdd, params)
    energy, momentum = dyn.kinetic_energy(q, qd, params), dyn.momentum(q, qd, params)
    for k in range(len(q)):
        mp = pin.crba(model, data, q[k])
        assert rel_err(m[k], np.triu(mp) + np.triu(mp, 1).T) <= TOL
        assert rel_err(momentum[k], m[k] @ qd[k]) <= TOL
        assert abs(energy[k] - pin.computeKineticEnergy(model, data, q[k], qd[k])) <= TOL * abs(energy[k])
        tau_ref = pin.rnea(model, data, q[k], qd[k], qdd[k]).copy()
        assert rel_err(tau[k], tau_ref) <= TOL
        qdd_ref = pin.aba(model, data, q[k], qd[k], tau_ref)
        assert rel_err(dyn.forward_dynamics(q[k], qd[k], tau_ref, params), qdd_ref) <= TOL


@pytest.mark.slow
def test_friction_and_offset_add_to_pinocchio(driven):
    """tau = rnea (with armature) + fv qd + fc sign(qd) + fo; forward dynamics inverts it."""
    robot, model, dyn = driven
    params, ia, fv, fc, fo = _drive_values(robot, 3)
    model.armature = ia
    data = model.createData()
    q, qd, qdd = _states(robot.n_dof, 5, 4)
    tau = dyn.inverse_dynamics(q, qd, qdd, params)
    for k in range(len(q)):
        ref = pin.rnea(model, data, q[k], qd[k], qdd[k]) + fv * qd[k] + fc * np.sign(qd[k]) + fo
        assert rel_err(tau[k], ref) <= TOL
        assert rel_err(dyn.forward_dynamics(q[k], qd[k], ref, params), qdd[k]) <= 1e-8


@pytest.mark.slow
def test_regressor_drive_columns(driven):
    """Y @ standard_params == tau, and each drive column is d tau / d(drive parameter) (central differences;
    tau is affine in them, so the difference is exact up to round-off)."""
    robot, _, dyn = driven
    params, *_ = _drive_values(robot, 5)
    q, qd, qdd = _states(robot.n_dof, 3, 6)
    y = np.asarray(dyn.regressor(q, qd, qdd, params))
    pi = jaxskid.standard_params(robot, params)
    names = jaxskid.standard_parameter_names(robot)
    assert y.shape == (3, robot.n_dof, 10 * robot.n_dof + 4 * robot.n_dof) == (3, robot.n_dof, len(pi))
    tau = np.asarray(dyn.inverse_dynamics(q, qd, qdd, params))
    assert rel_err(y @ pi, tau) <= TOL
    h = 1e-3
    for c in range(10 * robot.n_dof, len(names)):
        up = dyn.inverse_dynamics(q, qd, qdd, {**params, names[c]: params[names[c]] + h})
        down = dyn.inverse_dynamics(q, qd, qdd, {**params, names[c]: params[names[c]] - h})
        np.testing.assert_allclose(y[..., c], (np.asarray(up) - np.asarray(down)) / (2 * h), atol=1e-8)


@pytest.mark.slow
def test_vjp_and_time_derivatives_with_drives():
    """The symbolic reverse sweep (inverse_dynamics_vjp) agrees with jax.grad of inverse_dynamics (d sign/dqd
    = 0), and d/dt tau adds Ia q3d + fv qdd (finite differences along a polynomial motion)."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml", drives=True)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "inverse_dynamics_vjp", "inverse_dynamics_dot",
                                "inverse_dynamics_ddot"])
    params, *_ = _drive_values(robot, 7)
    p = dyn.param_vector({**robot.default_params(), **params})
    q, qd, qdd = (x[0] for x in _states(robot.n_dof, 1, 8))
    w = np.array([0.7, -1.3])
    raw = dyn.raw("inverse_dynamics")
    grads = jax.grad(lambda q_, qd_, p_: w @ raw(q_, qd_, qdd, p_), argnums=(0, 1, 2))(q, qd, p)
    np.testing.assert_allclose(dyn.raw("inverse_dynamics_vjp")(q, qd, qdd, w, p), np.concatenate(grads),
                               rtol=1e-10, atol=1e-12)
    q3, q4 = np.array([0.4, -0.9]), np.array([1.1, 0.3])

    def tau(t):
        return np.asarray(raw(q + qd * t + qdd * t**2 / 2 + q3 * t**3 / 6 + q4 * t**4 / 24,
                              qd + qdd * t + q3 * t**2 / 2 + q4 * t**3 / 6, qdd + q3 * t + q4 * t**2 / 2, p))

    h = 1e-4
    first = dyn.raw("inverse_dynamics_dot")(q, qd, qdd, q3, p)
    second = dyn.raw("inverse_dynamics_ddot")(q, qd, qdd, q3, q4, p)
    np.testing.assert_allclose(first, (tau(h) - tau(-h)) / (2 * h), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(second, (tau(h) - 2 * tau(0) + tau(-h)) / h**2, rtol=1e-5, atol=1e-5)
    # forward dynamics from M and the bias (numeric L D L^T, no closed-form quantity) inverts tau
    np.testing.assert_allclose(dyn.forward_dynamics(q, qd, tau(0), p), qdd, rtol=1e-10)


def test_identification_with_drives():
    """Base parameters of the wider regressor (the first joint's armature merges with its body's inertia
    about the axis), least squares recovers them, and LogCholesky passes the drive parameters through."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml", drives=True)
    dyn = jaxskid.lower(robot, ["regressor", "inverse_dynamics"])
    params, *_ = _drive_values(robot, 9)
    names = jaxskid.standard_parameter_names(robot)
    base = jaxskid.base_parameters(dyn, params, names=names)
    assert "upper_link_Iyy + 0.25 lower_link_m + q1_Ia" in base.describe()
    assert {"q1_fv", "q1_fc", "q1_fo", "q2_Ia", "q2_fv", "q2_fc", "q2_fo"} <= set(base.describe())
    q, qd, qdd = _states(robot.n_dof, 40, 10)
    y, tau = np.asarray(dyn.regressor(q, qd, qdd, params)), np.asarray(dyn.inverse_dynamics(q, qd, qdd, params))
    est = jaxskid.identify(base.reduce(y), tau)
    mixed = jaxskid.mixed_regressor(dyn, q[0], qd[0], qd[0], qdd[0], params)  # v = qd: the ordinary regressor
    np.testing.assert_allclose(mixed, y[0], atol=1e-12)
    np.testing.assert_allclose(est.params, base.project(jaxskid.standard_params(robot, params)), atol=1e-9)
    theta = np.random.default_rng(11).normal(size=len(names)) * 0.3
    lc = jaxskid.LogCholesky(drives=len(robot.driven))
    pi = np.asarray(lc.standard(jax.numpy.asarray(theta)))
    np.testing.assert_allclose(pi[20:], theta[20:])
    np.testing.assert_allclose(np.asarray(lc.init(jax.numpy.asarray(pi))), theta, atol=1e-12)
    assert jaxskid.physically_consistent(pi, drives=2).shape == (2,)


def test_runtime_knows_the_drives():
    """Forward dynamics from C qd + Q_grav would drop friction: refused; the self-check's Newton-Euler identity
    holds with friction and offset (on the part of tau even in qd)."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml", drives=True)
    params, *_ = _drive_values(robot, 12)
    robot = robot.with_defaults(params)
    partial = jaxskid.lower(robot, ["mass_matrix", "coriolis_torques", "gravity_torques"])
    assert partial.driven == ("q1", "q2")
    with pytest.raises(jaxskid.RequestError, match="drives"):
        partial.forward_dynamics(np.zeros(2), np.zeros(2), np.zeros(2))
    dyn = jaxskid.lower(robot, ["mass_matrix", "coriolis_matrix", "gravity_torques", "inverse_dynamics"])
    checks = self_check(dyn)
    assert all(c.ok for c in checks) and any("even in qd" in c.name for c in checks)
    assert jaxskid.lower(jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml"), ["mass_matrix"]).driven == ()


def test_without_drives_nothing_changes():
    plain = jaxskid.load(PANDA, lock=FINGERS)
    again = jaxskid.load(PANDA, lock=FINGERS, drives=False)
    assert again.parameters == plain.parameters and again.fingerprint() == plain.fingerprint()
    assert jaxskid.standard_parameter_names(plain) == jaxskid.standard_parameter_names(again)
    assert all(j.drive is None for j in again.joints)
    names = ["mass_matrix", "inverse_dynamics"]
    assert module_key(again, names) == module_key(plain, names)
    driven = jaxskid.load(PANDA, lock=FINGERS, drives=True)
    assert driven.fingerprint() != plain.fingerprint()
    assert driven.parameters[: len(plain.parameters)] != () and set(plain.parameters) < set(driven.parameters)


URDF = """<robot name="r">
  <link name="base"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="0.25" friction="0.5"/></joint>
  <joint name="j2" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""


def test_urdf_dynamics_are_the_friction_defaults(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text(URDF)
    robot = jaxskid.load(path, drives=True)
    defaults = robot.default_params()
    assert {k: defaults[k] for k in ("j1_Ia", "j1_fv", "j1_fc", "j1_fo")} == {
        "j1_Ia": 0.0, "j1_fv": 0.25, "j1_fc": 0.5, "j1_fo": 0.0}
    assert {k: defaults[k] for k in ("j2_Ia", "j2_fv", "j2_fc", "j2_fo")} == dict.fromkeys(
        ("j2_Ia", "j2_fv", "j2_fc", "j2_fo"), 0.0)
    assert jaxskid.load(path).parameters == tuple(p for p in robot.parameters if not p.startswith(("j1_", "j2_")))
    locked = jaxskid.load(path, drives=True, lock={"j1": 0.3})
    assert "j1_Ia" not in locked.parameters and "j2_Ia" in locked.parameters
    path.write_text(URDF.replace('damping="0.25"', 'damping="-0.25"'))
    with pytest.raises(ModelError, match=r"r\.urdf: joint\[name=j1\]\.dynamics\.viscous: expected a non-negative"):
        jaxskid.load(path, drives=True)


PLAIN = """
representation: body_fixed
gravity: [0, 0, -9.81]
joint_screw_coord: [[0, 0, 1, 0, 0, 0], [0, 0, 1, 0, 0, 0]]
body_ref_config: [{translation: [0, 0, 0]}, {translation: [1, 0, 0]}]
mass_inertia: [{mass: 1, inertia: 0.1}, {mass: m2, inertia: 1, com: [0.5, 0, 0]}]
q: [q1, q2]
assignments: {m2: 2, Jr: 0.001}
"""
DRIVES = """drives:
  - {gear_ratio: 10, rotor_inertia: Jr, viscous: 0.2, coulomb: 0.1, offset: -0.05}
"""


def _yaml(tmp_path, second: str = "  - null", extra: str = ""):
    path = tmp_path / "r.yaml"
    path.write_text(PLAIN + DRIVES + second + "\n" + extra)
    return path


def test_yaml_drives(tmp_path):
    robot = jaxskid.load(_yaml(tmp_path))
    assert robot.driven == (0,) and "Jr" in robot.parameters
    assert jaxskid.standard_parameter_names(robot)[-4:] == ("q1_Ia", "q1_fv", "q1_fc", "q1_fo")
    np.testing.assert_allclose(jaxskid.standard_params(robot)[-4:], [100 * 0.001, 0.2, 0.1, -0.05])
    np.testing.assert_allclose(jaxskid.standard_params(robot, {"Jr": 0.002})[-4], 0.2)
    both = jaxskid.load(_yaml(tmp_path), drives=True)
    assert both.driven == (0, 1) and both.joints[0].drive == robot.joints[0].drive
    assert both.parameters[-4:] == ("q2_Ia", "q2_fv", "q2_fc", "q2_fo")
    names = ["mass_matrix", "inverse_dynamics"]
    dyn = jaxskid.lower(robot, names)
    (tmp_path / "plain.yaml").write_text(PLAIN)
    plain = jaxskid.lower(jaxskid.load(tmp_path / "plain.yaml"), names)
    q, qd, qdd = np.array([0.3, -0.2]), np.array([0.5, -1.0]), np.array([0.1, 0.7])
    extra = dyn.inverse_dynamics(q, qd, qdd) - plain.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(extra, [0.1 * 0.1 + 0.2 * 0.5 + 0.1 - 0.05, 0.0], atol=1e-14)
    np.testing.assert_allclose(dyn.mass_matrix(q) - plain.mass_matrix(q), np.diag([0.1, 0.0]), atol=1e-14)


@pytest.mark.parametrize("second, extra, match", [
    ("  - {armature: -1}", "", r"r\.yaml: drives\[1\]\.armature: expected a non-negative armature"),
    ("  - {viscous: 0.1, stiction: 1}", "", r"r\.yaml: drives\[1\]: unknown key 'stiction'"),
    ("  - {armature: 1, gear_ratio: 2, rotor_inertia: 1}", "", r"r\.yaml: drives\[1\]: expected either armature"),
    ("  - {gear_ratio: 2, rotor_inertia: -1}", "", r"r\.yaml: drives\[1\]\.rotor_inertia: expected a non-negative"),
    ("  - {coulomb: -0.1}", "", r"r\.yaml: drives\[1\]\.coulomb: expected a non-negative coulomb"),
    ("  - {viscous: 0.1}", "lock: {q2: 0.1}", r"r\.yaml: drives\[1\]: joint 'q2' is locked"),
    ("", "", r"r\.yaml: drives: expected a list of 2 entries"),
])
def test_yaml_drive_errors(tmp_path, second, extra, match):
    with pytest.raises(ModelError, match=match):
        jaxskid.load(_yaml(tmp_path, second, extra))


def test_drive_on_a_fixed_joint():
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml")
    fixed = jaxskid.Joint("f", "fixed", 1, robot.joints[1].origin, None, robot.joints[1].inertia, "tip",
                          jaxskid.Drive(armature=0.1))
    with pytest.raises(ModelError, match=r"joints\[2\]\.drive: a fixed joint has no drive"):
        jaxskid.Robot.create("r", [*robot.joints, fixed])


def test_lagrange_route_with_drives():
    """The Euler-Lagrange route takes the rotors' energy into K and friction and offset as non-conservative
    forces: the same M, tau, K and momentum as the screw route."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml").with_drives()
    names = ["mass_matrix", "inverse_dynamics", "kinetic_energy", "momentum", "coriolis_torques"]
    lagrange = jaxskid.lower(robot, names, options=jaxskid.Options(route="lagrange"))
    screw = jaxskid.lower(robot, names)
    rng = np.random.default_rng(4)
    p = screw.param_vector({f"{j}_{k}": v for j in robot.joint_names
                            for k, v in zip(("Ia", "fv", "fc", "fo"), rng.uniform(0.1, 1.0, 4))})
    q, qd, qdd = rng.uniform(-2, 2, size=(3, 8, robot.n_dof))
    for name, args in (("mass_matrix", (q,)), ("inverse_dynamics", (q, qd, qdd)), ("kinetic_energy", (q, qd)),
                       ("momentum", (q, qd)), ("coriolis_torques", (q, qd))):
        a, b = (np.asarray(getattr(dyn, name)(*args, p)) for dyn in (lagrange, screw))
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12, err_msg=name)


def test_smooth_coulomb_friction():
    """Options(friction_smoothing=eps): fc tanh(qd / eps) in tau, its regressor column and time derivative, and
    a gradient in qd of fc / eps sech^2 (qd / eps); against the formula and finite differences."""
    robot = jaxskid.load(ROBOTS_DIR / "double_pendulum.yaml").with_drives()
    eps = 0.05
    names = ["inverse_dynamics", "regressor", "inverse_dynamics_dot"]
    smooth = jaxskid.lower(robot, names, options=jaxskid.Options(friction_smoothing=eps))
    exact = jaxskid.lower(robot, names)
    fc = np.array([0.7, 0.3])
    p = smooth.param_vector({f"{j}_fc": v for j, v in zip(robot.joint_names, fc)})
    rng = np.random.default_rng(8)
    q, qd, qdd, q3d = rng.uniform(-0.2, 0.2, size=(4, robot.n_dof))
    friction = np.asarray(smooth.inverse_dynamics(q, qd, qdd, p)) - np.asarray(exact.inverse_dynamics(q, qd, qdd, p))
    np.testing.assert_allclose(friction, fc * (np.tanh(qd / eps) - np.sign(qd)), rtol=1e-12, atol=1e-12)
    y = np.asarray(smooth.regressor(q, qd, qdd, p))
    np.testing.assert_allclose(y @ jaxskid.standard_params(robot, p), smooth.inverse_dynamics(q, qd, qdd, p),
                               rtol=1e-12, atol=1e-12)
    grad = jax.jacfwd(lambda v: smooth.inverse_dynamics(q, v, qdd, p))(jax.numpy.asarray(qd))
    np.testing.assert_allclose(np.diag(np.asarray(grad)) - np.diag(np.asarray(
        jax.jacfwd(lambda v: exact.inverse_dynamics(q, v, qdd, p))(jax.numpy.asarray(qd)))),
        fc / eps / np.cosh(qd / eps) ** 2, rtol=1e-10)
    h = 1e-6  # d tau / dt along q(t) = q + qd t + qdd t^2/2 + q3d t^3/6, central differences
    def tau_at(t):
        return np.asarray(smooth.inverse_dynamics(q + qd * t + qdd * t**2 / 2 + q3d * t**3 / 6,
                                                  qd + qdd * t + q3d * t**2 / 2, qdd + q3d * t, p))
    np.testing.assert_allclose(smooth.inverse_dynamics_dot(q, qd, qdd, q3d, p), (tau_at(h) - tau_at(-h)) / (2 * h),
                               rtol=1e-6, atol=1e-7)
    with pytest.raises(jaxskid.RequestError, match="friction_smoothing"):
        jaxskid.Options(friction_smoothing=-1.0)


def test_regressor_with_drives_keeps_its_native_kernel(driven):
    """The drive columns (qdd, qd, sign(qd), 1) have a native vector form: the regressor stays a native kernel,
    and it agrees with the JAX form and with tau = Y pi at velocities of both signs and exactly zero."""
    robot, _, dyn = driven
    assert dyn.native_target("regressor") is not None, "a C compiler is required (apt-get install gcc)"
    params, *_ = _drive_values(robot, 7)
    q, qd, qdd = _states(robot.n_dof, 6, 8)
    qd[:, ::3] = 0.0  # sign(0) = 0: no Coulomb friction at rest
    y = np.asarray(dyn.regressor(q, qd, qdd, params))
    p = dyn.param_vector(params)
    jax_form = np.asarray(jax.vmap(dyn.generated("regressor", False), (0, 0, 0, None))(q, qd, qdd, p))
    np.testing.assert_allclose(y, jax_form, rtol=1e-12, atol=1e-12 * np.abs(jax_form).max())
    pi = jaxskid.standard_params(robot, params)
    assert rel_err(y @ pi, np.asarray(dyn.inverse_dynamics(q, qd, qdd, params))) <= TOL


def test_report_names_each_quantitys_form(driven):
    """One report of how each quantity runs: the matrix-valued ones and the rollouts' backward steps as native
    kernels, with drives too; vectors in their JAX form, saying why."""
    _, _, dyn = driven
    report = dyn.report()
    assert set(dyn.quantities) <= set(report)
    for name in ("mass_matrix", "regressor", "forward_dynamics", "fd_vjp"):
        assert report[name] == "native kernel", (name, report[name])
    assert report["inverse_dynamics"].startswith("JAX form (a vector")
