"""A Skidy user's files and habits, each checked against something independent of jaxskid's derivation.

The descriptions are small Skidy-style files written here (none is copied from Skidy):

1. Skidy's Coriolis matrix (``Options(coriolis="skidy")``) equals Müller & Kumar's closed form
   ``C = -J^T (M A a + b^T M) J`` built by hand with NumPy for a planar 2R arm, and its time derivatives equal
   finite differences of it along a motion; the default C is the textbook Christoffel C of the 2R arm.
2. A description without ``mass_inertia`` loads for kinematics (forward kinematics against a hand formula) and
   a request for dynamics names the bodies without one.
3. ``dialect="skidy"``: ``parent`` without ``support`` is a serial chain, and ``frame: com`` carries over to the
   bodies after it, each against a Pinocchio model built from the same numbers; the strict reading against
   the Pinocchio model of its own meaning.
4. The hybrid Jacobian of an end-effector's parent body and its time derivative, against Pinocchio's
   ``LOCAL_WORLD_ALIGNED`` frame Jacobian of that body; an end-effector placed on a URDF link, against
   Pinocchio's placement of the link; Skidy's ``(n, 1)`` columns, landscape LaTeX and a project name in
   generated code.
5. Skidy's looser parsing in the dialect (assignments of assignments, a cycle named, unknown keys and a
   prismatic ``vec`` ignored with a warning) and jaxskid's strict errors outside it.
6. ``convert --round 1e-4`` round-trips, and ``generate`` self-checks with random positive values for the
   parameters without a default.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pinocchio as pin
import pytest
import yaml
from click.testing import CliRunner

import jaxskid
from jaxskid._cli import cli
from jaxskid.description._yaml_schema import parse_description
from jaxskid.description._yaml_writer import round_robot

# ------------------------------------------------------------------------------------------ hand-built SE(3)


def skew(v) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def rot_z(a) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def pose(r, p) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = r, p
    return out


def big_ad(c) -> np.ndarray:
    """Ad(C) on twists (omega, v): [[R, 0], [p~ R, R]]."""
    r, p = c[:3, :3], c[:3, 3]
    return np.block([[r, np.zeros((3, 3))], [skew(p) @ r, r]])


def small_ad(v) -> np.ndarray:
    """ad(V) for V = (omega, v): [[omega~, 0], [v~, omega~]]."""
    return np.block([[skew(v[:3]), np.zeros((3, 3))], [skew(v[3:]), skew(v[:3])]])


def body_inertia(m, c, i_c) -> np.ndarray:
    """The 6x6 mass-inertia about the body origin in (omega, v) order, from the mass, the centre of mass c and
    the rotational inertia about c: momentum (I_o omega + m c x v, m (v + omega x c))."""
    i_o = np.asarray(i_c) - m * skew(c) @ skew(c)
    return np.block([[i_o, m * skew(c)], [-m * skew(c), m * np.eye(3)]])


# ------------------------------------------------------------------------------------------ 1. Skidy's C
L1, LC1, LC2, M1, M2, I1, I2 = 0.6, 0.25, 0.2, 1.3, 0.9, 0.04, 0.03
ARM_2R = {
    "representation": "spatial",
    "parent": [0, 1], "support": [[1], [1, 2]],
    "joint_screw_coord": [{"type": "revolute", "axis": [0, 0, 1]},
                          {"type": "revolute", "axis": [0, 0, 1], "vec": [L1, 0, 0]}],
    "body_ref_config": [{"translation": [0, 0, 0]}, {"translation": [L1, 0, 0]}],
    "ee": {"translation": [0.4, 0, 0]},
    "mass_inertia": [{"mass": M1, "com": [LC1, 0, 0], "inertia": {"Izz": I1, "Ixx": 0.01, "Iyy": 0.04}, "frame": "com"},
                     {"mass": M2, "com": [LC2, 0, 0], "inertia": {"Izz": I2, "Ixx": 0.01, "Iyy": 0.03}, "frame": "com"}],
    "gravity": [0, -9.81, 0],
}
C_NAMES = ["mass_matrix", "coriolis_matrix", "coriolis_torques", "coriolis_matrix_dot", "coriolis_matrix_ddot"]


def skidy_2r(q, qd) -> tuple[np.ndarray, np.ndarray]:
    """(M, C) of the 2R arm by Müller & Kumar's closed form, every block written out: body frames at the joints,
    C_1 = Rz(q1), C_2 = C_1 T(L1) Rz(q2); X_i = e_z (omega); A = [[1, 0], [Ad(C_2^-1 C_1), 1]]; J = A X;
    a = diag(ad(X_i) qd_i), b = diag(ad(V_i)); M = J^T Mb J, C = -J^T (Mb A a + b^T Mb) J."""
    x = np.array([0, 0, 1, 0, 0, 0.0])
    c1 = pose(rot_z(q[0]), np.zeros(3))
    c2 = c1 @ pose(np.eye(3), [L1, 0, 0]) @ pose(rot_z(q[1]), np.zeros(3))
    a_big = np.eye(12)
    a_big[6:, :6] = big_ad(np.linalg.inv(c2) @ c1)
    xs = np.zeros((12, 2))
    xs[:6, 0], xs[6:, 1] = x, x
    j = a_big @ xs
    v = j @ qd
    a = np.zeros((12, 12))
    b = np.zeros((12, 12))
    mb = np.zeros((12, 12))
    for i, (m, lc, izz, ixx, iyy) in enumerate(((M1, LC1, I1, 0.01, 0.04), (M2, LC2, I2, 0.01, 0.03))):
        a[6 * i:6 * i + 6, 6 * i:6 * i + 6] = small_ad(x) * qd[i]
        b[6 * i:6 * i + 6, 6 * i:6 * i + 6] = small_ad(v[6 * i:6 * i + 6])
        mb[6 * i:6 * i + 6, 6 * i:6 * i + 6] = body_inertia(m, [lc, 0, 0], np.diag([ixx, iyy, izz]))
    return j.T @ mb @ j, -j.T @ (mb @ a_big @ a + b.T @ mb) @ j


def christoffel_2r(q, qd) -> tuple[np.ndarray, np.ndarray]:
    """The textbook (M, C) of a planar 2R arm (Spong, Hutchinson & Vidyasagar, sec. 7.4): h = m2 l1 lc2 sin q2,
    C = [[-h qd2, -h (qd1 + qd2)], [h qd1, 0]]."""
    c2, h = np.cos(q[1]), M2 * L1 * LC2 * np.sin(q[1])
    m11 = I1 + I2 + M1 * LC1**2 + M2 * (L1**2 + LC2**2 + 2 * L1 * LC2 * c2)
    m12 = I2 + M2 * (LC2**2 + L1 * LC2 * c2)
    m = np.array([[m11, m12], [m12, I2 + M2 * LC2**2]])
    return m, np.array([[-h * qd[1], -h * (qd[0] + qd[1])], [h * qd[0], 0]])


def test_skidy_coriolis_option_is_mueller_kumars_closed_form_and_the_default_is_christoffels():
    robot = parse_description(ARM_2R, source="arm_2r.yaml", dialect="skidy")
    skidy = jaxskid.lower(robot, C_NAMES, options=jaxskid.Options(coriolis="skidy"))
    default = jaxskid.lower(robot, C_NAMES)
    assert skidy.coriolis == "skidy" and default.coriolis == "christoffel"
    rng = np.random.default_rng(3)
    differ = 0.0
    for _ in range(4):
        q, qd = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
        m_s, c_s = skidy_2r(q, qd)
        m_t, c_t = christoffel_2r(q, qd)
        np.testing.assert_allclose(m_s, m_t, atol=1e-14)  # the hand-built blocks describe the same arm
        np.testing.assert_allclose(c_s @ qd, c_t @ qd, atol=1e-14)
        np.testing.assert_allclose(np.asarray(skidy.coriolis_matrix(q, qd)), c_s, atol=1e-14)
        np.testing.assert_allclose(np.asarray(default.coriolis_matrix(q, qd)), c_t, atol=1e-14)
        np.testing.assert_allclose(np.asarray(skidy.coriolis_torques(q, qd)), c_s @ qd, atol=1e-14)
        differ = max(differ, float(np.abs(c_s - c_t).max()))
    assert differ > 1e-2  # two factorisations, one C qd


def test_skidy_coriolis_time_derivatives_follow_the_hand_built_closed_form():
    """C' and C'' along q(t) = q0 + qd t + qdd t^2/2 + q3d t^3/6 + q4d t^4/24, against 4th-order central
    differences of the hand-built Skidy C."""
    robot = parse_description(ARM_2R, source="arm_2r.yaml", dialect="skidy")
    dyn = jaxskid.lower(robot, C_NAMES, options=jaxskid.Options(coriolis="skidy"))
    rng = np.random.default_rng(5)
    q0, qd, qdd, q3d, q4d = rng.uniform(-1, 1, (5, 2))

    def c_at(t):
        q = q0 + qd * t + qdd * t**2 / 2 + q3d * t**3 / 6 + q4d * t**4 / 24
        v = qd + qdd * t + q3d * t**2 / 2 + q4d * t**3 / 6
        return skidy_2r(q, v)[1]

    h = 1e-3
    c = {k: c_at(k * h) for k in (-2, -1, 0, 1, 2)}
    first = (c[-2] - 8 * c[-1] + 8 * c[1] - c[2]) / (12 * h)
    second = (-c[-2] + 16 * c[-1] - 30 * c[0] + 16 * c[1] - c[2]) / (12 * h**2)
    np.testing.assert_allclose(np.asarray(dyn.coriolis_matrix_dot(q0, qd, qdd)), first, atol=1e-9)
    np.testing.assert_allclose(np.asarray(dyn.coriolis_matrix_ddot(q0, qd, qdd, q3d)), second, atol=1e-6)


# ------------------------------------------------------------------------------------------ 2. kinematics only
KINEMATIC = {
    "representation": "spatial",
    "joint_screw_coord": [{"type": "revolute", "axis": [0, 0, 1]},
                          {"type": "revolute", "axis": [0, 0, 1], "vec": ["L1", 0, 0]}],
    "body_ref_config": [{"translation": [0, 0, 0]}, {"translation": ["L1", 0, 0]}],
    "ee": {"translation": ["L2", 0, 0]},
    "assignments": {"L1": 0.7, "L2": 0.45},
}


def test_a_description_without_mass_inertia_serves_kinematics_and_refuses_dynamics(tmp_path):
    path = tmp_path / "planar.yaml"
    path.write_text(yaml.safe_dump(KINEMATIC))
    robot = jaxskid.load(path)
    assert robot.without_inertia == ("link1", "link2")
    dyn = jaxskid.lower(robot)  # the default request: what a robot without masses has
    assert dyn.quantities == ("forward_kinematics",)
    q = np.array([0.4, -1.1])
    tip = np.asarray(dyn.forward_kinematics(q)["ee"])
    expected = [0.7 * np.cos(0.4) + 0.45 * np.cos(0.4 - 1.1), 0.7 * np.sin(0.4) + 0.45 * np.sin(0.4 - 1.1), 0]
    np.testing.assert_allclose(tip[:3, 3], expected, atol=1e-14)
    for names in (["mass_matrix"], ["forward_kinematics", "inverse_dynamics"]):
        with pytest.raises(jaxskid.RequestError) as info:
            jaxskid.lower(robot, names)
        message = str(info.value)
        assert names[-1] in message and "link1, link2" in message and "mass_inertia" in message
    # one body without its entry: only that one is named; written back, the file says so with a null
    one = {**KINEMATIC, "gravity": [0, 0, -9.81], "mass_inertia": [None, {"mass": 1.0, "com": [0.2, 0, 0], "frame": "com"}]}
    partial = parse_description(one, source="partial.yaml")
    assert partial.without_inertia == ("link1",)
    with pytest.raises(jaxskid.RequestError, match=r"for body link1: "):
        jaxskid.derive(partial, ["gravity_torques"])
    again = parse_description(jaxskid.robot_to_dict(partial), source="again.yaml")
    assert again.without_inertia == ("link1",) and again.fingerprint() == partial.fingerprint()
    assert "mass_inertia" not in jaxskid.robot_to_dict(robot)


# ------------------------------------------------------------------------------------------ 3. the dialect's tree and frames
AXES = ([0, 0, 1], [0, 1, 0], [1, 0, 0])
OFFSETS = ([0, 0, 0.3], [0.4, 0, 0], [0, 0.25, 0.1])
BODIES = ((1.2, [0.1, 0, 0.05], [0.05, 0.06, 0.04]), (0.8, [0.2, 0.02, 0], [0.02, 0.03, 0.025]),
          (0.5, [0.05, 0.1, 0], [0.01, 0.012, 0.015]))


def three_bodies(frames=("com", "com", "com"), **tree) -> dict:
    """A 3R body-fixed description: joint i turns body i about AXES[i] through its origin, OFFSETS[i] from its
    parent's origin; inertias BODIES (mass, com, principal moments) with the given frame keys (None: no key)."""
    inertia = [{"mass": m, "com": c, "inertia": {"Ixx": i[0], "Iyy": i[1], "Izz": i[2]}, **({"frame": f} if f else {})}
               for (m, c, i), f in zip(BODIES, frames)]
    return {"representation": "body_fixed", "gravity": [0, 0, -9.81],
            "joint_screw_coord": [[*a, 0, 0, 0] for a in AXES],
            "body_ref_config": [{"translation": o} for o in OFFSETS], "mass_inertia": inertia, **tree}


def pinocchio_model(parents, about_com):
    """The 3R robot of :func:`three_bodies` built in Pinocchio: body i on body parents[i] (0: the world); its
    moments are about the centre of mass where about_com[i], else about the body origin (moved to the centre
    of mass here by the parallel-axis theorem)."""
    model = pin.Model()
    model.gravity = pin.Motion(np.array([0, 0, -9.81]), np.zeros(3))
    ids = []
    for i, (parent, axis, offset, (m, c, moments)) in enumerate(zip(parents, AXES, OFFSETS, BODIES)):
        jid = model.addJoint(0 if parent == 0 else ids[parent - 1], pin.JointModelRevoluteUnaligned(np.array(axis, float)),
                             pin.SE3(np.eye(3), np.array(offset, float)), f"q{i + 1}")
        c = np.array(c, float)
        i_c = np.diag(moments) if about_com[i] else np.diag(moments) - m * (c @ c * np.eye(3) - np.outer(c, c))
        model.appendBodyToJoint(jid, pin.Inertia(m, c, i_c), pin.SE3.Identity())
        ids.append(jid)
    return model


def assert_like_pinocchio(robot, model):
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    data = model.createData()
    for q, qd, qdd in np.random.default_rng(7).uniform(-2, 2, (3, 3, 3)):
        np.testing.assert_allclose(np.asarray(dyn.inverse_dynamics(q, qd, qdd)), pin.rnea(model, data, q, qd, qdd),
                                   atol=1e-12)
        m = pin.crba(model, data, q)
        np.testing.assert_allclose(np.asarray(dyn.mass_matrix(q)), np.triu(m) + np.triu(m, 1).T, atol=1e-12)


def test_parent_without_support_is_a_serial_chain_in_the_skidy_dialect():
    data = three_bodies(parent=[0, 1, 1])  # a tree to jaxskid, a chain to Skidy (no support)
    with pytest.warns(jaxskid.DescriptionWarning, match=r"tree\.yaml: parent: ignored as Skidy ignores it"):
        chain = parse_description(data, source="tree.yaml", dialect="skidy")
    assert chain.parents == (-1, 0, 1)
    assert_like_pinocchio(chain, pinocchio_model([0, 1, 2], [True] * 3))
    tree = parse_description(data, source="tree.yaml")
    assert tree.parents == (-1, 0, 0)
    assert_like_pinocchio(tree, pinocchio_model([0, 1, 1], [True] * 3))
    both = parse_description({**data, "support": [[1], [1, 2], [1, 3]]}, source="tree.yaml", dialect="skidy")
    assert both.parents == (-1, 0, 0)  # parent and support together: Skidy's tree


def test_frame_com_carries_over_to_later_bodies_in_the_skidy_dialect():
    data = three_bodies(frames=("body", "com", None))
    skidy = parse_description(data, source="frames.yaml", dialect="skidy")
    assert_like_pinocchio(skidy, pinocchio_model([0, 1, 2], [False, True, True]))
    strict = parse_description(data, source="frames.yaml")
    assert_like_pinocchio(strict, pinocchio_model([0, 1, 2], [False, True, False]))


# ------------------------------------------------------------------------------------------ 4. outputs a Skidy user asks for
RIGHT_ANGLES = jaxskid.__file__.rsplit("/jaxskid/", 1)[0] + "/tests/data/urdf/right_angles.urdf"
TOOL = {"xyzrpy": [0.1, -0.2, 0.05, 0.3, -0.4, 0.5]}


def test_end_effector_on_a_urdf_link_and_the_hybrid_jacobian_of_its_parent_body():
    robot = jaxskid.load(RIGHT_ANGLES, symbolic_inertia=False, end_effectors={"tool": ("tip", TOOL)})
    assert robot.end_effectors == ("tool",)
    dyn = jaxskid.lower(robot, ["ee_pose", "ee_parent_hybrid_jacobian", "ee_parent_hybrid_jacobian_dot"])
    model = pin.buildModelFromUrdf(RIGHT_ANGLES)
    data = model.createData()
    offset = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.4, 0.5), np.array([0.1, -0.2, 0.05]))
    body = model.getFrameId("l2")  # the tip is welded to l2: the tool's parent body
    for q, qd in np.random.default_rng(2).uniform(-2, 2, (3, 2, 2)):
        pin.computeJointJacobiansTimeVariation(model, data, q, qd)
        pin.updateFramePlacements(model, data)
        np.testing.assert_allclose(np.asarray(dyn.ee_pose(q))[0], (data.oMf[model.getFrameId("tip")] * offset).homogeneous,
                                   atol=1e-14)
        jac = pin.getFrameJacobian(model, data, body, pin.LOCAL_WORLD_ALIGNED)  # (v, omega) of l2's origin
        jdot = pin.getFrameJacobianTimeVariation(model, data, body, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(np.asarray(dyn.ee_parent_hybrid_jacobian(q))[0], np.vstack([jac[3:], jac[:3]]),
                                   atol=1e-14)
        np.testing.assert_allclose(np.asarray(dyn.ee_parent_hybrid_jacobian_dot(q, qd))[0],
                                   np.vstack([jdot[3:], jdot[:3]]), atol=1e-13)


def test_cli_end_effector_offset_and_skidy_shapes_landscape_and_project(tmp_path):
    runner = CliRunner()
    shown = runner.invoke(cli, ["info", RIGHT_ANGLES, "--ee", "tool=tip@0.1,-0.2,0.05,0.3,-0.4,pi/6"])
    assert shown.exit_code == 0, shown.output
    assert "tool" in shown.output
    bad = runner.invoke(cli, ["info", RIGHT_ANGLES, "--ee", "tool=tip@0.1,0.2"])
    assert bad.exit_code == 2 and "NAME=LINK@X,Y,Z" in bad.output
    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump(ARM_2R))
    out = tmp_path / "out"
    done = runner.invoke(cli, ["generate", str(path), "-t", "python,latex", "-q", "inverse_dynamics,mass_matrix",
                               "--dialect", "skidy", "--landscape", "--project", "Hopper", "--no-pdf", "-o", str(out)])
    assert done.exit_code == 0, done.output
    assert "coriolis=skidy" in done.output and "shapes=skidy" in done.output
    source = (out / "arm_numpy.py").read_text()
    assert "# Project: Hopper" in source
    namespace: dict = {}
    exec(compile(source, "arm_numpy.py", "exec"), namespace)
    q = np.array([0.3, -0.2])
    tau = namespace["inverse_dynamics"](q, q, q)
    reference = jaxskid.lower(parse_description(ARM_2R, dialect="skidy"), ["inverse_dynamics"])
    assert tau.shape == (2, 1)  # Skidy's column
    np.testing.assert_allclose(tau[:, 0], np.asarray(reference.inverse_dynamics(q, q, q)), atol=1e-13)
    assert namespace["mass_matrix"](q).shape == (2, 2)
    assert r"\usepackage[a4paper,landscape,margin=2cm]{geometry}" in (out / "arm.tex").read_text()


# ------------------------------------------------------------------------------------------ 5. Skidy's looser parsing
def test_assignments_of_assignments_are_resolved_in_the_dialect_and_a_cycle_names_its_keys(tmp_path):
    data = {**KINEMATIC, "assignments": {"L2": "2*L1 - a", "L1": "a + 1/4", "a": 0.05}}
    robot = parse_description(data, source="chain.yaml", dialect="skidy")
    assert robot.default_params() == pytest.approx({"L1": 0.3, "L2": 0.55})
    with pytest.raises(jaxskid.ModelError, match=r"^chain\.yaml: assignments\.L2: expected a number, got '2\*L1 - a'"):
        parse_description(data, source="chain.yaml")
    path = tmp_path / "cycle.yaml"
    path.write_text(yaml.safe_dump({**KINEMATIC, "assignments": {"L1": "L2 / 2", "L2": "3 * b", "b": "L1", "c": 1}}))
    with pytest.raises(jaxskid.ModelError) as info:
        jaxskid.load(path, dialect="skidy")
    err = info.value
    assert err.source == str(path) and err.where == "assignments"
    assert "L1, L2, b" in err.message and "cycle" in err.message and "expected" in err.message


def test_unknown_keys_and_a_prismatic_vec_are_warnings_in_the_dialect_and_errors_outside_it(tmp_path):
    data = {**KINEMATIC, "notes": "from the lab",
            "joint_screw_coord": [{"type": "prismatic", "axis": [1, 0, 0], "vec": [0, 0.1, 0]},
                                  {"type": "revolute", "axis": [0, 0, 1], "vec": ["L1", 0, 0], "limit": 2}]}
    path = tmp_path / "loose.json"
    path.write_text(json.dumps(data))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        robot = jaxskid.load(path, dialect="skidy")
    texts = [str(w.message) for w in record if issubclass(w.category, jaxskid.DescriptionWarning)]
    assert any(t.startswith(f"{path}: notes: unknown key") for t in texts)
    assert any(t.startswith(f"{path}: joint_screw_coord[1].limit: unknown key") for t in texts)
    assert any(t.startswith(f"{path}: joint_screw_coord[0].vec: ignored") for t in texts)
    assert robot.joint_types == ("prismatic", "revolute")
    with pytest.raises(jaxskid.ModelError, match=r"loose\.json: unknown key 'notes'; expected one of"):
        jaxskid.load(path)
    del data["notes"]
    data["joint_screw_coord"][1].pop("limit")
    path.write_text(json.dumps(data))
    with pytest.raises(jaxskid.ModelError, match=r"joint_screw_coord\[0\]\.vec: a prismatic joint takes no vec"):
        jaxskid.load(path)
    with pytest.raises(jaxskid.RequestError, match="dialect: expected one of jaxskid, skidy"):
        jaxskid.load(path, dialect="Skidy")


# ------------------------------------------------------------------------------------------ 6. workflow
NOISY_URDF = """<robot name="noisy">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.05 0 0.0825"/><mass value="1.50004"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.025"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.24998 0 0"/><mass value="0.5"/>
    <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.006"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.50002" rpy="0 0 1.5708"/>
    <axis xyz="0 0 1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.0825 0 0.33332" rpy="0.7854 0 0"/>
    <axis xyz="0 1 0"/></joint>
</robot>
"""


def test_convert_round_at_skidys_tolerance_round_trips(tmp_path):
    urdf, first, second = tmp_path / "noisy.urdf", tmp_path / "noisy.yaml", tmp_path / "again.yaml"
    urdf.write_text(NOISY_URDF)
    runner = CliRunner()
    assert runner.invoke(cli, ["convert", str(urdf), str(first), "--round", "1e-4"]).exit_code == 0
    data = yaml.safe_load(first.read_text())
    assert data["body_ref_config"][0] == {"translation": [0, 0, "1/2"], "rotation": {"rpy": [0, 0, "pi/2"]}}
    assert data["body_ref_config"][1] == {"translation": [0.0825, 0, "1/3"], "rotation": {"rpy": ["pi/4", 0, 0]}}
    expected = round_robot(jaxskid.load(urdf, symbolic_inertia=False), 1e-4)
    assert jaxskid.load(first).fingerprint() == expected.fingerprint()
    assert runner.invoke(cli, ["convert", str(first), str(second), "--round", "1e-4"]).exit_code == 0
    assert second.read_text().splitlines()[1:] == first.read_text().splitlines()[1:]  # a fixed point
    refused = runner.invoke(cli, ["convert", str(urdf), str(tmp_path / "x.yaml"), "--round", "1e-3"])
    assert refused.exit_code == 2 and "0<=x<=0.0001" in refused.output


def test_generate_self_checks_with_random_positive_values_for_parameters_without_a_default(tmp_path):
    data = {**ARM_2R, "body_ref_config": [{"translation": [0, 0, 0]}, {"translation": ["l1", 0, 0]}],
            "joint_screw_coord": [{"type": "revolute", "axis": [0, 0, 1]},
                                  {"type": "revolute", "axis": [0, 0, 1], "vec": ["l1", 0, 0]}],
            "mass_inertia": [{"mass": "m1", "com": ["c1", 0, 0], "inertia": {"index": 1}},
                             {"mass": "m2", "com": ["c2", 0, 0], "inertia": {"index": 2}, "frame": "com"}],
            "assignments": {"l1": 0.5}}
    path = tmp_path / "symbols.yaml"
    path.write_text(yaml.safe_dump(data))
    names = "mass_matrix,coriolis_matrix,coriolis_torques,gravity_torques,inverse_dynamics"
    done = CliRunner().invoke(cli, ["generate", str(path), "-q", names, "-o", str(tmp_path / "out"), "--dialect", "skidy"])
    assert done.exit_code == 0, done.output
    stated = [line for line in done.output.splitlines() if "random positive values" in line]
    assert len(stated) == 1 and "m1=" in stated[0] and "Ixy2=" in stated[0] and "l1=" not in stated[0]
    rows = [line for line in done.output.splitlines() if line.rstrip().endswith((" ok", "FAILED"))]
    assert len(rows) == 4 and all(r.rstrip().endswith(" ok") for r in rows)  # no skew test for Skidy's C
