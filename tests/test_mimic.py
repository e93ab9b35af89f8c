"""Mimic joints, ``q_m = a q_j + b``, eliminated in closed form, against independent references.

* Pinocchio's mimic model, ``buildModelFromUrdf(path, mimic=True)``: ``rnea``, ``nonLinearEffects``,
  ``computeGeneralizedGravity``, frame Jacobians and placements; ``M`` column by column from ``rnea`` (as
  Pinocchio's own ``unittest/crba.cpp`` checks it: 4.1's ``crba`` of a mimic model gets some off-diagonal
  entries of the revolute chain below wrong, while its ``rnea`` agrees with the uncoupled model projected; on
  the Panda ``crba`` is checked too); forward dynamics as ``M^-1 (tau - nle)`` (4.1's ``aba`` refuses mimic
  joints).
* Where Pinocchio has no mimic answer, its model of the same URDF without coupling, projected with the
  constant ``G`` of ``q_bodies = G q + b`` built here from the URDF's numbers: the Coriolis matrix
  ``G^T C(Gq + b, G qd) G`` (4.1's ``computeCoriolisMatrix`` of a mimic model gives ``C qd != nle - g``),
  ``dM/dt``, ``dtau/dt`` (``computeRNEADerivatives``), the regressor (``computeJointTorqueRegressor``) and
  chains of mimic joints (Pinocchio refuses them).
* The vector-Jacobian product of inverse dynamics against central differences of ``rnea``.

Robots: the Panda from example-robot-data (``panda_finger_joint2`` mimics ``panda_finger_joint1``) and
URDFs written here with multipliers and offsets other than 1 and 0: a revolute chain, prismatic joints (a
revolute joint following a prismatic one) and a mimic joint on another branch of a tree. The equations
are evaluated with NumPy (``jaxskid.testing._reference.evaluate``, nothing compiled) at random states,
relative error at most 1e-9 (normwise); one test lowers a robot and calls the JAX functions.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from jaxskid._api import module_key
from jaxskid.description._yaml_schema import parse_description
from jaxskid.testing._reference import evaluate
from helpers import PANDA, pinocchio_urdf_model, rel_err

TOL = 1e-9
N_STATES = 3
LIMIT = '<limit lower="-3" upper="3" effort="10" velocity="10"/>'

# (name, type, parent, child, origin xyz, origin rpy, axis[, (followed joint, multiplier, offset)])
CASES = {
    "revolute_chain": [
        ("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1"),
        ("j2", "revolute", "l1", "l2", "0.3 0 0", "0.1 0 0", "0 1 0", ("j1", -1.5, 0.2)),
        ("j3", "revolute", "l2", "l3", "0.3 0 0", "0 0.2 0", "1 0 0"),
        ("j4", "revolute", "l3", "l4", "0 0.2 0", "0 0 0.3", "0 1 0", ("j3", 0.7, -0.4)),
    ],
    "prismatic": [
        ("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1"),
        ("j2", "prismatic", "l1", "l2", "0.3 0 0", "0 0.1 0", "1 0 0"),
        ("j3", "prismatic", "l2", "l3", "0 0.1 0", "0.2 0 0", "0 1 0", ("j2", -0.7, 0.02)),
        ("j4", "revolute", "l3", "l4", "0 0 0.2", "0 0 0.1", "0 0 1", ("j2", 2.0, 0.3)),  # revolute follows prismatic
    ],
    "branch": [
        ("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1"),
        ("j2", "revolute", "l1", "l2", "0.3 0 0", "0 0 0.2", "0 1 0"),
        ("j3", "revolute", "l2", "l3", "0.3 0 0", "0.1 0 0", "0 1 0"),
        ("j4", "revolute", "l1", "l4", "0 0.3 0", "0 0.3 0", "1 0 0", ("j3", 0.5, -0.1)),  # another branch
        ("j5", "revolute", "l4", "l5", "0 0.2 0", "0 0 0", "0 0 1"),
    ],
}
QUANTITIES = ["mass_matrix", "gravity_torques", "coriolis_torques", "inverse_dynamics", "forward_dynamics",
              "body_jacobian", "hybrid_jacobian", "forward_kinematics", "regressor", "body_twist",
              "inverse_dynamics_vjp"]
SECOND_ORDER = ["coriolis_matrix", "mass_matrix_dot", "inverse_dynamics_dot"]  # derived in seconds each
SLOW = pytest.mark.slow


def _link(name: str, k: int) -> str:
    return (f'<link name="{name}"><inertial><origin xyz="{0.05 * k} -0.02 0.1" rpy="0.1 0.2 {0.3 * k}"/>'
            f'<mass value="{1.0 + 0.3 * k}"/><inertia ixx="{0.1 + 0.01 * k}" ixy="0.01" ixz="-0.02" iyy="0.2" '
            f'iyz="0.03" izz="{0.3 - 0.01 * k}"/></inertial></link>')


def _joint(name, kind, parent, child, xyz, rpy, axis, mimic=None) -> str:
    tag = "" if mimic is None else f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]}" offset="{mimic[2]}"/>'
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>{LIMIT}{tag}</joint>')


def write_urdf(path, joints) -> str:
    links = "".join(_link(j[3], k) for k, j in enumerate(joints))
    path.write_text(f'<robot name="{path.stem}"><link name="base"/>{links}{"".join(_joint(*j) for j in joints)}</robot>')
    return str(path)


def coupling(joints):
    """``G`` (bodies x coordinates) and ``b`` of ``q_bodies = G q + b`` from the URDF's own numbers."""
    independent = [j[0] for j in joints if len(j) < 8]
    g, b = np.zeros((len(joints), len(independent))), np.zeros(len(joints))
    for i, j in enumerate(joints):
        if len(j) < 8:
            g[i, independent.index(j[0])] = 1.0
        else:
            g[i, independent.index(j[7][0])], b[i] = j[7][1], j[7][2]
    return g, b


def states(n: int, seed: int = 3) -> dict:
    rng = np.random.default_rng(seed)
    out = {"q": rng.uniform(-1.5, 1.5, (N_STATES, n))}
    out.update({k: rng.normal(size=(N_STATES, n)) for k in ("qd", "qdd", "q3d", "tau", "cotangent")})
    return out


def evaluated(robot, names, state) -> dict:
    eqs = jaxskid.derive(robot, names)
    defaults = robot.default_params()
    return evaluate(eqs, names, state, np.array([defaults[p] for p in eqs.parameters]))


def sym(m):
    return np.triu(m) + np.triu(m, 1).T


def mass_matrix(model, data, q) -> np.ndarray:
    """``M`` column by column: ``rnea(q, 0, e_k) - rnea(q, 0, 0)``."""
    z = np.zeros(model.nv)
    rest = pin.rnea(model, data, q, z, z)
    return np.array([pin.rnea(model, data, q, z, e) - rest for e in np.eye(model.nv)]).T


def jacobian(model, data, frame: str, ref) -> np.ndarray:
    j = pin.getFrameJacobian(model, data, model.getFrameId(frame), ref)
    return np.vstack([j[3:], j[:3]])  # Pinocchio's (v, omega) -> (omega, v)


@pytest.fixture(scope="module", params=list(CASES))
def case(request, tmp_path_factory):
    """(name, joints, path, robot, states, QUANTITIES evaluated at the states): one derivation per robot."""
    joints = CASES[request.param]
    path = write_urdf(tmp_path_factory.mktemp("mimic") / f"{request.param}.urdf", joints)
    robot = jaxskid.load(path, mimic=True)
    s = states(robot.n_dof)
    return request.param, joints, path, robot, s, evaluated(robot, QUANTITIES, s)


# ------------------------------------------------------------------------------------------ against Pinocchio
def test_urdf_cases_match_pinocchio_mimic_model(case):
    name, joints, path, robot, s, ours = case
    independent = [j[0] for j in joints if len(j) < 8]
    assert robot.joint_names == tuple(independent) and robot.n_dof == len(independent)
    assert robot.mimic_joints == tuple(j[0] for j in joints if len(j) == 8) and robot.n_bodies == len(joints)
    model = pin.buildModelFromUrdf(path, mimic=True)
    data = model.createData()
    assert model.nv == robot.n_dof
    pi = jaxskid.standard_params(robot)
    for k in range(N_STATES):
        q, qd, qdd, tau = (s[a][k] for a in ("q", "qd", "qdd", "tau"))
        m = mass_matrix(model, data, q)
        g = pin.computeGeneralizedGravity(model, data, q)
        nle = pin.nonLinearEffects(model, data, q, qd)
        rnea = pin.rnea(model, data, q, qd, qdd)
        checks = {
            "mass_matrix": (ours["mass_matrix"][k], m),
            "gravity_torques": (ours["gravity_torques"][k], g),
            "coriolis_torques": (ours["coriolis_torques"][k], nle - g),
            "inverse_dynamics": (ours["inverse_dynamics"][k], rnea),
            "forward_dynamics": (ours["forward_dynamics"][k], np.linalg.solve(m, tau - nle)),
            "regressor @ pi": (ours["regressor"][k] @ pi, rnea),
        }
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for e, frame in enumerate(robot.end_effectors):
            checks[f"body_jacobian {frame}"] = (ours["body_jacobian"][k, e], jacobian(model, data, frame, pin.LOCAL))
            checks[f"hybrid_jacobian {frame}"] = (ours["hybrid_jacobian"][k, e],
                                                  jacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED))
        for f, frame in enumerate(robot.frame_names):
            checks[f"pose {frame}"] = (ours["forward_kinematics"][k, f], data.oMf[model.getFrameId(frame)].homogeneous)
        for what, (a, b) in checks.items():
            assert rel_err(a, b) < TOL, f"{name}, state {k}: {what}: {rel_err(a, b):.2e}"


@pytest.mark.parametrize("name", [pytest.param("revolute_chain", marks=SLOW), "prismatic",
                                  pytest.param("branch", marks=SLOW)])
def test_projected_quantities_match_the_uncoupled_model(name, tmp_path):
    """C, dM/dt, dtau/dt, the regressor and the bodies' twists: Pinocchio's model without the coupling,
    projected with G."""
    joints = CASES[name]
    path = write_urdf(tmp_path / f"{name}.urdf", joints)
    robot = jaxskid.load(path, mimic=True)
    s = states(robot.n_dof)
    ours = evaluated(robot, [*SECOND_ORDER, "regressor", "body_twist"], s)
    g, b = coupling(joints)
    full = pin.buildModelFromUrdf(path)
    data = full.createData()
    for k in range(N_STATES):
        q, qd, qdd, q3d = (g @ s[a][k] for a in ("q", "qd", "qdd", "q3d"))
        q = q + b
        c = pin.computeCoriolisMatrix(full, data, q, qd)
        dtau_dq, dtau_dv, m = pin.computeRNEADerivatives(full, data, q, qd, qdd)
        y = pin.computeJointTorqueRegressor(full, data, q, qd, qdd)
        pin.forwardKinematics(full, data, q, qd)
        twists = np.array([np.concatenate([data.v[i].angular, data.v[i].linear]) for i in range(1, full.njoints)])
        checks = {
            "coriolis_matrix": (ours["coriolis_matrix"][k], g.T @ c @ g),
            "mass_matrix_dot": (ours["mass_matrix_dot"][k], g.T @ (c + c.T) @ g),
            "inverse_dynamics_dot": (ours["inverse_dynamics_dot"][k],
                                     g.T @ (dtau_dq @ qd + dtau_dv @ qdd + sym(m) @ q3d)),
            "regressor": (ours["regressor"][k], g.T @ y),
            "body_twist": (ours["body_twist"][k], twists),
        }
        for what, (a, ref) in checks.items():
            assert rel_err(a, ref) < TOL, f"{name}, state {k}: {what}: {rel_err(a, ref):.2e}"


def test_inverse_dynamics_vjp_against_differences_of_rnea(case):
    name, joints, path, robot, s, ours = case
    model = pin.buildModelFromUrdf(path, mimic=True)
    data = model.createData()
    ours = ours["inverse_dynamics_vjp"]
    n, h = robot.n_dof, 1e-6
    for k in range(N_STATES):
        q, qd, qdd, w = (s[a][k] for a in ("q", "qd", "qdd", "cotangent"))
        grad = np.zeros(2 * n)
        for c in range(n):
            e = h * np.eye(n)[c]
            grad[c] = w @ (pin.rnea(model, data, q + e, qd, qdd) - pin.rnea(model, data, q - e, qd, qdd)) / (2 * h)
            grad[n + c] = w @ (pin.rnea(model, data, q, qd + e, qdd) - pin.rnea(model, data, q, qd - e, qdd)) / (2 * h)
        assert rel_err(ours[k, : 2 * n], grad) < 1e-7, f"{name}, state {k}"


def test_chain_of_mimic_joints_is_composed(tmp_path):
    """j3 follows j2, which follows j1 (Pinocchio refuses the chain): q3 = a3 (a2 q1 + b2) + b3."""
    (a2, b2), (a3, b3) = (-1.5, 0.2), (0.8, -0.3)
    base = [("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1"),
            ("j2", "revolute", "l1", "l2", "0.3 0 0", "0.1 0 0", "0 1 0", ("j1", a2, b2))]
    chained = write_urdf(tmp_path / "chained.urdf", [*base, ("j3", "prismatic", "l2", "l3", "0 0.2 0", "0 0 0",
                                                             "1 0 0", ("j2", a3, b3))])
    direct = write_urdf(tmp_path / "direct.urdf", [*base, ("j3", "prismatic", "l2", "l3", "0 0.2 0", "0 0 0",
                                                           "1 0 0", ("j1", a3 * a2, a3 * b2 + b3))])
    robot = jaxskid.load(chained, mimic=True)
    assert robot.joint_names == ("j1",)
    composed = robot.joints[2].mimic
    assert composed.joint == "j1"
    assert float(composed.multiplier) == pytest.approx(a3 * a2) and float(composed.offset) == pytest.approx(a3 * b2 + b3)
    model = pin.buildModelFromUrdf(direct, mimic=True)
    data = model.createData()
    s = states(1)
    ours = evaluated(robot, ["mass_matrix", "inverse_dynamics"], s)
    for k in range(N_STATES):
        q, qd, qdd = (s[a][k] for a in ("q", "qd", "qdd"))
        assert rel_err(ours["mass_matrix"][k], mass_matrix(model, data, q)) < TOL
        assert rel_err(ours["inverse_dynamics"][k], pin.rnea(model, data, q, qd, qdd)) < TOL


def test_panda_with_coupled_fingers():
    robot = jaxskid.load(PANDA, mimic=True)
    assert robot.n_dof == 8 and robot.mimic_joints == ("panda_finger_joint2",)
    assert robot.joint_names[-1] == "panda_finger_joint1" and "panda_finger_joint2" not in robot.joint_names
    model = pin.buildModelFromUrdf(str(PANDA), mimic=True)
    data = model.createData()
    s = states(8)
    s["q"][:, 7] = np.abs(s["q"][:, 7]) * 0.02  # the fingers' travel
    ours = evaluated(robot, ["mass_matrix", "inverse_dynamics", "gravity_torques", "body_jacobian"], s)
    for k in range(N_STATES):
        q, qd, qdd = (s[a][k] for a in ("q", "qd", "qdd"))
        assert rel_err(ours["mass_matrix"][k], sym(pin.crba(model, data, q))) < TOL
        assert rel_err(ours["mass_matrix"][k], mass_matrix(model, data, q)) < TOL
        assert rel_err(ours["inverse_dynamics"][k], pin.rnea(model, data, q, qd, qdd)) < TOL
        assert rel_err(ours["gravity_torques"][k], pin.computeGeneralizedGravity(model, data, q)) < TOL
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for e, frame in enumerate(robot.end_effectors):
            assert rel_err(ours["body_jacobian"][k, e], jacobian(model, data, frame, pin.LOCAL)) < TOL, frame


@SLOW
def test_lowered_functions_take_the_independent_coordinates(tmp_path):
    joints = CASES["revolute_chain"]
    robot = jaxskid.load(write_urdf(tmp_path / "lowered.urdf", joints), mimic=True)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "regressor"])
    assert dyn.joint_names == ("j1", "j3") and dyn.n_dof == 2
    model = pin.buildModelFromUrdf(str(tmp_path / "lowered.urdf"), mimic=True)
    data = model.createData()
    s = states(2)
    tau = np.asarray(dyn.inverse_dynamics(s["q"], s["qd"], s["qdd"]))  # a batch of states
    y = np.asarray(dyn.regressor(s["q"], s["qd"], s["qdd"]))
    assert tau.shape == (N_STATES, 2) and y.shape == (N_STATES, 2, 10 * 4)
    for k in range(N_STATES):
        q, qd, qdd = (s[a][k] for a in ("q", "qd", "qdd"))
        assert rel_err(dyn.mass_matrix(q), mass_matrix(model, data, q)) < TOL
        assert rel_err(tau[k], pin.rnea(model, data, q, qd, qdd)) < TOL
        assert rel_err(y[k] @ jaxskid.standard_params(robot), tau[k]) < TOL


def test_drive_on_a_mimic_joint_acts_through_the_coupling(tmp_path):
    """tau gains G^T (Ia qdd_b + fv qd_b + fc sign(qd_b) + fo), the bodies' drive forces at qd_b = G qd."""
    joints = CASES["prismatic"]
    path = write_urdf(tmp_path / "driven.urdf", joints)
    g, _ = coupling(joints)
    values = {f"{j}_{p}": v for j, row in zip(("j1", "j2", "j3", "j4"), ([0.1, 0.2, 0.3, 0.4], [0.5, 0.6, 0.7, 0.8],
                                                                      [0.9, 1.0, 1.1, 1.2], [1.3, 1.4, 1.5, 1.6]))
              for p, v in zip(("Ia", "fv", "fc", "fo"), row)}
    robot = jaxskid.load(path, mimic=True, drives=True).with_defaults(values)
    assert len(robot.driven) == 4  # mimic joints have drives too
    s = states(robot.n_dof)
    ours = evaluated(robot, ["inverse_dynamics", "mass_matrix", "regressor"], s)
    bare = evaluated(jaxskid.load(path, mimic=True), ["inverse_dynamics", "mass_matrix"], s)
    ia, fv, fc, fo = (np.array([values[f"{j}_{p}"] for j in ("j1", "j2", "j3", "j4")]) for p in ("Ia", "fv", "fc", "fo"))
    pi = jaxskid.standard_params(robot)
    for k in range(N_STATES):
        qd, qdd = g @ s["qd"][k], g @ s["qdd"][k]
        drive = g.T @ (ia * qdd + fv * qd + fc * np.sign(qd) + fo)
        assert rel_err(ours["inverse_dynamics"][k], bare["inverse_dynamics"][k] + drive) < TOL
        assert rel_err(ours["mass_matrix"][k], bare["mass_matrix"][k] + g.T @ np.diag(ia) @ g) < TOL
        assert rel_err(ours["regressor"][k] @ pi, ours["inverse_dynamics"][k]) < TOL


# ------------------------------------------------------------------------------------------ the request
@SLOW
def test_every_quantity_is_derived_in_the_coordinates_or_refused(tmp_path):
    pair = [CASES["prismatic"][0], ("j2", "revolute", "l1", "l2", "0.3 0 0", "0 0.1 0", "0 1 0"),
            ("j3", "revolute", "l2", "l3", "0.3 0 0", "0 0 0", "1 0 0", ("j1", 0.5, 0.1))]
    robot = jaxskid.load(write_urdf(tmp_path / "pair.urdf", pair), mimic=True)
    robot = robot.with_constraints([jaxskid.PointContact("l3")])  # and the constraints' quantities
    eqs = jaxskid.derive(robot, "all")  # derive checks every quantity's size against its shape
    n, nb = robot.n_dof, robot.n_bodies
    assert set(eqs.quantities) == set(jaxskid.QUANTITIES)
    assert eqs.quantities["constraint_jacobian"].shape == (3, n)
    assert eqs.quantities["system_jacobian"].shape == (6 * nb, n) and eqs.quantities["body_twist"].shape == (nb, 6)
    assert eqs.quantities["inverse_dynamics_vjp"].shape == (2 * n + len(robot.parameters),)
    assert all(len(eqs.arguments[a].symbols) == n for a in ("q", "qd", "qdd", "q3d", "q4d", "tau", "cotangent"))


def test_cache_key_holds_the_coupling_and_lagrange_is_refused(tmp_path):
    robot = jaxskid.load(write_urdf(tmp_path / "chain.urdf", CASES["revolute_chain"]), mimic=True)
    with pytest.raises(jaxskid.RequestError, match="route='lagrange'.*mimic joints \\(j2, j4\\)"):
        jaxskid.derive(robot, ["mass_matrix"], options=jaxskid.Options(route="lagrange"))
    joints = list(robot.joints)
    keys = {module_key(robot, ["mass_matrix"])}
    for change in ({"offset": 0.3}, {"multiplier": -1.4}, {"joint": "j3"}):
        moved = [joints[0], replace(joints[1], mimic=replace(joints[1].mimic, **change)), *joints[2:]]
        keys.add(module_key(robot._recreate(joints=moved), ["mass_matrix"]))
    with pytest.warns(jaxskid.DescriptionWarning):
        keys.add(module_key(jaxskid.load(tmp_path / "chain.urdf"), ["mass_matrix"]))
    assert len(keys) == 5


# ------------------------------------------------------------------------------------------ descriptions
def test_default_reads_mimic_joints_as_independent_and_warns_naming_the_option(case):
    name, joints, path, *_ = case
    with pytest.warns(jaxskid.DescriptionWarning, match=r"mimic=True") as record:
        robot = jaxskid.load(path)
    record = [w for w in record if issubclass(w.category, jaxskid.DescriptionWarning)]
    mimics = [j[0] for j in joints if len(j) == 8]
    assert robot.n_dof == len(joints) and not robot.mimic_joints
    (message,) = (str(w.message) for w in record)  # one warning per file, naming every mimic joint
    assert message.startswith(f"{path}: joint[name=")
    assert message.split(": ")[1] in [f"joint[name={m}].mimic" for m in mimics]
    assert all(f"'{m}' to " in message for m in mimics) if len(mimics) > 1 else message.count("coupling to ") == 1


def test_python_and_yaml_declarations_give_the_same_robot(case, tmp_path):
    name, joints, path, robot, *_ = case
    with pytest.warns(jaxskid.DescriptionWarning):
        loose = jaxskid.load(path)
    spec = {j[0]: j[7] for j in joints if len(j) == 8}
    as_tuples = [replace(j, mimic=spec.get(j.name)) for j in loose.joints]
    declared = jaxskid.Robot.create(robot.name, as_tuples, frames=loose.frames, end_effectors=loose.end_effectors,
                                    defaults=dict(loose.defaults), base=loose.base)
    assert declared.fingerprint() == robot.fingerprint()
    jaxskid.write_description(robot, tmp_path / "robot.yaml")
    text = (tmp_path / "robot.yaml").read_text()
    assert "mimic:" in text
    again = jaxskid.load(tmp_path / "robot.yaml")
    assert again.fingerprint() == robot.fingerprint() and again.joint_names == robot.joint_names


def test_yaml_short_form_and_lock_follow(tmp_path):
    joints = CASES["revolute_chain"]
    robot = jaxskid.load(write_urdf(tmp_path / "chain.urdf", joints), mimic=True)
    data = jaxskid.robot_to_dict(robot)
    data["mimic"][1] = "j1"  # multiplier 1, offset 0
    short = parse_description(data)
    assert short.joints[1].mimic == jaxskid.Mimic("j1", 1, 0)
    # locking j1 locks its mimic joint j2 at -1.5 * 0.4 + 0.2; j3 and its mimic joint j4 stay
    locked = jaxskid.load(tmp_path / "chain.urdf", mimic=True, lock={"j1": 0.4})
    assert locked.joint_names == ("j3",) and locked.mimic_joints == ("j4",)
    assert robot.lock({"j1": 0.4}).fingerprint() == locked.fingerprint()
    reduced = pinocchio_urdf_model(tmp_path / "chain.urdf", lock={"j1": 0.4, "j2": -1.5 * 0.4 + 0.2})
    assert reduced.nv == 2
    g, b = np.array([[1.0], [0.7]]), np.array([0.0, -0.4])  # (j3, j4) of the reduced model from q3
    s = states(1)
    ours = evaluated(locked, ["mass_matrix"], s)["mass_matrix"]
    for k in range(N_STATES):
        m = sym(pin.crba(reduced, reduced.createData(), g @ s["q"][k] + b))
        assert rel_err(ours[k], g.T @ m @ g) < TOL


# ------------------------------------------------------------------------------------------ bad input
def _yaml_case(tmp_path):
    robot = jaxskid.load(write_urdf(tmp_path / "chain.urdf", CASES["revolute_chain"]), mimic=True)
    return jaxskid.robot_to_dict(robot)


@pytest.mark.parametrize("entry, where, message", [
    ({"joint": "q9"}, "mimic[1].joint", "expected the name of a joint, got 'q9'"),
    ({"joint": "j1", "multiplier": "m1"}, "mimic[1].multiplier", "expected a number, got 'm1', which depends on m1"),
    ({"joint": "j1", "multiplier": [1, 2]}, "mimic[1].multiplier", "expected a number or an expression, got a list"),
    ({"joint": "j1", "gain": 2}, "mimic[1]", "unknown key 'gain'"),
    ({"joint": "j2"}, "mimic[1].joint", "loop j2 -> j2"),
])
def test_bad_yaml_mimic_names_file_and_key(tmp_path, entry, where, message):
    data = _yaml_case(tmp_path)
    data["mimic"][1] = entry
    with pytest.raises(jaxskid.ModelError) as err:
        parse_description(data, source="robot.yaml")
    assert str(err.value).startswith(f"robot.yaml: {where}: ") and message in str(err.value)


def test_bad_urdf_mimic_names_file_and_key(tmp_path):
    j1 = ("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1")
    cases = {
        "loop": ([("j1", *j1[1:], ("j2", 1, 0)), ("j2", "revolute", "l1", "l2", "0.3 0 0", "0 0 0", "0 1 0",
                                                 ("j1", 2, 0))], "joint[name=j1].mimic.joint", "loop j1 -> j2 -> j1"),
        "fixed": ([("f", "fixed", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1"),
                   ("j2", "revolute", "l1", "l2", "0.3 0 0", "0 0 0", "0 1 0", ("f", 1, 0))],
                  "joint[name=j2].mimic.joint", "expected a moving joint, got fixed joint 'f'"),
        "missing": ([j1, ("j2", "revolute", "l1", "l2", "0.3 0 0", "0 0 0", "0 1 0", ("j7", 1, 0))],
                    "joint[name=j2].mimic.joint", "expected the name of a joint, got 'j7'"),
        "word": ([j1, ("j2", "revolute", "l1", "l2", "0.3 0 0", "0 0 0", "0 1 0", ("j1", "two", 0))],
                 "joint[name=j2].mimic.multiplier", "expected a number, got 'two'"),
    }
    for name, (joints, where, message) in cases.items():
        path = write_urdf(tmp_path / f"{name}.urdf", joints)
        with pytest.raises(jaxskid.ModelError) as err:
            jaxskid.load(path, mimic=True)
        assert str(err.value).startswith(f"{path}: {where}: ") and message in str(err.value), name


def test_bad_python_mimic_and_lock(tmp_path):
    robot = jaxskid.load(write_urdf(tmp_path / "chain.urdf", CASES["revolute_chain"]), mimic=True)
    joints = list(robot.joints)
    with pytest.raises(jaxskid.ModelError, match=r"^joints\[1\]\.mimic: expected a Mimic, a joint name"):
        jaxskid.Robot.create("r", [joints[0], replace(joints[1], mimic=42), *joints[2:]])
    with pytest.raises(jaxskid.ModelError, match=r"^joints\[1\]\.mimic\.offset: expected a number, got 'b'"):
        jaxskid.Robot.create("r", [joints[0], replace(joints[1], mimic=("j1", 1, "b")), *joints[2:]])
    with pytest.raises(jaxskid.ModelError, match=r"^lock\.j2: joint 'j2' mimics 'j1': lock 'j1' instead"):
        robot.lock({"j2": 0.1})
    with pytest.raises(jaxskid.ModelError, match=r"^lock\.j2: joint 'j2' mimics 'j1'.*expected"):
        robot.lock({"j1": 0.0, "j2": 0.1})


def test_write_urdf_keeps_the_coupling(case, tmp_path):
    """``write_urdf`` writes each ``<mimic>`` back: yourdfpy reads the same couplings, and the written file
    loads with the same independent joints and mass matrix."""
    import yourdfpy

    _, _, _, robot, state, values = case
    out = tmp_path / "written.urdf"
    jaxskid.write_urdf(robot, out)
    urdf = yourdfpy.URDF.load(str(out), build_scene_graph=False, load_meshes=False)
    written = {j.name: j.mimic for j in urdf.robot.joints if j.mimic is not None}
    expected = {j.name: j.mimic for j in robot.joints if j.mimic is not None}
    assert expected and written.keys() == expected.keys()
    for name, m in expected.items():
        assert written[name].joint == m.joint
        assert np.isclose(float(written[name].multiplier), float(m.multiplier))
        assert np.isclose(float(written[name].offset), float(m.offset))
    again = jaxskid.load(out, mimic=True)
    assert again.joint_names == robot.joint_names
    m1 = evaluated(again, ["mass_matrix"], state)["mass_matrix"]
    assert rel_err(m1, values["mass_matrix"]) < 1e-12
