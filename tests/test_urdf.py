"""read_urdf against Pinocchio's URDF parser (the reference engine), and its error messages.

Kinematics: every link's pose from a product of exponentials over the Robot (C_i = C_parent B_i exp(X_i q_i),
frames C_body offset) equals Pinocchio's ``oMf`` of the link's BODY frame. Inertia: every body's 6x6 matrix
equals ``model.inertias[j]`` with Pinocchio's (v, omega) blocks swapped to (omega, v), merged fixed links
included.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import sympy as sp

import helpers
import jaxskid
from jaxskid import ModelError
from jaxskid.model._lie import STANDARD_PARAMETER_NAMES
from jaxskid.description._urdf import read_urdf

DATA = Path(__file__).parent / "data" / "urdf"
URDFS = {**helpers.URDFS, "branched": DATA / "branched.urdf"}
PANDA = helpers.PANDA
# part-open, unlike helpers.FINGERS, and at two values, so that a swap would show
FINGERS = {"panda_finger_joint1": 0.013, "panda_finger_joint2": 0.031}
SWAP = np.block([[np.zeros((3, 3)), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])  # (v, omega) <-> (omega, v)


# ------------------------------------------------------------------------------------------ helpers


def numeric(m, values) -> np.ndarray:
    subs = {sp.Symbol(k, real=True): v for k, v in values.items()}
    return np.array(sp.Matrix(m).xreplace(subs), dtype=float)


def screw_exp(x: np.ndarray, angle: float) -> np.ndarray:
    """exp([X] angle) with the closed form of Lynch & Park (2017), Prop. 3.25: p = G(angle) v."""
    w, v = x[:3], x[3:]
    out = np.eye(4)
    if np.linalg.norm(w) == 0:
        out[:3, 3] = v * angle
        return out
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    s, c = np.sin(angle), np.cos(angle)
    out[:3, :3] = np.eye(3) + s * W + (1 - c) * W @ W
    out[:3, 3] = (np.eye(3) * angle + (1 - c) * W + (angle - s) * W @ W) @ v
    return out


def link_poses(robot, q) -> dict[str, np.ndarray]:
    """World pose of every link by name: the base, the bodies and the frames."""
    values = robot.default_params()
    body = []
    for i, j in enumerate(robot.joints):
        parent = np.eye(4) if j.parent < 0 else body[j.parent]
        body.append(parent @ numeric(j.origin, values) @ screw_exp(np.array(j.screw, dtype=float), q[i]))
    poses = {robot.base: np.eye(4)}
    poses.update({j.link: body[i] for i, j in enumerate(robot.joints)})
    for f in robot.frames:
        poses[f.name] = (np.eye(4) if f.body < 0 else body[f.body]) @ numeric(f.offset, values)
    return poses


def pin_configuration(model, names, q) -> np.ndarray:
    """Pinocchio's q for joint angles ``q`` in the order ``names`` (continuous joints are (cos, sin))."""
    qp = np.zeros(model.nq)
    for name, value in zip(names, q):
        j = model.joints[model.getJointId(name)]
        qp[j.idx_q : j.idx_q + j.nq] = [value] if j.nq == 1 else [np.cos(value), np.sin(value)]
    return qp


def reference_model(key, lock=None):
    return helpers.pinocchio_urdf_model(URDFS[key], lock)


CASES = [(key, None) for key in URDFS] + [("panda", FINGERS)]
CASE_IDS = [key for key in URDFS] + ["panda_fingers_locked"]


@pytest.fixture(scope="module", params=CASES, ids=CASE_IDS)
def case(request):
    key, lock = request.param
    return (
        read_urdf(URDFS[key], lock=lock),
        read_urdf(URDFS[key], lock=lock, symbolic_inertia=False),
        reference_model(key, lock),
    )


# ------------------------------------------------------------------------------------------ against Pinocchio


def test_joint_order_matches_pinocchio(case):
    robot, numeric_robot, model = case
    assert robot.joint_names == tuple(model.names)[1:]
    assert numeric_robot.joint_names == robot.joint_names
    assert robot.n_dof == model.njoints - 1


def test_link_poses_match_pinocchio_frames(case):
    robot, _, model = case
    data = model.createData()
    rng = np.random.default_rng(0)
    bodies = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
    for _ in range(3):
        q = rng.uniform(-np.pi, np.pi, robot.n_dof)
        poses = link_poses(robot, q)
        assert set(poses) == bodies
        pin.forwardKinematics(model, data, pin_configuration(model, robot.joint_names, q))
        pin.updateFramePlacements(model, data)
        for name, pose in poses.items():
            expected = data.oMf[model.getFrameId(name, pin.FrameType.BODY)].homogeneous
            np.testing.assert_allclose(pose, expected, rtol=0, atol=1e-10, err_msg=name)


def test_inertias_match_pinocchio(case):
    robot, numeric_robot, model = case
    values = robot.default_params()
    for j, jn in zip(robot.joints, numeric_robot.joints):
        expected = SWAP @ model.inertias[model.getJointId(j.name)].matrix() @ SWAP
        assert not jn.inertia.free_symbols
        np.testing.assert_allclose(numeric(jn.inertia, {}), expected, rtol=0, atol=1e-10, err_msg=j.name)
        np.testing.assert_allclose(numeric(j.inertia, values), expected, rtol=0, atol=1e-10, err_msg=j.name)


def test_ten_standard_parameters_per_moving_body(case):
    robot, numeric_robot, model = case
    names = [f"{j.link}_{p}" for j in robot.joints for p in STANDARD_PARAMETER_NAMES]
    assert sorted(robot.parameters) == sorted(names)
    assert set(robot.default_params()) == set(names)
    assert numeric_robot.parameters == ()
    for j in robot.joints:  # Pinocchio's dynamic parameters, in its order (mass, first moments, inertia)
        pi = model.inertias[model.getJointId(j.name)].toDynamicParameters()
        got = [robot.default_params()[f"{j.link}_{p}"] for p in STANDARD_PARAMETER_NAMES]
        np.testing.assert_allclose(got, pi, rtol=0, atol=1e-10, err_msg=j.link)


# ------------------------------------------------------------------------------------------ model contents


def test_panda_fixed_links_frames_and_end_effectors():
    with pytest.warns(jaxskid.DescriptionWarning, match=r"joint\[name=panda_finger_joint2\]\.mimic: .*mimic=True"):
        robot = read_urdf(PANDA)
    assert robot.base == "panda_link0"
    assert robot.n_dof == 9
    assert [(f.name, robot.joints[f.body].link) for f in robot.frames] == [
        ("panda_link8", "panda_link7"), ("panda_hand", "panda_link7"), ("panda_hand_tcp", "panda_link7")
    ]
    assert robot.end_effectors == ("panda_leftfinger", "panda_rightfinger", "panda_hand_tcp")
    # panda_finger_joint2 mimics panda_finger_joint1: read as independent (as Pinocchio's default), and said so
    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxskid.DescriptionWarning)  # locked: no warning
        locked = read_urdf(PANDA, lock=FINGERS, end_effectors=["panda_hand_tcp"])
    assert locked.n_dof == 7 and locked.end_effectors == ("panda_hand_tcp",)
    assert {"panda_leftfinger", "panda_rightfinger"} <= {f.name for f in locked.frames}
    assert len(locked.parameters) == 70


def test_branched_tree_walk_and_massless_link():
    robot = read_urdf(DATA / "branched.urdf", gravity=(0, 0, -1.62))
    # depth-first, children by joint name (urdfdom order), not the file's order (j_b1 comes first there)
    assert robot.joint_names == ("Z_extra", "j_a1", "j_a2", "j_grip", "j_b1", "j_b2")
    assert robot.joint_types == ("revolute",) * 3 + ("prismatic", "revolute", "revolute")
    assert robot.link_names[robot.parents[3]] == "arm_a2"  # the gripper hangs from arm_a2 via two fixed links
    assert robot.gravity == (0, 0, sp.Float(-1.62))
    np.testing.assert_allclose(np.array(robot.joints[3].screw, dtype=float), [0, 0, 0, 0.6, 0.8, 0], atol=1e-15)
    np.testing.assert_allclose(np.array(robot.joints[4].screw, dtype=float), [0, 0, 1, 0, 0, 0], atol=1e-15)
    # arm_a2 has no <inertial>, but tool_mount and tool are welded to it
    assert robot.default_params()["arm_a2_m"] == pytest.approx(0.6, abs=1e-15)
    massless = read_urdf(DATA / "branched.urdf", lock={"j_grip": 0.0}, symbolic_inertia=False)
    assert massless.frame("tool").body == massless.link_names.index("arm_a2")
    # the leaf links, except sensor: it is welded to the base, so its Jacobian is zero
    assert set(massless.end_effectors) == {"extra", "gripper", "arm_b2"}


def test_default_end_effectors_leave_out_links_welded_to_the_world():
    robot = read_urdf(URDFS["ur5"])
    on_world = {robot.base} | {f.name for f in robot.frames if f.body < 0}
    assert "base" in on_world  # base_link-base_fixed_joint welds it to the root
    assert robot.end_effectors and not on_world & set(robot.end_effectors)
    dyn = jaxskid.lower(robot, ["body_jacobian"])
    rng = np.random.default_rng(5)
    jac = np.asarray(dyn.body_jacobian(rng.uniform(-np.pi, np.pi, (8, robot.n_dof))))  # (batch, n_ee, 6, n)
    assert jac.shape[1] == len(robot.end_effectors)
    for k, name in enumerate(robot.end_effectors):
        assert np.abs(jac[:, k]).max() > 0.1, f"{name}: the Jacobian is zero"


def test_right_angles_stay_exact():
    robot = read_urdf(DATA / "branched.urdf", symbolic_inertia=False)
    rotation = robot.joints[robot.joint_names.index("j_a1")].origin[:3, :3]
    assert rotation == sp.Matrix([[0, -1, 0], [1, 0, 0], [0, 0, 1]])


def test_no_output(capsys):
    read_urdf(URDFS["solo12"])
    assert capsys.readouterr() == ("", "")


# ------------------------------------------------------------------------------------------ errors

BAD = [
    ("empty.urdf", None, "empty file"),
    ("binary.urdf", None, "binary data"),
    ("broken_xml.urdf", None, "syntax error at line"),
    ("not_robot.urdf", "robot", "got <sdf>"),
    ("robot_no_name.urdf", "robot.name", "name attribute"),
    ("no_links.urdf", "robot", "at least one <link>"),
    ("link_no_name.urdf", "link[1].name", "name attribute"),
    ("joint_no_name.urdf", "joint[0].name", "name attribute"),
    ("duplicate_link.urdf", "link[name=l1].name", "unique link names"),
    ("duplicate_joint.urdf", "joint[name=j1].name", "unique joint names"),
    ("unknown_parent.urdf", "joint[name=j1].parent", "got 'nowhere'"),
    ("unknown_child.urdf", "joint[name=j2].child", "got 'ghost'"),
    ("missing_child.urdf", "joint[name=j1].child", '<child link="..."/>'),
    ("two_roots.urdf", "robot", "exactly one root link (a link that is no joint's child), got 2: base, loose"),
    ("two_parents.urdf", "joint[name=j2].child", "one parent joint"),
    ("cycle.urdf", "joint[name=j", "cycle of joints"),
    ("planar_joint.urdf", "joint[name=j1].type", "unsupported type 'planar'"),
    ("unknown_type.urdf", "joint[name=j1].type", "expected one of revolute, continuous, prismatic, fixed"),
    ("missing_type.urdf", "joint[name=j1].type", "got no type"),
    ("zero_axis.urdf", "joint[name=j1].axis", "non-zero axis"),
    ("short_axis.urdf", "joint[name=j1].axis", "expected 3 numbers, got '1 0'"),
    ("nan_origin.urdf", "joint[name=j1].origin.xyz", "finite"),
    ("text_rpy.urdf", "joint[name=j1].origin.rpy", "expected 3 numbers"),
    ("no_mass.urdf", "link[name=l1].inertial.mass", "<mass"),
    ("mass_no_value.urdf", "link[name=l1].inertial.mass", "got nothing"),
    ("inf_mass.urdf", "link[name=l1].inertial.mass", "finite"),
    ("negative_mass.urdf", "link[name=l1].inertial.mass", "non-negative mass, got -0.5"),
    ("no_inertia.urdf", "link[name=l1].inertial.inertia", "<inertia"),
    ("inertia_missing_izz.urdf", "link[name=l1].inertial.inertia.izz", "got nothing"),
    ("nan_inertia.urdf", "link[name=l1].inertial.inertia.ixx", "finite"),
    ("non_psd_inertia.urdf", "link[name=l1].inertial.inertia", "positive semi-definite"),
    ("bad_inertial_origin.urdf", "link[name=l1].inertial.origin.rpy", "expected 3 numbers"),
    ("clashing_names.urdf", "link[name=arm_1].name", "'arm-1' and 'arm_1'"),
]


@pytest.mark.parametrize(("filename", "where", "message"), BAD, ids=[b[0] for b in BAD])
def test_bad_file(filename, where, message):
    path = DATA / filename
    with pytest.raises(ModelError) as info:
        read_urdf(path)
    err = info.value
    assert err.source == str(path)
    assert err.where == where or (where is not None and err.where.startswith(where))
    assert message in err.message
    assert str(err).startswith(f"{path}: {where or ''}")
    assert err.__cause__ is None and err.__suppress_context__  # no lxml or yourdfpy traceback attached


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(ModelError, match=r"nope\.urdf: expected an existing URDF file"):
        read_urdf(tmp_path / "nope.urdf")
    with pytest.raises(ModelError, match="got a directory"):
        read_urdf(tmp_path)


@pytest.mark.parametrize(
    ("kwargs", "where", "message"),
    [
        ({"lock": {"panda_joint42": 0.0}}, "lock", "got 'panda_joint42'; joints are panda_joint1"),
        ({"lock": {"panda_joint8": 0.0}}, "lock", "revolute, continuous or prismatic joint, got 'panda_joint8'"),
        ({"lock": {"panda_joint1": float("nan")}}, "lock.panda_joint1", "finite number"),
        ({"lock": {"panda_joint1": "up"}}, "lock.panda_joint1", "finite number, got 'up'"),
        ({"end_effectors": ["panda_hand", "gripper"]}, "end_effectors", "got 'gripper'"),
        ({"gravity": (0, -9.81)}, "gravity", "expected 3 values"),
    ],
)
def test_bad_arguments(kwargs, where, message):
    with pytest.raises(ModelError) as info:
        read_urdf(PANDA, **kwargs)
    assert str(info.value).startswith(f"{PANDA}: {where}: ")
    assert message in info.value.message
