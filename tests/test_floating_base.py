"""Floating base (a free-flyer root), against independent references.

* Pinocchio's ``buildModelFromUrdf(path, JointModelFreeFlyer())`` of solo12 and go2 (and the G1, slow):
  ``rnea``, ``crba``, ``computeCoriolisMatrix``, ``nonLinearEffects``, ``computeGeneralizedGravity``, ``aba``,
  a foot's placement and its ``getFrameJacobian`` in ``LOCAL`` and ``LOCAL_WORLD_ALIGNED``. Pinocchio's base
  velocity is ``(v, omega)`` and its base force ``(f, n)``, both in the base frame; jaxskid puts the angular
  part first, so the six base rows and columns are permuted (``P``) before comparing. Its ``q`` is jaxskid's.
* Central differences (Richardson-extrapolated) along a trajectory whose base pose is integrated from its
  twist, ``dp/dt = R v``, ``dquat/dt = quat * (omega, 0) / 2`` (RK4, fine steps): the first and second time
  derivatives of M and tau.
* The regressor: ``Y pi = tau``, and its six base rows alone, stacked over random states, identify the base
  parameters (Ayusawa, Venture & Nakamura, IJRR 33(3), 2014): the estimate is the true parameters mapped to
  the base parameters, and it reproduces the base wrench of fresh states.

Most checks evaluate the derived equations with NumPy (``jaxskid.testing._reference.evaluate``, nothing
compiled); the solo12 checks call the lowered JAX functions. Errors are normwise relative.
"""

from __future__ import annotations

import functools
import math
import time

import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from jaxskid import codegen
from jaxskid.testing._reference import evaluate
from helpers import ERD, PANDA, URDFS, rel_err

TOL = 1e-9
ROBOTS = {  # URDF, a foot frame
    "solo12": (URDFS["solo12"], "FL_FOOT"),
    "go2": (ERD / "go2_description/urdf/go2.urdf", "FL_foot"),
    "g1": (ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf", "left_ankle_roll_link"),
}
PINOCCHIO = ["inverse_dynamics", "mass_matrix", "coriolis_matrix", "coriolis_torques", "gravity_torques",
             "forward_dynamics", "forward_kinematics", "body_jacobian", "hybrid_jacobian"]
LOWERED = ["inverse_dynamics", "mass_matrix", "forward_dynamics", "forward_kinematics", "hybrid_jacobian"]


def permutation(nv: int) -> np.ndarray:
    """Pinocchio's velocity index of each of jaxskid's: ``(omega, v, joints)`` from ``(v, omega, joints)``."""
    return np.r_[3:6, 0:3, 6:nv]


def random_states(robot, samples: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``q`` (unit quaternions), ``qd``, ``qdd``, ``q3d`` and ``tau`` at random, ``(samples, nq or nv)``."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(samples, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = np.concatenate([rng.normal(size=(samples, 3)), quat,
                        rng.uniform(-np.pi, np.pi, size=(samples, robot.n_dof))], axis=1)
    out = {"q": q}
    for k in ("qd", "qdd", "q3d", "tau"):
        out[k] = rng.normal(size=(samples, robot.nv))
    return out


@functools.cache
def pinocchio_model(name: str):
    path, _ = ROBOTS[name]
    return pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())


@functools.cache
def robot(name: str) -> jaxskid.Robot:
    path, foot = ROBOTS[name]
    return jaxskid.load(path, floating_base=True, end_effectors=[foot])


def params(eqs) -> np.ndarray:
    defaults = eqs.robot.default_params()
    return np.array([defaults[k] for k in eqs.parameters])


def pinocchio_reference(name: str, q, v, a, tau) -> dict[str, np.ndarray]:
    """Pinocchio's quantities at one state, in jaxskid's order (``v``, ``a``, ``tau`` in jaxskid's order)."""
    model = pinocchio_model(name)
    data = model.createData()
    _, foot = ROBOTS[name]
    fid = model.getFrameId(foot)
    p = permutation(model.nv)
    vp, ap, taup = (np.empty(model.nv) for _ in range(3))
    vp[p], ap[p], taup[p] = v, a, tau
    both = np.ix_(p, p)
    m = pin.crba(model, data, q)
    m = np.triu(m) + np.triu(m, 1).T
    gravity = pin.computeGeneralizedGravity(model, data, q)
    out = {
        "inverse_dynamics": pin.rnea(model, data, q, vp, ap)[p],
        "mass_matrix": m[both],
        "coriolis_matrix": pin.computeCoriolisMatrix(model, data, q, vp)[both],
        "coriolis_torques": (pin.nonLinearEffects(model, data, q, vp) - gravity)[p],
        "gravity_torques": gravity[p],
        "forward_dynamics": pin.aba(model, data, q, vp, taup)[p],
    }
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    pin.computeJointJacobians(model, data, q)
    rows = np.r_[3:6, 0:3]  # (omega, v) from Pinocchio's (v, omega)
    out["foot_pose"] = data.oMf[fid].homogeneous
    out["body_jacobian"] = pin.getFrameJacobian(model, data, fid, pin.LOCAL)[np.ix_(rows, p)]
    out["hybrid_jacobian"] = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[np.ix_(rows, p)]
    out["base_pose"] = data.oMi[1].homogeneous
    return out


def check_against_pinocchio(name: str, ours: dict, states: dict, index: int) -> None:
    """``ours``: jaxskid's quantities at state ``index`` of ``states``, against Pinocchio's."""
    s = {k: v[index] for k, v in states.items()}
    ref = pinocchio_reference(name, s["q"], s["qd"], s["qdd"], s["tau"])
    r = robot(name)
    got = {k: v for k, v in ours.items() if k not in ("forward_kinematics", "body_jacobian", "hybrid_jacobian")}
    got.update({k: ours[k][0] for k in ("body_jacobian", "hybrid_jacobian") if k in ours})
    if "forward_kinematics" in ours:
        poses = ours["forward_kinematics"]
        got["foot_pose"] = poses[r.frame_names.index(r.end_effectors[0])]
        got["base_pose"] = poses[r.frame_names.index(r.base)]
    for key, value in got.items():
        err = rel_err(value, ref[key])
        assert err < TOL, f"{name} {key} state {index}: relative error {err:.3g}"


# ---------------------------------------------------------------------------------------------- the model
def test_layouts_and_sizes():
    r = robot("solo12")
    assert r.floating_base and r.nq == 19 and r.nv == 18 and r.n_dof == 12
    assert r.joint_names == tuple(pinocchio_model("solo12").names[2:])
    fixed = jaxskid.load(ROBOTS["solo12"][0])
    assert not fixed.floating_base and fixed.nq == fixed.nv == 12
    assert fixed.fingerprint() != r.fingerprint()
    names = jaxskid.standard_parameter_names(r)
    assert len(names) == len(jaxskid.standard_params(r)) == 130 and names[0] == f"{r.base}_m"
    # the root link keeps its inertia: Pinocchio's free-flyer body
    ref = pinocchio_model("solo12").inertias[1].toDynamicParameters()
    np.testing.assert_allclose(jaxskid.standard_params(r)[:10], ref, rtol=1e-12, atol=1e-15)


def test_yaml_and_urdf_keep_the_floating_base(tmp_path):
    r = robot("solo12")
    jaxskid.write_description(r, tmp_path / "solo.yaml")
    again = jaxskid.load(tmp_path / "solo.yaml")
    assert again.floating_base and again.fingerprint() == r.fingerprint()
    jaxskid.write_urdf(r, tmp_path / "solo.urdf")
    from_urdf = jaxskid.load(tmp_path / "solo.urdf", floating_base=True, end_effectors=r.end_effectors)
    np.testing.assert_allclose(jaxskid.standard_params(from_urdf), jaxskid.standard_params(r), rtol=1e-12, atol=1e-15)


def test_bad_floating_base_values(tmp_path):
    path = ROBOTS["solo12"][0]
    for value in ("yes", 1, None):
        with pytest.raises(jaxskid.ModelError, match=r"floating_base: expected true or false"):
            jaxskid.load(path, floating_base=value)
    yaml = tmp_path / "solo.yaml"
    jaxskid.write_description(robot("solo12"), yaml)
    yaml.write_text(yaml.read_text().replace("floating_base: true", "floating_base: false"))
    with pytest.raises(jaxskid.ModelError, match=r"solo\.yaml: base_inertia: a fixed base has no inertia"):
        jaxskid.load(yaml)
    with pytest.raises(jaxskid.RequestError, match="floating base"):
        jaxskid.derive(robot("solo12"), ["mass_matrix"], options=jaxskid.Options(route="lagrange"))


# ---------------------------------------------------------------------------------------------- Pinocchio
@pytest.fixture(scope="module")
def solo():
    """solo12 with a floating base, lowered: (robot, dyn)."""
    r = robot("solo12")
    return r, jaxskid.lower(r, LOWERED)


@pytest.mark.slow
def test_lowered_functions_match_pinocchio(solo):
    r, dyn = solo
    s = random_states(r, 1)
    args = {k: v[0] for k, v in s.items()}
    ours = {name: np.asarray(getattr(dyn, name)(*(args[a] for a in dyn.signature(name)[0])))
            for name in LOWERED if name != "forward_kinematics"}
    poses = dyn.forward_kinematics(args["q"])  # a dict (jit returns it with its keys sorted)
    ours["forward_kinematics"] = np.stack([np.asarray(poses[f]) for f in r.frame_names])
    check_against_pinocchio("solo12", ours, s, 0)


@pytest.mark.parametrize("name", ["solo12", "go2", pytest.param("g1", marks=pytest.mark.slow)])
def test_matches_pinocchio(name):
    """Every quantity of ``PINOCCHIO`` (the derived programs, evaluated with NumPy) against Pinocchio at three
    random states; for the G1 (29 joints, nv 35) the derivation is most of the test."""
    r = robot(name)
    eqs = jaxskid.derive(r, PINOCCHIO)
    s = random_states(r, 3, seed=1)
    out = evaluate(eqs, PINOCCHIO, s, params(eqs))
    for k in range(3):
        check_against_pinocchio(name, {q: out[q][k] for q in PINOCCHIO}, s, k)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["g1", "go2"])
def test_humanoid_and_quadruped_match_pinocchio(name):
    """The G1 humanoid (29 joints): tau and M; the go2 (12 joints) also forward dynamics solved on M's
    sparsity from them (against aba; the same solve on the G1 takes over a minute to compile); prints the
    derive and lower time."""
    r = robot(name)
    names = ["inverse_dynamics", "mass_matrix"]
    t0 = time.perf_counter()
    dyn = jaxskid.lower(r, names, cache=False)
    s = random_states(r, 2, seed=2)
    got = {name: np.asarray(getattr(dyn, name)(*(s[a][0] for a in dyn.signature(name)[0]))) for name in names}
    print(f"{r.name} floating base: derive, lower and first call of tau and M {time.perf_counter() - t0:.1f} s")
    if name == "go2":
        got["forward_dynamics"] = np.asarray(dyn.forward_dynamics(s["q"][0], s["qd"][0], s["tau"][0]))
    ref = pinocchio_reference(name, s["q"][0], s["qd"][0], s["qdd"][0], s["tau"][0])
    for name in got:
        assert rel_err(got[name], ref[name]) < TOL, name


def test_mimic_joints_on_a_floating_base():
    """The Panda on a free-flyer with its fingers coupled, against Pinocchio's ``buildModelFromUrdf(path,
    JointModelFreeFlyer(), mimic=True)``: tau, and M column by column from rnea."""
    r = jaxskid.load(PANDA, floating_base=True, mimic=True)
    model = pin.buildModelFromUrdf(str(PANDA), pin.JointModelFreeFlyer(), mimic=True)
    data = model.createData()
    assert (r.nq, r.nv) == (model.nq, model.nv)
    names = ["inverse_dynamics", "mass_matrix"]
    eqs = jaxskid.derive(r, names)
    s = random_states(r, 2, seed=12)
    out = evaluate(eqs, names, s, params(eqs))
    p = permutation(model.nv)
    for k in range(2):
        q, v, a = s["q"][k], np.empty(model.nv), np.empty(model.nv)
        v[p], a[p] = s["qd"][k], s["qdd"][k]
        zero = np.zeros(model.nv)
        m = np.column_stack([pin.rnea(model, data, q, zero, e) - pin.rnea(model, data, q, zero, zero)
                             for e in np.eye(model.nv)])
        assert rel_err(out["inverse_dynamics"][k], pin.rnea(model, data, q, v, a)[p]) < TOL
        assert rel_err(out["mass_matrix"][k], m[np.ix_(p, p)]) < TOL


def test_numpy_code_matches_pinocchio(tmp_path):
    """The generated NumPy module (codegen target ``python``) takes q of 7 + n and velocities of 6 + n."""
    r = robot("solo12")
    eqs = jaxskid.derive(r, ["inverse_dynamics", "mass_matrix"])
    codegen.generate(eqs, "python", tmp_path)
    ns: dict = {}
    path = tmp_path / f"{codegen.stem(r.name)}_numpy.py"
    exec(compile(path.read_text(), str(path), "exec"), ns)
    s = random_states(r, 1, seed=3)
    ref = pinocchio_reference("solo12", s["q"][0], s["qd"][0], s["qdd"][0], s["tau"][0])
    assert rel_err(ns["inverse_dynamics"](s["q"][0], s["qd"][0], s["qdd"][0]), ref["inverse_dynamics"]) < TOL
    assert rel_err(ns["mass_matrix"](s["q"][0]), ref["mass_matrix"]) < TOL


def test_a_quaternion_that_is_not_unit_norm_is_normalised(solo):
    r, dyn = solo
    s = random_states(r, 1, seed=4)
    q, qd, qdd = s["q"][0], s["qd"][0], s["qdd"][0]
    scaled = q.copy()
    scaled[3:7] *= 2.5
    np.testing.assert_allclose(dyn.inverse_dynamics(scaled, qd, qdd), dyn.inverse_dynamics(q, qd, qdd), rtol=1e-12,
                               atol=1e-12)
    pose = dyn.forward_kinematics(scaled)[r.base]
    np.testing.assert_allclose(pose, dyn.forward_kinematics(q)[r.base], atol=1e-14)


def test_runtime_shapes(solo):
    r, dyn = solo
    assert (dyn.nq, dyn.nv, dyn.floating_base) == (19, 18, True)
    s = random_states(r, 3, seed=5)
    assert dyn.mass_matrix(s["q"]).shape == (3, 18, 18)  # a batch
    assert dyn.hybrid_jacobian(s["q"][0]).shape == (1, 6, 18)
    with pytest.raises(jaxskid.ShapeError):
        dyn.mass_matrix(s["q"][0, :18])
    with pytest.raises(jaxskid.ShapeError):
        dyn.inverse_dynamics(s["q"][0], s["qd"][0, :12], s["qdd"][0, :12])


def test_inverse_dynamics_vjp():
    """The vector-Jacobian product of inverse dynamics (``nq + nv + n_params`` entries: q with the base
    position and quaternion, qd with the base twist, then the parameters), which differentiates forward
    dynamics, against a central difference of tau along a random direction of (q, qd, p)."""
    r = robot("solo12")
    names = ["inverse_dynamics", "inverse_dynamics_vjp"]
    eqs = jaxskid.derive(r, names)
    p = params(eqs)
    s = random_states(r, 2, seed=6)
    state = {k: v[:1] for k, v in s.items()}
    state["cotangent"] = s["tau"][1:]
    vjp = evaluate(eqs, ["inverse_dynamics_vjp"], state, p)["inverse_dynamics_vjp"][0]
    assert vjp.shape == (r.nq + r.nv + len(p),)
    dq, dqd = s["q"][1], s["qd"][1]
    dp = np.random.default_rng(7).normal(size=len(p)) * p
    h = 1e-6

    def tau(sign):
        moved = {"q": state["q"] + sign * h * dq, "qd": state["qd"] + sign * h * dqd, "qdd": state["qdd"]}
        return evaluate(eqs, ["inverse_dynamics"], moved, p + sign * h * dp)["inverse_dynamics"][0]

    fd = np.dot(state["cotangent"][0], tau(1) - tau(-1)) / (2 * h)
    assert abs(np.dot(vjp, np.r_[dq, dqd, dp]) - fd) < 1e-6 * max(1.0, abs(fd))


# ---------------------------------------------------------------------------------------------- regressor
def test_regressor_times_standard_parameters_is_tau():
    r = robot("solo12")
    names = ["regressor", "inverse_dynamics"]
    eqs = jaxskid.derive(r, names)
    out = evaluate(eqs, names, random_states(r, 4, seed=8), params(eqs))
    assert out["regressor"].shape == (4, 18, 130)
    assert rel_err(out["regressor"] @ jaxskid.standard_params(r), out["inverse_dynamics"]) < 1e-10


def test_base_rows_identify_the_base_parameters():
    """The six base rows alone (no joint torques) identify the base parameters: as many as the whole
    regressor's, the estimate equals the true parameters mapped to them, and it predicts fresh states."""
    r = robot("solo12")
    names = ["regressor", "inverse_dynamics"]
    eqs = jaxskid.derive(r, names)
    p = params(eqs)
    train, fresh = random_states(r, 40, seed=9), random_states(r, 10, seed=10)
    out = evaluate(eqs, names, train, p)
    y_base, tau_base = out["regressor"][:, :6], out["inverse_dynamics"][:, :6]
    base = jaxskid.base_parameters(y_base, names=jaxskid.standard_parameter_names(r))
    assert base.n_base == jaxskid.base_parameters(out["regressor"]).n_base
    estimate = jaxskid.identify(base.reduce(y_base), tau_base)
    pi = jaxskid.standard_params(r)
    assert rel_err(estimate.params, base.project(pi)) < 1e-8
    new = evaluate(eqs, names, fresh, p)
    assert rel_err(base.reduce(new["regressor"][:, :6]) @ estimate.params, new["inverse_dynamics"][:, :6]) < 1e-8


# ---------------------------------------------------------------------------------------------- time derivatives
def _quaternion_rate(quat, omega):
    """``dquat/dt = quat * (omega, 0) / 2`` for ``quat = (x, y, z, w)`` and the body angular velocity."""
    u, w = quat[:3], quat[3]
    return 0.5 * np.r_[w * omega + np.cross(u, omega), -np.dot(u, omega)]


def _rotation(quat):
    x, y, z, w = quat / np.linalg.norm(quat)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def trajectory(s: dict, t: float, steps: int = 40) -> dict[str, np.ndarray]:
    """The state at time ``t`` of the motion whose velocity is the cubic ``qd + t qdd + t^2/2 q3d + t^3/6 q4d``
    (the base twist in the base frame and the joint velocities), from ``s`` at ``t = 0``: the joints'
    positions integrated in closed form, the base pose by RK4 of ``dp/dt = R v``, ``dquat/dt = quat (omega, 0)/2``."""
    jet = [s[k] for k in ("qd", "qdd", "q3d", "q4d")]

    def velocity(order: int, tau: float) -> np.ndarray:  # the order-th derivative of the velocity at tau
        return sum(jet[order + m] * tau**m / math.factorial(m) for m in range(4 - order))

    def rate(tau, x):
        v = velocity(0, tau)
        return np.r_[_rotation(x[3:]) @ v[3:6], _quaternion_rate(x[3:], v[:3])]

    x, dt = s["q"][:7].copy(), t / steps
    for k in range(steps):
        t0 = k * dt
        k1 = rate(t0, x)
        k2 = rate(t0 + dt / 2, x + dt / 2 * k1)
        k3 = rate(t0 + dt / 2, x + dt / 2 * k2)
        k4 = rate(t0 + dt, x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    joints = s["q"][7:] + sum(jet[m][6:] * t ** (m + 1) / math.factorial(m + 1) for m in range(4))
    return {"q": np.r_[x, joints], **{k: velocity(m, t) for m, k in enumerate(("qd", "qdd", "q3d", "q4d"))}}


@pytest.mark.slow
def test_time_derivatives_match_finite_differences():
    """dM/dt, d^2M/dt^2, dtau/dt and d^2tau/dt^2 against central differences of M, dM/dt, tau and dtau/dt
    along the trajectory, Richardson-extrapolated (the error falls from about 1e-6 to 1e-12)."""
    r = robot("solo12")
    pairs = {"mass_matrix": "mass_matrix_dot", "mass_matrix_dot": "mass_matrix_ddot",
             "inverse_dynamics": "inverse_dynamics_dot", "inverse_dynamics_dot": "inverse_dynamics_ddot"}
    names = list(dict.fromkeys([*pairs, *pairs.values(), "coriolis_matrix"]))
    eqs = jaxskid.derive(r, names)
    p = params(eqs)
    s = {k: v[0] for k, v in random_states(r, 1, seed=11).items()}
    s["q4d"] = np.random.default_rng(12).normal(size=r.nv)
    h = 2e-3
    states = [trajectory(s, t) for t in (-h, h, -h / 2, h / 2)]
    along = evaluate(eqs, list(pairs), {k: np.stack([st[k] for st in states]) for k in states[0]}, p)
    at = evaluate(eqs, names, {k: v[None] for k, v in s.items()}, p)
    for name, exact in pairs.items():
        v = along[name]
        coarse, fine = (v[1] - v[0]) / (2 * h), (v[3] - v[2]) / h
        err = rel_err(at[exact][0], (4 * fine - coarse) / 3)  # Richardson: O(h^4)
        assert err < 1e-9, f"{exact}: relative error {err:.3g}"
    c = at["coriolis_matrix"][0]
    assert rel_err(at["mass_matrix_dot"][0], c + c.T) < 1e-12
