"""The YAML/JSON reader and writer (jaxskid.description._yaml_*): syntax variants, seed robots, round trips, bad input.

Variants are checked against each other and against hand-computed matrices; the seed robots against
textbook closed forms through an independent numeric evaluation (body Jacobians built here with numpy).
"""

from __future__ import annotations

import copy
import warnings
import json
import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import yaml

from jaxskid import Frame, Joint, ModelError, Robot, symbol
from jaxskid.description._yaml_schema import parse_description, parse_extras, read_description, read_extras
from jaxskid.description._yaml_writer import robot_to_dict, write_description

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = sorted((ROOT / "robots").glob("*.yaml"))
DATA = Path(__file__).resolve().parent / "data" / "yaml"


# ---------------------------------------------------------------------------------------------- helpers
def numeric(expr_or_matrix, values) -> np.ndarray:
    subs = {symbol(k): v for k, v in values.items()}
    return np.array(sp.Matrix(expr_or_matrix).xreplace(subs).evalf(), dtype=float)


def same(a, b) -> bool:
    """Exact symbolic equality of two matrices (or vectors), up to simplification."""
    return sp.simplify(sp.Matrix(a) - sp.Matrix(b)).is_zero_matrix


def one_joint(pose=None, inertia=None) -> dict:
    """A one-joint description; ``pose`` and ``inertia`` replace body_ref_config[0] and mass_inertia[0]."""
    return {
        "representation": "body_fixed",
        "gravity": [0, 0, -9.81],
        "joint_screw_coord": [[0, 0, 1, 0, 0, 0]],
        "body_ref_config": [pose if pose is not None else {"translation": [0, 0, 0]}],
        "mass_inertia": [inertia if inertia is not None else {"mass": 1, "inertia": 1}],
    }


def exp_screw(x, q) -> np.ndarray:
    """exp(X q) for a unit revolute (|omega| = 1, omega . v = 0) or prismatic screw (Rodrigues)."""
    w, v = np.asarray(x[:3], float), np.asarray(x[3:], float)
    out = np.eye(4)
    if np.allclose(w, 0):
        out[:3, 3] = v * q
        return out
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    r = np.eye(3) + np.sin(q) * k + (1 - np.cos(q)) * k @ k
    out[:3, :3] = r
    out[:3, 3] = (np.eye(3) - r) @ np.cross(w, v)
    return out


def adjoint(t) -> np.ndarray:
    r, p = t[:3, :3], t[:3, 3]
    px = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    return np.block([[r, np.zeros((3, 3))], [px @ r, r]])


def rigid_body_terms(robot: Robot, q) -> tuple[np.ndarray, np.ndarray, list]:
    """M(q), Q_grav(q) and the body poses, as sums over bodies of J_i^T M_i J_i and -J_i^T M_i (0, R_i^T g)."""
    d = robot.default_params()
    xs = [numeric(j.screw, d).ravel() for j in robot.joints]
    poses = []
    for i, j in enumerate(robot.joints):
        parent = np.eye(4) if j.parent < 0 else poses[j.parent]
        poses.append(parent @ numeric(j.origin, d) @ exp_screw(xs[i], q[i]))
    g = numeric(robot.gravity, d).ravel()
    n = robot.n_dof
    m, qg = np.zeros((n, n)), np.zeros(n)
    for i, j in enumerate(robot.joints):
        jac = np.zeros((6, n))
        for k in robot.support(i):
            jac[:, k] = adjoint(np.linalg.inv(poses[i]) @ poses[k]) @ xs[k]
        m6 = numeric(j.inertia, d)
        m += jac.T @ m6 @ jac
        qg -= jac.T @ m6 @ np.concatenate([np.zeros(3), poses[i][:3, :3].T @ g])
    return m, qg, poses


# ---------------------------------------------------------------------------------------------- syntax
R120 = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]  # 120 degrees about (1, 1, 1)/sqrt(3); Rz(90 deg) Rx(90 deg)
POSE_VARIANTS = {
    "matrix4": [[0, 0, 1, 1], [1, 0, 0, 2], [0, 1, 0, 3], [0, 0, 0, 1]],
    "rotation_matrix": {"rotation": R120, "translation": [1, 2, 3]},
    "axis_angle": {"rotation": {"axis": ["1/sqrt(3)"] * 3, "angle": "2*pi/3"}, "translation": [1, 2, 3]},
    "rpy": {"rotation": {"rpy": ["pi/2", 0, "pi/2"]}, "translation": [1, 2, 3]},
    "quaternion": {"rotation": {"Q": [0.5, 0.5, 0.5, 0.5]}, "translation": [1, 2, 3]},
    "xyzrpy": {"xyzrpy": [1, 2, 3, "pi/2", 0, "pi/2"]},
}


@pytest.mark.parametrize("variant", sorted(POSE_VARIANTS))
def test_pose_variants_give_the_same_pose(variant):
    robot = parse_description(one_joint(pose=POSE_VARIANTS[variant]), source=f"{variant}.yaml")
    expected = sp.Matrix([[0, 0, 1, 1], [1, 0, 0, 2], [0, 1, 0, 3], [0, 0, 0, 1]])
    assert same(robot.joints[0].origin, expected)


def test_rotation_and_translation_may_be_omitted():
    identity = parse_description(one_joint(pose={}), source="r.yaml").joints[0].origin
    only_t = parse_description(one_joint(pose={"translation": [1, 2, 3]}), source="r.yaml").joints[0].origin
    only_r = parse_description(one_joint(pose={"rotation": R120}), source="r.yaml").joints[0].origin
    assert identity == sp.eye(4)
    assert only_t == sp.Matrix([[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]])
    assert only_r[:3, :3] == sp.Matrix(R120) and only_r[:3, 3] == sp.zeros(3, 1)


def test_screw_variants_agree():
    m, c = sp.symbols("m c", real=True)
    forms = [
        {"type": "revolute", "axis": [0, 1, 0], "vec": ["c", 0, 0]},
        [0, 1, 0, 0, 0, "c"],  # v = vec x axis = (c, 0, 0) x (0, 1, 0)
    ]
    screws = []
    for form in forms:
        d = one_joint(inertia={"mass": "m", "inertia": 1})
        d["joint_screw_coord"] = [form]
        screws.append(parse_description(d, source="screw.yaml").joints[0].screw)
    assert screws[0] == screws[1] == (0, 1, 0, 0, 0, c)
    d = one_joint()
    d["joint_screw_coord"] = [{"type": "prismatic", "axis": [0, 0, 1]}]
    robot = parse_description(d, source="screw.yaml")
    assert robot.joints[0].type == "prismatic" and robot.joints[0].screw == (0, 0, 0, 0, 0, 1)


def hand_mass_inertia(m, c, i_origin) -> np.ndarray:
    """[[I_o, m c~], [-m c~, m 1]], written out entry by entry."""
    cx, cy, cz = c
    mcx = m * np.array([[0, -cz, cy], [cz, 0, -cx], [-cy, cx, 0]])
    return np.block([[np.asarray(i_origin, float), mcx], [-mcx, m * np.eye(3)]])


M, COM = 2.0, [0.1, -0.2, 0.3]
I_COM = [[0.1, 0.01, 0.02], [0.01, 0.2, 0.03], [0.02, 0.03, 0.3]]
I_ORIGIN = np.array(I_COM) + M * (np.dot(COM, COM) * np.eye(3) - np.outer(COM, COM))  # parallel axis
EXPECTED_6X6 = hand_mass_inertia(M, COM, I_ORIGIN)
INERTIA_VARIANTS = {
    "matrix6": EXPECTED_6X6.tolist(),
    "matrix3_body": {"mass": M, "com": COM, "inertia": I_ORIGIN.tolist()},
    "matrix3_body_explicit": {"mass": M, "com": COM, "inertia": I_ORIGIN.tolist(), "frame": "body"},
    "matrix3_com": {"mass": M, "com": COM, "inertia": I_COM, "frame": "com"},
    "six_values_com": {"mass": M, "com": COM, "frame": "com",
                       "inertia": [0.1, 0.01, 0.02, 0.2, 0.03, 0.3]},
    "dict_com": {"mass": M, "com": COM, "frame": "com",
                 "inertia": {"Ixx": 0.1, "Ixy": 0.01, "Ixz": 0.02, "Iyy": 0.2, "Iyz": 0.03, "Izz": 0.3}},
}
# I_COM in the axes of a COM frame turned by R120 (its x, y, z axes are the body's y, z, x), written out by
# hand: I'_xx = I_yy, I'_yy = I_zz, I'_zz = I_xx, I'_xy = I_yz, I'_xz = I_yx, I'_yz = I_zx
I_COM_TURNED = [[0.2, 0.03, 0.01], [0.03, 0.3, 0.02], [0.01, 0.02, 0.1]]
INERTIA_VARIANTS.update({
    f"rotated_com_{name}": {"mass": M, "com": COM, "frame": "com", "inertia": I_COM_TURNED,
                            "rotation": POSE_VARIANTS[name]["rotation"]}
    for name in ("rotation_matrix", "axis_angle", "rpy", "quaternion")
})


@pytest.mark.parametrize("variant", sorted(INERTIA_VARIANTS))
def test_inertia_variants_match_the_hand_computed_matrix(variant):
    robot = parse_description(one_joint(inertia=INERTIA_VARIANTS[variant]), source=f"{variant}.yaml")
    np.testing.assert_allclose(numeric(robot.joints[0].inertia, {}), EXPECTED_6X6, rtol=0, atol=1e-14)


def test_com_rotation_is_symbolic_and_applies_only_with_frame_com():
    a, b, c, t = (symbol(x) for x in ("A", "B", "C", "t"))
    turned = {"mass": 1, "frame": "com", "inertia": [["A", 0, 0], [0, "B", 0], [0, 0, "C"]],
              "rotation": {"axis": [0, 0, 1], "angle": "t"}}
    robot = parse_description(one_joint(inertia=turned), source="r.yaml")
    ct, st = sp.cos(t), sp.sin(t)  # Rz(t) diag(A, B, C) Rz(t)^T
    expected = sp.Matrix([[a * ct**2 + b * st**2, (a - b) * ct * st, 0],
                          [(a - b) * ct * st, a * st**2 + b * ct**2, 0], [0, 0, c]])
    assert same(robot.joints[0].inertia[:3, :3], expected)
    import jaxskid

    plain = parse_description(one_joint(inertia={"mass": M, "com": COM, "inertia": I_ORIGIN.tolist()}), source="r.yaml")
    ignored = {"mass": M, "com": COM, "inertia": I_ORIGIN.tolist(), "frame": "body", "rotation": R120}
    with pytest.warns(jaxskid.DescriptionWarning, match=r"r\.yaml: mass_inertia\[0\]\.rotation: ignored, as Skidy"):
        assert parse_description(one_joint(inertia=ignored), source="r.yaml") == plain
    bad = {"mass": 1, "frame": "com", "inertia": 1, "rotation": [[1, 0, 0], [0, 2, 0], [0, 0, 1]]}
    with pytest.raises(ModelError, match=r"r\.yaml: mass_inertia\[0\]\.rotation: expected a rotation matrix"):
        parse_description(one_joint(inertia=bad), source="r.yaml")


def test_symbolic_inertia_shortcuts():
    k, i1 = symbol("k"), symbol("I1")
    scalar = parse_description(one_joint(inertia={"mass": "k", "inertia": "k/10"}), source="r.yaml")
    assert scalar.joints[0].inertia[:3, :3] == sp.eye(3) * k / 10
    point = parse_description(one_joint(inertia={"mass": 1, "inertia": {"index": 1, "pointmass": True}}),
                              source="r.yaml")
    assert point.joints[0].inertia[:3, :3] == sp.eye(3) * i1
    full = parse_description(one_joint(inertia={"mass": 1, "inertia": {"index": 1}}), source="r.yaml")
    names = [["Ixx1", "Ixy1", "Ixz1"], ["Ixy1", "Iyy1", "Iyz1"], ["Ixz1", "Iyz1", "Izz1"]]
    assert full.joints[0].inertia[:3, :3] == sp.Matrix(3, 3, lambda r, c: symbol(names[r][c]))
    partial = parse_description(one_joint(inertia={"mass": 1, "inertia": {"Izz": "J"}}), source="r.yaml")
    assert partial.joints[0].inertia[:3, :3] == sp.diag(0, 0, symbol("J"))


def test_spatial_and_body_fixed_descriptions_agree():
    spatial = read_description(DATA / "rrp_spatial.yaml")
    body = read_description(DATA / "rrp_body_fixed.yaml")
    assert [j.type for j in spatial.joints] == [j.type for j in body.joints] == ["revolute", "revolute", "prismatic"]
    for js, jb in zip(spatial.joints, body.joints):
        assert same(js.origin, jb.origin)
        assert same(js.screw, jb.screw)
    assert spatial.gravity == body.gravity
    assert same(spatial.frame("ee").offset, body.frame("ee").offset)
    # the hand-computed spatial screws and poses agree with forward kinematics of the body-fixed model
    _, _, poses = rigid_body_terms(body, np.zeros(3))
    np.testing.assert_allclose(poses[2][:3, 3], [0, 0.3, 0.7], atol=1e-14)


def test_end_effector_forms_and_parents():
    d = one_joint()
    d["ee"] = {"translation": [1, 0, 0]}
    single = parse_description(d, source="ee.yaml")
    assert single.end_effectors == ("ee",) and single.frame("ee").body == 0
    d["ee"] = [{"translation": [1, 0, 0]}, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2], [0, 0, 0, 1]]]
    d["ee_parent"] = [1, 0]
    d["ee_names"] = ["tool", "camera"]
    two = parse_description(d, source="ee.yaml")
    assert two.end_effectors == ("tool", "camera")
    assert two.frame("tool").body == 0 and two.frame("camera").body == -1
    assert two.frame("camera").offset[2, 3] == 2


def test_single_matrix_ee_defaults_to_the_last_body_and_frames_key_adds_frames():
    d = yaml.safe_load((ROOT / "robots" / "arm_2r.yaml").read_text())
    del d["ee_parent"], d["ee_names"]
    d["ee"] = [[0, -1, 0, "l2"], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    d["frames"] = [{"name": "camera", "parent": 1, "pose": {"translation": ["l1/2", 0, 0]}}, {"name": "mount", "parent": 0}]
    robot = parse_description(d, source="arm.yaml")
    assert robot.end_effectors == ("ee",) and robot.frame("ee").body == 1
    assert robot.frame("ee").offset[:2, :2] == sp.Matrix([[0, -1], [1, 0]])
    assert robot.frame("camera").body == 0 and robot.frame("camera").offset[0, 3] == symbol("l1") / 2
    assert robot.frame("mount").body == -1 and robot.frame("mount").offset == sp.eye(4)
    d["frame_order"] = ["mount", "ee", "camera"]
    assert [f.name for f in parse_description(d, source="arm.yaml").frames] == ["mount", "ee", "camera"]


def test_joint_and_link_names_come_from_q_or_the_extension_keys():
    d = one_joint()
    assert parse_description(d, source="arm.yaml").joint_names == ("q1",)
    assert parse_description(d, source="arm.yaml").name == "arm"
    d["q"] = ["theta"]
    assert parse_description(d, source="arm.yaml").joint_names == ("theta",)
    d.update(joint_names=["waist"], link_names=["column"], name="my_arm")
    robot = parse_description(d, source="arm.yaml")
    assert (robot.joint_names, robot.link_names, robot.name) == (("waist",), ("column",), "my_arm")


def test_skidy_template_reads_from_yaml_and_json_alike():
    from_yaml = read_description(DATA / "skidy_template_rp.yaml")
    from_json = read_description(DATA / "skidy_template_rp.json")
    assert from_yaml == from_json
    assert from_yaml.joint_types == ("revolute", "prismatic")
    assert from_yaml.gravity == (0, 0, -symbol("g"))
    extras = read_extras(DATA / "skidy_template_rp.yaml")
    assert extras.q == ("q1", "q2") and extras.q4d == ("ddddq1", "ddddq2")
    fx, mz = symbol("Fx"), symbol("Mz")
    assert extras.end_effectors == ("ee",)
    assert extras.wrench[0][2] == mz and extras.wrench[0][3] == fx
    assert extras.wrench_d[0][3] == symbol("dFx") and extras.wrench_2d == ((0,) * 6,)


def test_extras_broadcast_one_wrench_and_take_one_per_end_effector():
    d = one_joint()
    d.update(ee=[{}, {}], WEE=[0, 0, 0, "F", 0, 0], WDEE=[[1, 0, 0, 0, 0, 0], [0, 2, 0, 0, 0, 0]])
    extras = parse_extras(d, source="w.yaml")
    assert extras.end_effectors == ("ee1", "ee2")
    assert extras.wrench == ((0, 0, 0, symbol("F"), 0, 0),) * 2
    assert extras.wrench_d[1] == (0, 2, 0, 0, 0, 0)
    assert extras.qd == ("dq1",)


def test_assignments_accept_expressions_of_numbers():
    d = one_joint(pose={"rotation": {"axis": [0, 0, 1], "angle": "alpha"}})
    d["assignments"] = {"alpha": "pi/2", "beta": 2}
    robot = parse_description(d, source="a.yaml")
    assert dict(robot.defaults) == {"alpha": pytest.approx(np.pi / 2), "beta": 2.0}


def test_lock_from_the_file_and_from_the_argument():
    d = yaml.safe_load((ROOT / "robots" / "arm_2r.yaml").read_text())
    d["lock"] = {"elbow": 0}
    locked = parse_description(d, source="arm_2r.yaml")
    assert locked.joint_names == ("shoulder",) and "link2" in locked.frame_names
    overridden = parse_description(d, source="arm_2r.yaml", lock={"elbow": "pi/2", "shoulder": 0})
    assert overridden.n_dof == 0
    assert overridden.frame("tip").offset[:3, 3] == sp.Matrix([symbol("l1"), symbol("l2"), 0])


# ---------------------------------------------------------------------------------------------- seed robots
@pytest.mark.parametrize("path", ROBOTS, ids=[p.stem for p in ROBOTS])
def test_seed_robot_loads_with_named_end_effectors_and_defaults(path):
    robot = read_description(path)
    assert robot.n_dof >= 1
    assert robot.end_effectors and not any(re.fullmatch(r"ee\d*", name) for name in robot.end_effectors)
    assert set(robot.parameters) == set(robot.default_params())  # every parameter has a default
    assert "lock" not in yaml.safe_load(path.read_text())
    m, _, _ = rigid_body_terms(robot, np.random.default_rng(0).uniform(-1, 1, robot.n_dof))
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_seed_robots_mix_syntaxes():
    texts = {p.stem: yaml.safe_load(p.read_text()) for p in ROBOTS}
    representations = {d.get("representation", "spatial") for d in texts.values()}
    assert representations == {"spatial", "body_fixed"}
    assert len(ROBOTS) == 9


def test_single_pendulum_matches_the_textbook():
    robot = read_description(ROOT / "robots" / "single_pendulum.yaml")
    d = robot.default_params()
    for q in (0.0, 0.4, -2.0):
        m, qg, _ = rigid_body_terms(robot, [q])
        np.testing.assert_allclose(m, [[d["m"] * d["l"] ** 2]], rtol=1e-13)
        np.testing.assert_allclose(qg, [d["m"] * d["g"] * d["l"] * np.sin(q)], rtol=1e-13, atol=1e-15)


def test_double_pendulum_matches_the_textbook():
    robot = read_description(ROOT / "robots" / "double_pendulum.yaml")
    p = robot.default_params()
    m1, m2, l1, l2, i1, i2, g = (p[k] for k in ("m1", "m2", "l1", "l2", "I1", "I2", "g"))
    for q1, q2 in [(0.3, -0.7), (1.2, 2.0)]:
        m, qg, _ = rigid_body_terms(robot, [q1, q2])
        c2 = np.cos(q2)
        expected_m = [[i1 + i2 + m1 * l1**2 + m2 * (l1**2 + l2**2 + 2 * l1 * l2 * c2), i2 + m2 * (l2**2 + l1 * l2 * c2)],
                      [i2 + m2 * (l2**2 + l1 * l2 * c2), i2 + m2 * l2**2]]
        expected_g = [(m1 + m2) * g * l1 * np.sin(q1) + m2 * g * l2 * np.sin(q1 + q2), m2 * g * l2 * np.sin(q1 + q2)]
        np.testing.assert_allclose(m, expected_m, rtol=1e-13)
        np.testing.assert_allclose(qg, expected_g, rtol=1e-12)


def test_arm_2r_matches_the_textbook():
    robot = read_description(ROOT / "robots" / "arm_2r.yaml")
    p = robot.default_params()
    m1, m2, l1, l2, g = (p[k] for k in ("m1", "m2", "l1", "l2", "g"))
    for q1, q2 in [(0.0, 0.0), (0.5, -1.1), (-2.0, 2.5)]:
        m, qg, _ = rigid_body_terms(robot, [q1, q2])
        c2 = np.cos(q2)
        expected_m = [[m1 * l1**2 + m2 * (l1**2 + 2 * l1 * l2 * c2 + l2**2), m2 * (l1 * l2 * c2 + l2**2)],
                      [m2 * (l1 * l2 * c2 + l2**2), m2 * l2**2]]
        expected_g = [(m1 + m2) * g * l1 * np.cos(q1) + m2 * g * l2 * np.cos(q1 + q2), m2 * g * l2 * np.cos(q1 + q2)]
        np.testing.assert_allclose(m, expected_m, rtol=1e-13)
        np.testing.assert_allclose(qg, expected_g, rtol=1e-12, atol=1e-14)


def test_hopping_leg_rail_holds_the_whole_weight_against_gravity_along_x():
    robot = read_description(ROOT / "robots" / "hopping_leg.yaml")
    p = robot.default_params()
    _, qg, poses = rigid_body_terms(robot, [0.1, 0.3, -0.6])
    np.testing.assert_allclose(qg[0], (p["m0"] + p["m1"] + p["m2"]) * p["g"], rtol=1e-13)
    np.testing.assert_allclose(poses[0][:3, 3], [-0.1, 0, 0], atol=1e-15)  # a positive q1 lifts the leg (x down)
    foot = poses[2] @ numeric(robot.frame("foot").offset, p)
    np.testing.assert_allclose(foot[:3, 3], [-0.1 + p["L1"] * np.cos(0.3) + p["L2"] * np.cos(-0.3),
                                             p["L1"] * np.sin(0.3) + p["L2"] * np.sin(-0.3), 0], atol=1e-14)


def test_quadruped_feet_and_tree():
    robot = read_description(ROOT / "robots" / "quadruped_12dof.yaml")
    p = robot.default_params()
    assert robot.parents == (-1, 0, 1, -1, 3, 4, -1, 6, 7, -1, 9, 10) and robot.base == "trunk"
    _, _, poses = rigid_body_terms(robot, np.zeros(12))
    assert len(robot.end_effectors) == 4  # one foot per leg, in the order zipped below
    for name, (sx, sy) in zip(robot.end_effectors, [(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        frame = robot.frame(name)
        foot = poses[frame.body] @ numeric(frame.offset, p)
        np.testing.assert_allclose(foot[:3, 3], [sx * p["hip_x"], sy * (p["hip_y"] + p["abad_len"]),
                                                 -p["l_thigh"] - p["l_calf"]], atol=1e-15)
    leg_mass = sum(float(numeric(j.inertia, p)[5, 5]) for j in robot.joints[:3])
    assert 1.0 < leg_mass < 3.0


# ---------------------------------------------------------------------------------------------- writer
def test_every_seed_robot_round_trips_exactly(tmp_path):
    for path in ROBOTS:
        robot = read_description(path)
        assert parse_description(robot_to_dict(robot), source=path.name) == robot
        for suffix in (".yaml", ".json"):
            out = tmp_path / f"{path.stem}{suffix}"
            write_description(robot, out)
            back = read_description(out)
            assert back == robot and back.fingerprint() == robot.fingerprint()


def test_round_trip_keeps_merged_frames_order_floats_and_constants(tmp_path):
    a, b = symbol("a"), symbol("b")
    x = (0, 0, 1, 0, 0, 0)
    body = sp.diag(0.1 + 0.2, 0.7, 1 / sp.Integer(3), 1, 1, 1)  # 0.30000000000000004 must survive
    joints = [
        Joint("j1", "revolute", -1, sp.eye(4), x, body, "l1"),
        Joint("fixed", "fixed", 0, sp.Matrix([[1, 0, 0, a], [0, 1, 0, 0], [0, 0, 1, sp.E], [0, 0, 0, 1]]), None,
              sp.zeros(6), "flange"),
        Joint("j2", "prismatic", 1, sp.Matrix([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, sp.sqrt(2) * b / 3], [0, 0, 0, 1]]),
              (0, 0, 0, 1, 0, 0), sp.diag(b, b, b, 1e-3, 1e-3, 1e-3) * 7, "l2"),
    ]
    frames = [Frame("camera", 0, sp.Matrix([[1, 0, 0, -0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]))]
    robot = Robot.create("odd", joints, gravity=(0, "-g*sin(b)", 0), frames=frames,
                         end_effectors=("flange", "l2", "camera", "floor"), defaults={"a": 0.25, "b": 1.5},
                         base="floor")
    assert [f.name for f in robot.frames] == ["camera", "flange"]  # the merged link comes after the user's frame
    data = robot_to_dict(robot)
    assert data["frame_order"] == ["camera", "flange"] and data["base"] == "floor"
    assert data["mass_inertia"][0][0][0] == 0.1 + 0.2
    assert parse_description(data, source="odd.yaml") == robot
    write_description(robot, tmp_path / "odd.yaml")
    assert read_description(tmp_path / "odd.yaml") == robot


def test_locked_robot_round_trips(tmp_path):
    robot = read_description(ROOT / "robots" / "hopping_leg.yaml", lock={"rail": 0.1})
    assert "slider" in robot.frame_names
    write_description(robot, tmp_path / "locked.yaml")
    assert read_description(tmp_path / "locked.yaml") == robot
    assert "frame_order" not in (tmp_path / "locked.yaml").read_text()


def test_writer_emits_numbers_and_strings_in_skidy_schema(tmp_path):
    robot = read_description(ROOT / "robots" / "arm_2r.yaml")
    write_description(robot, tmp_path / "arm.json")
    data = json.loads((tmp_path / "arm.json").read_text())
    assert data["representation"] == "body_fixed" and data["gravity"] == [0, "-g", 0]
    assert data["body_ref_config"][1][0] == [1, 0, 0, "l1"]
    assert data["mass_inertia"][1][5][5] == "m2" and len(data["mass_inertia"][1]) == 6
    assert data["ee"] == [[[1, 0, 0, "l2"], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]] and data["ee_parent"] == [2]
    assert data["assignments"]["g"] == 9.81 and data["joint_names"] == ["shoulder", "elbow"]


def test_writer_refuses_to_overwrite_without_force(tmp_path):
    robot = read_description(ROOT / "robots" / "single_pendulum.yaml")
    out = tmp_path / "pendulum.yaml"
    out.write_text("keep me\n")
    with pytest.raises(FileExistsError, match="pendulum.yaml.*force=True"):
        write_description(robot, out)
    assert out.read_text() == "keep me\n"
    write_description(robot, out, force=True)
    assert read_description(out) == robot
    with pytest.raises(ModelError, match="pendulum.txt.*expected a file name ending in .yaml"):
        write_description(robot, tmp_path / "pendulum.txt")


# ---------------------------------------------------------------------------------------------- bad input
BASE = yaml.safe_load((ROOT / "robots" / "arm_2r.yaml").read_text())


def edit(**changes):
    """arm_2r.yaml with top-level keys replaced (None removes a key) or nested values set by path."""
    d = copy.deepcopy(BASE)
    for key, value in changes.items():
        if "__" in key:  # body_ref_config__1__0__3 = ... sets d["body_ref_config"][1][0][3]
            *path, last = [int(p) if p.isdigit() else p for p in key.split("__")]
            target = d
            for p in path:
                target = target[p]
            target[last] = value
        elif value is None:
            d.pop(key)
        else:
            d[key] = value
    return yaml.safe_dump(d, sort_keys=False)


RRR = {"joint_screw_coord": [[0, 0, 1, 0, 0, 0]] * 3, "body_ref_config": [{}] * 3,
       "mass_inertia": [{"mass": 1, "inertia": 1}] * 3, "gravity": [0, 0, -9.81]}

BAD = {
    # (file text, key path, part of the message)
    "empty": ("", None, "empty"),
    "comments_only": ("# nothing here\n", None, "empty"),
    "top_level_list": ("- 1\n- 2\n", None, "expected a mapping of keys at the top level, got a list"),
    "yaml_syntax": ("gravity: [0, 0, -9.81]\njoint_screw_coord:\n  - [0, 0, 1\nbody_ref_config: []\n", None, "line 4"),
    "yaml_duplicate_key": ("gravity: [0, 0, 1]\ngravity: [0, 0, 2]\n", None, "duplicate key 'gravity'"),
    "unknown_key": (edit(gravitation=[0, 0, 1]), None, "unknown key 'gravitation'"),
    "missing_screws": (edit(joint_screw_coord=None), "joint_screw_coord", "required key is missing"),
    "missing_poses": (edit(body_ref_config=None), "body_ref_config", "required key is missing"),
    "missing_gravity": (edit(gravity=None), "gravity", "required key is missing"),
    "screws_not_a_list": (edit(joint_screw_coord=5), "joint_screw_coord", "expected a non-empty list"),
    "gravity_size": (edit(gravity=[0, -9.81]), "gravity", "expected 3 values, got 2"),
    "inertia_five_values": (edit(mass_inertia__1__inertia=[1, 0, 0, 1, 0]), "mass_inertia[1].inertia", "expected 6 values, got 5"),
    "inertia_wrong_type": (edit(mass_inertia__1__inertia=True), "mass_inertia[1].inertia", "got true"),
    "fewer_poses": (edit(body_ref_config=BASE["body_ref_config"][:1]), "body_ref_config", "expected 2 entries"),
    "fewer_inertias": (edit(mass_inertia=BASE["mass_inertia"][:1]), "mass_inertia", "expected 2 entries"),
    "q_length": (edit(q=["a", "b", "c"]), "q", "expected 2 names"),
    "nan": (edit(gravity=[0, float("nan"), 0]), "gravity[1]", "finite"),
    "inf_string": (edit(gravity=[0, "oo", 0]), "gravity[1]", "finite"),
    "inf_assignment": (edit(assignments={"g": float("inf")}), "assignments.g", "finite"),
    "division_by_zero": (edit(body_ref_config__1__0__3="l1/0"), "body_ref_config[1][0][3]", "finite"),
    "negative_mass": (edit(mass_inertia__0__mass=-1), "mass_inertia[0].mass", "non-negative mass"),
    "negative_default_mass": (edit(assignments={**BASE["assignments"], "m2": -0.5}), "mass_inertia[1].mass", "non-negative"),
    "not_positive_definite": (edit(mass_inertia__1__inertia=[1, 0, 0, 1, 0, -1]), "mass_inertia[1]", "positive definite"),
    "six_by_six_block": (edit(mass_inertia__0=[[1, 0, 0, 0, 0, 0]] * 6), "mass_inertia[0]", "symmetric"),
    "non_unit_axis": (edit(joint_screw_coord__0__axis=[0, 0, 2]), "joint_screw_coord[0].axis", "unit axis, got norm 2"),
    "non_unit_screw": (edit(joint_screw_coord__1=[0, 0, 0.5, 0, 0, 0]), "joint_screw_coord[1]", "unit rotation axis"),
    "helical_screw": (edit(joint_screw_coord__1=[0, 0, 1, 0, 0, 0.2]), "joint_screw_coord[1]", "helical"),
    "unknown_joint_type": (edit(joint_screw_coord__0__type="spherical"), "joint_screw_coord[0].type", "unknown joint type 'spherical'"),
    "prismatic_with_vec": (edit(joint_screw_coord__0={"type": "prismatic", "axis": [1, 0, 0], "vec": [0, 0, 0]}),
                           "joint_screw_coord[0].vec", "takes no vec"),
    "parent_cycle": (yaml.safe_dump({**RRR, "parent": [3, 1, 2]}), "parent", "cycle: body 1 -> body 3 -> body 2 -> body 1"),
    "parent_self": (yaml.safe_dump({**RRR, "parent": [0, 2, 1]}), "parent", "cycle: body 2 -> body 2"),
    "forward_reference": (yaml.safe_dump({**RRR, "parent": [0, 3, 0]}), "parent[1]", "body 2's parent is body 3, which comes after it"),
    "parent_range": (edit(parent=[0, 7]), "parent[1]", "expected a body index in 0..2"),
    "support_mismatch": (edit(parent=[0, 1], support=[[1], [2]]), "support[1]", "expected [1, 2]"),
    "duplicate_joint_names": (edit(joint_names=["a", "a"]), "joint_names[1]", "duplicate name 'a'"),
    "duplicate_link_names": (edit(link_names=["arm", "arm"]), "link_names[1]", "duplicate name 'arm'"),
    "frame_named_like_a_link": (edit(ee_names=["link1"]), "ee_names[0]", "duplicate frame name 'link1'"),
    "unknown_representation": (edit(representation="world"), "representation", "expected spatial or body_fixed"),
    "unparsable": (edit(body_ref_config__1__0__3="l1 +* 2"), "body_ref_config[1][0][3]", "'l1 +* 2'"),
    "code_injection": (edit(body_ref_config__1__0__3="__import__('os').getcwd()"), "body_ref_config[1][0][3]",
                       "expected an arithmetic expression"),
    "attribute_access": (edit(body_ref_config__1__0__3="pi.evalf(10)"), "body_ref_config[1][0][3]", "arithmetic"),
    "unknown_function": (edit(body_ref_config__1__0__3="f(l1)"), "body_ref_config[1][0][3]", "unknown function 'f'"),
    "joint_variable_as_parameter": (edit(body_ref_config__1__0__3="shoulder"), "body_ref_config[1][0][3]", "joint variable"),
    "complex_value": (edit(gravity=[0, "sqrt(-9.81)", 0]), "gravity[1]", "real value"),
    "boolean_mass": (edit(mass_inertia__0__mass=True), "mass_inertia[0].mass", "got true"),
    "not_a_rotation": (edit(body_ref_config__0={"rotation": [[1, 0, 0], [0, 2, 0], [0, 0, 1]]}),
                       "body_ref_config[0].rotation", "rotation matrix"),
    "reflection": (edit(body_ref_config__0={"rotation": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]}), "body_ref_config[0].rotation", "determinant +1"),
    "non_unit_quaternion": (edit(body_ref_config__0={"rotation": {"Q": [1, 1, 0, 0]}}), "body_ref_config[0].rotation.Q", "unit quaternion"),
    "two_rotation_forms": (edit(body_ref_config__0={"rotation": {"Q": [1, 0, 0, 0], "rpy": [0, 0, 0]}}),
                           "body_ref_config[0].rotation", "exactly one of Q, rpy or axis"),
    "pose_last_row": (edit(body_ref_config__1__3=[0, 0, 0, 2]), "body_ref_config[1][3]", "last row"),
    "pose_rows": (edit(body_ref_config__1=[[1, 0, 0, 0]] * 3), "body_ref_config[1]", "4 rows, got 3"),
    "xyzrpy_size": (edit(body_ref_config__0={"xyzrpy": [0, 0, 0]}), "body_ref_config[0].xyzrpy", "expected 6 values, got 3"),
    "ee_parent_range": (edit(ee_parent=[3]), "ee_parent[0]", "expected a body index in 0..2"),
    "ee_names_length": (edit(ee_names=["a", "b"]), "ee_names", "expected 1 name(s), one per ee"),
    "wrench_size": (edit(WEE=[1, 2, 3]), "WEE", "expected 6 values, got 3"),
    "assignment_with_symbols": (edit(assignments={"m1": "2*m2"}), "assignments.m1", "depends on m2"),
    "assignment_of_joint_variable": (edit(assignments={"elbow": 1}), "assignments.elbow", "joint variable"),
    "inertia_frame": (edit(mass_inertia__0__frame="world"), "mass_inertia[0].frame", "expected body"),
    "lock_unknown_joint": (edit(lock={"wrist": 0}), "lock", "cannot lock unknown joint(s) 'wrist'"),
    "gravity_twice": (edit(gravity_vector=[0, 0, 1]), "gravity", "either gravity or gravity_vector"),
    "absurd_magnitude": (edit(mass_inertia__1__com=[0, "2**1000", 0]), "mass_inertia[1].com[1]", "check the units"),
    "wrench_without_ee": (edit(ee=None, ee_parent=None, ee_names=None, WEE=[0, 0, 0, 1, 0, 0]), "WEE", "no ee"),
    "frame_parent_range": (edit(frames=[{"name": "cam", "parent": -1}]), "frames[0].parent", "expected a body index"),
    "frame_order_names": (edit(frames=[{"name": "cam", "parent": 1}], frame_order=["cam"]), "frame_order",
                          "expected the names ['tip', 'cam'] in some order"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_names_file_key_and_expectation(tmp_path, case):
    text, where, message = BAD[case]
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    with pytest.raises(ModelError) as info:
        read_description(path)
    err = info.value
    assert str(err).startswith(f"{path}: ")
    assert message in str(err)
    if where is not None:
        assert err.where == where and f": {where}: " in str(err)


def test_yaml_syntax_error_reports_the_line(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text("gravity: [0, 0, -9.81]\nrepresentation: spatial\n  joint_screw_coord: bad\n")
    with pytest.raises(ModelError, match=r"robot\.yaml: line 3, column \d+: invalid YAML"):
        read_description(path)


@pytest.mark.parametrize("content, message", [
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "expected a text file (YAML or JSON), found binary data"),
    (b"gravity: [0, 0, -9.81\xff]\n", "expected UTF-8 text"),
])
def test_unreadable_bytes(tmp_path, content, message):
    path = tmp_path / "robot.yaml"
    path.write_bytes(content)
    with pytest.raises(ModelError) as info:
        read_description(path)
    assert str(info.value).startswith(f"{path}: {message}")


def test_json_errors_name_the_file_and_line(tmp_path):
    path = tmp_path / "robot.json"
    path.write_text('{\n  "gravity": [0, 0, -9.81],\n  "joint_screw_coord": [1, 2,\n}\n')
    with pytest.raises(ModelError, match=r"robot\.json: line 4, column \d+: invalid JSON"):
        read_description(path)
    path.write_text('{"gravity": [0, 0, 1], "gravity": [0, 0, 2]}')
    with pytest.raises(ModelError, match="robot.json: invalid JSON: duplicate key 'gravity'"):
        read_description(path)


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(ModelError, match="nowhere.yaml: cannot read the file"):
        read_description(tmp_path / "nowhere.yaml")
    (tmp_path / "robot.urdf").write_text("<robot/>")
    with pytest.raises(ModelError, match="robot.urdf: expected a .yaml, .yml or .json file"):
        read_description(tmp_path / "robot.urdf")


def test_parse_description_names_its_source():
    with pytest.raises(ModelError, match=r"^<dict>: gravity: expected 3 values, got 1$"):
        parse_description({**RRR, "gravity": [1]})
    with pytest.raises(ModelError, match=r"^<dict>: expected a mapping of keys at the top level, got the string"):
        parse_description("gravity")


# ---------------------------------------------------------------------------------------------- Skidy's child lists
def _pinocchio_dynamics(robot, n_states=4, seed=0):
    """(M, tau) from Pinocchio at random states, and those states, for ``robot`` at its defaults."""
    import pinocchio as pin

    from pinref import to_pinocchio

    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    rng = np.random.default_rng(seed)
    states = rng.uniform(-1.5, 1.5, (n_states, 3, robot.n_dof))
    m = np.stack([pin.crba(model, data, q) for q, _, _ in states])
    tau = np.stack([pin.rnea(model, data, q, qd, qdd) for q, qd, qdd in states])
    return states, np.triu(m) + np.triu(m, 1).transpose(0, 2, 1), tau


def _jaxskid_dynamics(robot, states):
    import jaxskid

    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    q, qd, qdd = states[:, 0], states[:, 1], states[:, 2]
    return np.asarray(dyn.mass_matrix(q)), np.asarray(dyn.inverse_dynamics(q, qd, qdd))


def test_child_list_off_by_one_is_ignored_with_a_warning():
    """Skidy's example files carry child lists off by one, and Skidy reads only parent: so does jaxskid,
    with one warning naming the file, the key and the child list that parent implies."""
    import jaxskid

    path = DATA / "skidy_2r_child_off_by_one.yaml"
    with pytest.warns(jaxskid.DescriptionWarning, match=r"skidy_2r_child_off_by_one\.yaml: child: ignored.*"
                                                         r"child\[0\] is \[1\].*follows parent.*\[\[2\], \[\]\]"):
        robot = jaxskid.load(path)
    assert [j.parent for j in robot.joints] == [-1, 0]
    text = path.read_text().replace("child:\n  - [1]\n  - []\n", "")
    assert "child" not in yaml.safe_load(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # without the child list: no warning, the same robot
        plain = parse_description(yaml.safe_load(text), source="plain.yaml")
    states, m_ref, tau_ref = _pinocchio_dynamics(plain)
    m, tau = _jaxskid_dynamics(robot, states)
    np.testing.assert_allclose(m, m_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tau, tau_ref, rtol=1e-12, atol=1e-12)


def test_child_list_that_disagrees_otherwise_and_a_spatial_tree():
    """A tree in Skidy's spatial representation whose child list misses a branch: the parent tree is used
    (with the warning), and it is the robot of a hand-written body-fixed description, whose dynamics are
    Pinocchio's."""
    import jaxskid

    with pytest.warns(jaxskid.DescriptionWarning, match=r"child\[0\] is \[2\], but the bodies whose parent is body 1 "
                                                         r"are \[2, 3\].*\[\[2, 3\], \[\], \[\]\]"):
        spatial = jaxskid.load(DATA / "skidy_tree_spatial.yaml")
    body = jaxskid.load(DATA / "skidy_tree_body_fixed.yaml")
    assert [j.parent for j in spatial.joints] == [j.parent for j in body.joints] == [-1, 0, 0]
    for js, jb in zip(spatial.joints, body.joints):
        assert same(js.origin, jb.origin) and same(js.screw, jb.screw) and same(js.inertia, jb.inertia)
    for name in ("ee1", "ee2"):
        assert spatial.frame(name).body == body.frame(name).body and same(spatial.frame(name).offset, body.frame(name).offset)
    states, m_ref, tau_ref = _pinocchio_dynamics(body, seed=1)
    m, tau = _jaxskid_dynamics(spatial, states)
    np.testing.assert_allclose(m, m_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tau, tau_ref, rtol=1e-12, atol=1e-12)


def test_child_list_problems_never_fail_but_parent_and_support_problems_do():
    d = one_joint()
    d.update(parent=[0], child="not a list")
    with pytest.warns(UserWarning, match=r"child: ignored.*expected 1 lists"):
        parse_description(d, source="c.yaml")
    d.update(parent=[2], child=[[]])
    with pytest.raises(ModelError, match=r"c\.yaml: parent\[0\]"):
        parse_description(d, source="c.yaml")
    d = one_joint()
    d.update(parent=[0], support=[[2]])
    with pytest.raises(ModelError, match=r"c\.yaml: support\[0\]"):
        parse_description(d, source="c.yaml")
