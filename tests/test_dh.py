"""Denavit–Hartenberg tables (the ``dh:`` block of a description, ``jaxskid.dh_robot`` in Python) against
Pinocchio models built here, directly from the same tables, with Pinocchio's own SE3 placements and joint
models (``JointModelRZ``, ``JointModelPZ``), not through jaxskid:

* standard (Denavit & Hartenberg 1955): frame i = frame i-1 Rz(theta + q) Tz(d) Tx(a) Rx(alpha). Joint i turns
  about z_{i-1}: its Pinocchio frame is DH frame i-1 turned by Rz(theta), and DH frame i (the body) sits at
  Tz(d) Tx(a) Rx(alpha) in it.
* modified (Craig 1986): frame i = frame i-1 Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta + q) Tz(d). Joint i turns
  about z_i: its Pinocchio frame is DH frame i.

The tables and their inertial data:

* PUMA 560, standard DH: Corke, Robotics Toolbox for Python, ``roboticstoolbox/models/DH/Puma560.py`` (after
  Corke & Armstrong-Hélouvry, "A search for consensus among model parameters reported for the PUMA 560
  robot", ICRA 1994): a = [0, 0.4318, 0.0203, 0, 0, 0], d = [0, 0, 0.15005, 0.4318, 0, 0], alpha = [pi/2, 0,
  -pi/2, pi/2, -pi/2, 0], masses, centres of mass ``r`` and inertias ``I = [Ixx, Iyy, Izz, Ixy, Iyz, Ixz]``
  about the centre of mass, in DH frame i. The file's later versions put the shoulder height 0.672 m into
  d1; here it is the table's ``base`` pose, which is the same (Tz and Rz about one axis commute).
* Franka Emika Panda, modified DH: Franka Control Interface documentation, "Robot and interface
  specifications" (https://frankaemika.github.io/docs/control_parameters.html): a = [0, 0, 0, 0.0825, -0.0825,
  0, 0.088], d = [0.333, 0, 0.316, 0, 0.384, 0, 0], alpha = [0, -pi/2, pi/2, pi/2, -pi/2, pi/2, pi/2], and
  the flange at d = 0.107 on frame 7. Masses and inertias: Corke's ``roboticstoolbox/models/DH/Panda.py``,
  which gives no centres of mass (they are at each frame's origin) and puts frame 7 at the flange: its
  centre of mass is at z = 0.107 in Franka's frame 7.
* Stanford arm, standard DH with a prismatic joint: Corke's ``roboticstoolbox/models/DH/Stanford.py``
  (kinematics: Stanford AIM-177, fig. 2.3; masses, centres of mass and inertias: Paul 1981, tables 6.5, 6.6).

M (crba), Q_grav (computeGeneralizedGravity), tau (rnea) and the pose of every DH frame
(framesForwardKinematics) agree to 1e-9 at random states.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import sympy as sp
import yaml

import jaxskid
from jaxskid import DH, ModelError, dh_robot, spatial_inertia
from jaxskid._cli import main

LEG_URDF = Path(__file__).parent / "data" / "urdf" / "hopping_leg.urdf"
TOL = 1e-9
QUANTITIES = ["mass_matrix", "gravity_torques", "inverse_dynamics", "forward_kinematics"]

# (type, a, alpha, d, theta) per row; per body (mass, centre of mass, [Ixx, Iyy, Izz, Ixy, Iyz, Ixz] about it)
PUMA_ROWS = [("revolute", 0, "pi/2", 0, 0), ("revolute", 0.4318, 0, 0, 0), ("revolute", 0.0203, "-pi/2", 0.15005, 0),
             ("revolute", 0, "pi/2", 0.4318, 0), ("revolute", 0, "-pi/2", 0, 0), ("revolute", 0, 0, 0, 0)]
PUMA_LINKS = [(0, [0, 0, 0], [0, 0.35, 0, 0, 0, 0]),
              (17.4, [-0.3638, 0.006, 0.2275], [0.13, 0.524, 0.539, 0, 0, 0]),
              (4.8, [-0.0203, -0.0141, 0.070], [0.066, 0.086, 0.0125, 0, 0, 0]),
              (0.82, [0, 0.019, 0], [1.8e-3, 1.3e-3, 1.8e-3, 0, 0, 0]),
              (0.34, [0, 0, 0], [0.3e-3, 0.4e-3, 0.3e-3, 0, 0, 0]),
              (0.09, [0, 0, 0.032], [0.15e-3, 0.15e-3, 0.04e-3, 0, 0, 0])]
PUMA_BASE = 0.672

PANDA_ROWS = [("revolute", 0, 0, 0.333, 0), ("revolute", 0, "-pi/2", 0, 0), ("revolute", 0, "pi/2", 0.316, 0),
              ("revolute", 0.0825, "pi/2", 0, 0), ("revolute", -0.0825, "-pi/2", 0.384, 0),
              ("revolute", 0, "pi/2", 0, 0), ("revolute", 0.088, "pi/2", 0, 0)]
PANDA_LINKS = [
    (4.970684, [0, 0, 0], [7.03370e-01, 7.06610e-01, 9.11700e-03, -1.39000e-04, 1.91690e-02, 6.77200e-03]),
    (0.646926, [0, 0, 0], [7.96200e-03, 2.81100e-02, 2.59950e-02, -3.92500e-03, 7.04000e-04, 1.02540e-02]),
    (3.228604, [0, 0, 0], [3.72420e-02, 3.61550e-02, 1.08300e-02, -4.76100e-03, -1.28050e-02, -1.13960e-02]),
    (3.587895, [0, 0, 0], [2.58530e-02, 1.95520e-02, 2.83230e-02, 7.79600e-03, 8.64100e-03, -1.33200e-03]),
    (1.225946, [0, 0, 0], [3.55490e-02, 2.94740e-02, 8.62700e-03, -2.11700e-03, 2.29000e-04, -4.03700e-03]),
    (1.666555, [0, 0, 0], [1.96400e-03, 4.35400e-03, 5.43300e-03, 1.09000e-04, 3.41000e-04, -1.15800e-03]),
    (7.35522e-01, [0, 0, 0.107], [1.25160e-02, 1.00270e-02, 4.81500e-03, -4.28000e-04, -7.41000e-04, -1.19600e-03]),
]
PANDA_FLANGE = 0.107

STANFORD_ROWS = [("revolute", 0, "-pi/2", 0.412, 0), ("revolute", 0, "pi/2", 0.154, 0),
                 ("prismatic", 0.0203, 0, 0, "-pi/2"), ("revolute", 0, "-pi/2", 0, 0),
                 ("revolute", 0, "pi/2", 0, 0), ("revolute", 0, 0, 0, 0)]
STANFORD_LINKS = [(9.29, [0, 0.0175, -0.1105], [0.276, 0.255, 0.071, 0, 0, 0]),
                  (5.01, [0, -1.054, 0], [0.108, 0.018, 0.100, 0, 0, 0]),
                  (4.25, [0, 0, -6.447], [2.51, 2.51, 0.006, 0, 0, 0]),
                  (1.08, [0, 0.092, -0.054], [0.002, 0.001, 0.001, 0, 0, 0]),
                  (0.630, [0, 0.566, 0.003], [0.003, 0.0004, 0, 0, 0, 0]),
                  (0.51, [0, 0, 1.554], [0.013, 0.013, 0.0003, 0, 0, 0])]


# ---------------------------------------------------------------------------------------------- references
INERTIA_KEYS = ("Ixx", "Iyy", "Izz", "Ixy", "Iyz", "Ixz")  # Corke's order of I
def _value(x, values=None) -> float:
    """A table entry (a number, or a string such as ``pi/2`` or ``L1``) as a float."""
    return float(sp.sympify(x, locals={"pi": sp.pi}).subs(values or {})) if isinstance(x, str) else float(x)


def _rz(t):
    return pin.SE3(pin.utils.rotate("z", t), np.zeros(3))


def _rx(t):
    return pin.SE3(pin.utils.rotate("x", t), np.zeros(3))


def _tz(d):
    return pin.SE3(np.eye(3), np.array([0.0, 0.0, d]))


def _tx(a):
    return pin.SE3(np.eye(3), np.array([a, 0.0, 0.0]))


def _inertia3(i):
    ixx, iyy, izz, ixy, iyz, ixz = i
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def pinocchio_dh(rows, links, convention, *, base=None, values=None, gravity=(0, 0, -9.81), flange=None):
    """A Pinocchio model of a serial DH table: joint i and frame ``dh<i>`` (DH frame i) per row, ``flange``
    (a distance along z of the last frame) as frame ``ee``. ``values`` gives the parameters of the entries."""
    model = pin.Model()
    model.gravity = pin.Motion(np.asarray(gravity, dtype=float), np.zeros(3))
    joint, tail = 0, base if base is not None else pin.SE3.Identity()
    for i, (row, (mass, com, inertia)) in enumerate(zip(rows, links)):
        kind, a, alpha, d, theta = row[0], *(_value(x, values) for x in row[1:])
        joint_model = pin.JointModelRZ() if kind == "revolute" else pin.JointModelPZ()
        if convention == "standard":  # the joint turns about z_{i-1}
            placement, body = tail * _rz(theta), _tz(d) * _tx(a) * _rx(alpha)
        else:  # about z_i: the joint frame is DH frame i
            placement, body = tail * _rx(alpha) * _tx(a) * _rz(theta) * _tz(d), pin.SE3.Identity()
        joint = model.addJoint(joint, joint_model, placement, f"q{i + 1}")
        com = np.array([_value(c, values) for c in com])
        inertia = _inertia3([_value(x, values) for x in inertia])
        model.appendBodyToJoint(joint, pin.Inertia(_value(mass, values), com, inertia), body)
        model.addFrame(pin.Frame(f"link{i + 1}", joint, 0, body, pin.FrameType.OP_FRAME))
        tail = body
    if flange is not None:
        model.addFrame(pin.Frame("ee", joint, 0, tail * _tz(flange), pin.FrameType.OP_FRAME))
    return model


def description(rows, links, convention, **extra) -> dict:
    """The YAML description of a DH table (entries as written in ``rows``)."""
    return {
        "name": extra.pop("name", "dh_robot"),
        "gravity": [0, 0, -9.81],
        "dh": {"convention": convention,
               "joints": [dict(zip(("type", "a", "alpha", "d", "theta"), row)) for row in rows]},
        "mass_inertia": [{"mass": m, "com": list(c), "inertia": dict(zip(INERTIA_KEYS, i)), "frame": "com"}
                         for m, c, i in links],
        **extra,
    }


def load(tmp_path, data, name="robot.yaml") -> jaxskid.Robot:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return jaxskid.load(path)


def close(ours, ref, tol: float = TOL) -> bool:
    """Entrywise within ``tol`` times the reference's size (at least 1, for results near zero)."""
    ref = np.asarray(ref)
    return bool(np.abs(np.asarray(ours) - ref).max() <= tol * max(1.0, np.abs(ref).max()))


def assert_matches(robot, model, *, params=None, states=4, seed=0):
    """M, Q_grav, tau and the pose of every frame of ``model`` that ``robot`` has, at random states."""
    dyn = jaxskid.lower(robot, QUANTITIES)
    data = model.createData()
    n = robot.n_dof
    q, qd, qdd = np.random.default_rng(seed).uniform(-2, 2, (3, states, n))
    got = {"M": dyn.mass_matrix(q, params), "g": dyn.gravity_torques(q, params),
           "tau": dyn.inverse_dynamics(q, qd, qdd, params)}
    poses = dyn.forward_kinematics(q, params)
    frames = [f.name for f in model.frames if f.name in poses]
    assert len(frames) >= n
    for k in range(states):
        m = pin.crba(model, data, q[k])
        ref = {"M": np.triu(m) + np.triu(m, 1).T, "g": pin.computeGeneralizedGravity(model, data, q[k]),
               "tau": pin.rnea(model, data, q[k], qd[k], qdd[k])}
        for key, value in ref.items():
            assert close(got[key][k], value), (key, np.abs(np.asarray(got[key][k]) - value).max())
        pin.framesForwardKinematics(model, data, q[k])
        for name in frames:
            pose = data.oMf[model.getFrameId(name)].homogeneous
            assert np.abs(np.asarray(poses[name][k]) - pose).max() <= TOL, name
    return dyn


# ---------------------------------------------------------------------------------------------- published robots
@pytest.mark.slow
def test_puma560_standard_dh_matches_pinocchio(tmp_path):
    data = description(PUMA_ROWS, PUMA_LINKS, "standard", name="puma560")
    data["dh"]["base"] = {"translation": [0, 0, PUMA_BASE]}
    robot = load(tmp_path, data)
    assert robot.n_dof == 6 and robot.parameters == ()
    assert_matches(robot, pinocchio_dh(PUMA_ROWS, PUMA_LINKS, "standard", base=_tz(PUMA_BASE)))


@pytest.mark.slow
def test_panda_modified_dh_matches_pinocchio(tmp_path):
    data = description(PANDA_ROWS, PANDA_LINKS, "modified", name="panda", ee={"translation": [0, 0, PANDA_FLANGE]})
    robot = load(tmp_path, data)
    assert robot.end_effectors == ("ee",)
    # the joint's screw is z of its own body in the modified convention
    assert all(j.screw == (0, 0, 1, 0, 0, 0) for j in robot.joints)
    assert_matches(robot, pinocchio_dh(PANDA_ROWS, PANDA_LINKS, "modified", flange=PANDA_FLANGE))


@pytest.mark.slow
def test_stanford_arm_prismatic_standard_dh_in_python_matches_pinocchio():
    rows = [DH(kind, a, alpha, d, theta) for kind, a, alpha, d, theta in STANFORD_ROWS]
    inertias = [spatial_inertia(m, c, [i[0], i[3], i[5], i[1], i[4], i[2]]) for m, c, i in STANFORD_LINKS]
    robot = dh_robot("stanford", rows, inertias, convention="standard")
    assert robot.joint_types[2] == "prismatic"
    x = robot.joints[2].screw  # slides along z_2 of the previous frame: in frame 3 (alpha = 0) that is z
    assert x == (0, 0, 0, 0, 0, 1)
    assert_matches(robot, pinocchio_dh(STANFORD_ROWS, STANFORD_LINKS, "standard"))


# ---------------------------------------------------------------------------------------------- conventions
SMALL_ROWS = [("revolute", 0.3, "pi/2", 0.2, 0.1), ("prismatic", 0.25, "-pi/3", 0.15, "pi/4"),
              ("revolute", "a3", "pi/6", 0.1, -0.2)]
SMALL_LINKS = [(1.5, [0.1, 0.02, -0.05], [0.02, 0.03, 0.025, 0.001, 0.002, -0.001]),
               (0.8, [-0.05, 0.04, 0.1], [0.01, 0.012, 0.008, 0, 0.001, 0]),
               (0.5, [0.02, 0, 0.06], [0.004, 0.005, 0.003, 0, 0, 0.0005])]


@pytest.mark.slow
@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_one_table_in_each_convention_with_a_prismatic_joint_and_a_parameter(tmp_path, convention):
    data = description(SMALL_ROWS, SMALL_LINKS, convention, assignments={"a3": 0.35},
                       ee={"translation": [0.05, 0, 0]})
    robot = load(tmp_path, data)
    assert robot.parameters == ("a3",) and robot.default_params() == {"a3": 0.35}
    assert robot.joint_types == ("revolute", "prismatic", "revolute")
    dyn = assert_matches(robot, pinocchio_dh(SMALL_ROWS, SMALL_LINKS, convention, values={"a3": 0.35}))
    # the length stays an input of the lowered functions: another value, another robot
    assert_matches(robot, pinocchio_dh(SMALL_ROWS, SMALL_LINKS, convention, values={"a3": 0.6}),
                   params={"a3": 0.6}, seed=1)
    q = np.array([0.4, 0.1, -0.7])
    assert np.abs(np.asarray(dyn.forward_kinematics(q, {"a3": 0.6})["ee"])
                  - np.asarray(dyn.forward_kinematics(q)["ee"])).max() > 1e-2


def test_the_conventions_differ_and_the_screws_are_exact():
    """Exact screws: standard joint i moves about z_{i-1}, (0, sin alpha, cos alpha, 0, a cos alpha,
    -a sin alpha) in frame i; modified about z_i; the same rows give other frames."""
    a, alpha = sp.symbols("a alpha", real=True)
    rows = [DH("revolute", a, alpha, "d1", "th1"), DH("prismatic", "a2", "pi/3", 0, 0)]
    inertias = [spatial_inertia(1, (0, 0, 0), (1, 0, 0, 1, 0, 1))] * 2
    standard = dh_robot("s", rows, inertias, convention="standard")
    modified = dh_robot("m", rows, inertias, convention="modified")
    assert standard.joints[0].screw == (0, sp.sin(alpha), sp.cos(alpha), 0, a * sp.cos(alpha), -a * sp.sin(alpha))
    assert standard.joints[1].screw == (0, 0, 0, 0, sp.sqrt(3) / 2, sp.Rational(1, 2))
    assert modified.joints[0].screw == (0, 0, 1, 0, 0, 0) and modified.joints[1].screw == (0, 0, 0, 0, 0, 1)
    assert set(standard.parameters) == {"a", "alpha", "d1", "th1", "a2"}
    given = {"a": 0.3, "alpha": 0.4, "d1": 0.2, "th1": 0.5, "a2": 0.1}
    values = {sp.Symbol(k, real=True): v for k, v in given.items()}
    numeric = [np.array(r.joints[0].origin.xreplace(values), dtype=float) for r in (standard, modified)]
    assert np.abs(numeric[0] - numeric[1]).max() > 0.1


@pytest.mark.slow
def test_the_same_table_in_the_two_conventions_gives_different_fk_each_its_own(tmp_path):
    rows = [row for row in SMALL_ROWS[:2]]
    links = SMALL_LINKS[:2]
    fk = {}
    for convention in ("standard", "modified"):
        robot = load(tmp_path, description(rows, links, convention), name=f"{convention}.yaml")
        model = pinocchio_dh(rows, links, convention)
        dyn = assert_matches(robot, model, states=2)
        fk[convention] = np.asarray(dyn.forward_kinematics(np.array([0.3, 0.2]))["link2"])
    assert np.abs(fk["standard"] - fk["modified"]).max() > 1e-2


def test_python_and_yaml_forms_give_the_same_robot(tmp_path):
    data = description(SMALL_ROWS, SMALL_LINKS, "modified", assignments={"a3": 0.35}, joint_names=["j1", "j2", "j3"],
                       name="small")
    from_yaml = load(tmp_path, data)
    inertias = [spatial_inertia(m, c, [i[0], i[3], i[5], i[1], i[4], i[2]]) for m, c, i in SMALL_LINKS]
    from_python = dh_robot("small", [DH(*row) for row in SMALL_ROWS], inertias, convention="modified",
                           joint_names=["j1", "j2", "j3"], defaults={"a3": 0.35})
    assert from_python.joints == from_yaml.joints and from_python.defaults == from_yaml.defaults


def test_tree_and_base_pose(tmp_path):
    """``parent`` makes a tree: a row is relative to its parent body's DH frame; ``base`` places frame 0."""
    rows = [("revolute", 0.3, "pi/2", 0.2, 0), ("revolute", 0.25, 0, 0, 0), ("prismatic", 0, "pi/2", 0.1, 0)]
    data = description(rows, SMALL_LINKS, "standard", parent=[0, 1, 1])
    data["dh"]["base"] = {"translation": [1, 2, 3], "rotation": {"rpy": [0, 0, "pi/2"]}}
    robot = load(tmp_path, data)
    assert robot.parents == (-1, 0, 0)
    chain = load(tmp_path, description(rows, SMALL_LINKS, "standard"), name="chain.yaml")
    assert robot.joints[2].origin == chain.joints[2].origin and robot.joints[2].screw == chain.joints[2].screw
    base = sp.Matrix(jaxskid.pose_xyzrpy(1, 2, 3, 0, 0, sp.pi / 2))
    assert robot.joints[0].origin == base * chain.joints[0].origin


# ---------------------------------------------------------------------------------------------- CLI
@pytest.mark.slow
@pytest.mark.parametrize("ext", ["yaml", "json", "py"])
def test_template_dh_loads_and_matches_pinocchio_from_its_own_table(tmp_path, capsys, ext):
    path = tmp_path / f"rrp_arm.{ext}"
    with pytest.raises(SystemExit) as done:
        main(["template", "--dh", "-S", "RRP", str(path)])
    assert done.value.code == 0 and "DH template" in capsys.readouterr().out
    if ext == "py":
        robot = _run_python(path)
        table = yaml.safe_load(render_yaml("RRP"))
    else:
        robot = jaxskid.load(path)
        table = yaml.safe_load(path.read_text())
        assert "joint_screw_coord" not in table and table["dh"]["convention"] == "standard"
    values = table["assignments"]
    rows = [tuple(r[k] for k in ("type", "a", "alpha", "d", "theta")) for r in table["dh"]["joints"]]
    links = [(m["mass"], m["com"], [m["inertia"][k] for k in (0, 3, 5, 1, 4, 2)]) for m in table["mass_inertia"]]
    model = pinocchio_dh(rows, links, "standard", values=values, gravity=(0, 0, -values["g"]), flange=0)
    assert robot.joint_types == ("revolute", "revolute", "prismatic")
    assert_matches(robot, model)


def render_yaml(structure):
    from jaxskid.description import render_template

    return render_template(structure, "yaml", name="rrp_arm", kinematics="dh")


def _run_python(path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"dh_template_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.robot


@pytest.mark.slow
def test_template_dh_passes_the_self_check_of_generate(tmp_path, capsys):
    path = tmp_path / "elbow.yaml"
    for args in (["template", "--dh", "--dof", "3", str(path)],
                 ["generate", str(path), "-q", "mass_matrix,gravity_torques,inverse_dynamics", "-o",
                  str(tmp_path / "out")]):
        with pytest.raises(SystemExit) as done:
            main(args)
        assert done.value.code == 0
    out = capsys.readouterr().out
    assert "self-check" in out and "FAILED" not in out


def test_template_dh_usage(tmp_path, capsys):
    with pytest.raises(SystemExit) as done:
        main(["template", "--dh", "--urdf", str(LEG_URDF), str(tmp_path / "x.py")])
    assert done.value.code == 2


# ---------------------------------------------------------------------------------------------- URDF
def _pinocchio_dynamics(model, order, q, qd, qdd):
    data = model.createData()
    index = [model.joints[model.getJointId(name)].idx_v for name in order]
    qq, vv, aa = (np.zeros(model.nv) for _ in range(3))
    qq[index], vv[index], aa[index] = q, qd, qdd
    m = pin.crba(model, data, qq)
    m = np.triu(m) + np.triu(m, 1).T
    return (m[np.ix_(index, index)], pin.computeGeneralizedGravity(model, data, qq)[index],
            pin.rnea(model, data, qq, vv, aa)[index])


@pytest.mark.slow
def test_convert_dh_to_urdf_round_trip(tmp_path, capsys):
    """The Puma written as URDF: jaxskid.load of it has the source's M, Q_grav and tau (1e-10), and
    Pinocchio's own URDF parser agrees with the model built from the table."""
    data = description(PUMA_ROWS, PUMA_LINKS, "standard", name="puma560", ee={"translation": [0, 0, 0.05]})
    data["dh"]["base"] = {"translation": [0, 0, PUMA_BASE]}
    source = tmp_path / "puma.yaml"
    source.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "puma.urdf"
    with pytest.raises(SystemExit) as done:
        main(["convert", str(source), str(out)])
    assert done.value.code == 0 and f"wrote {out}" in capsys.readouterr().out
    robot, back = jaxskid.load(source), jaxskid.load(out)
    assert sorted(back.joint_names) == sorted(robot.joint_names) and "ee" in back.frame_names
    names = list(robot.joint_names)
    ours = jaxskid.lower(robot, QUANTITIES[:3])
    theirs = jaxskid.lower(back, QUANTITIES[:3])
    order = [back.joint_names.index(n) for n in names]
    urdf_model = pin.buildModelFromUrdf(str(out))
    table_model = pinocchio_dh(PUMA_ROWS, PUMA_LINKS, "standard", base=_tz(PUMA_BASE))
    rng = np.random.default_rng(5)
    for _ in range(4):
        q, qd, qdd = rng.uniform(-2, 2, (3, 6))
        a = (ours.mass_matrix(q), ours.gravity_torques(q), ours.inverse_dynamics(q, qd, qdd))
        qb, qdb, qddb = (np.zeros(6) for _ in range(3))
        qb[order], qdb[order], qddb[order] = q, qd, qdd
        b = (theirs.mass_matrix(qb), theirs.gravity_torques(qb), theirs.inverse_dynamics(qb, qdb, qddb))
        b = (np.asarray(b[0])[np.ix_(order, order)], np.asarray(b[1])[order], np.asarray(b[2])[order])
        for x, y in zip(a, b):
            assert close(x, y, 1e-10)
        for x, y in zip(_pinocchio_dynamics(urdf_model, names, q, qd, qdd),
                        _pinocchio_dynamics(table_model, names, q, qd, qdd)):
            assert close(x, y, 1e-10)


def test_convert_dh_to_screw_yaml_is_the_same_robot(tmp_path, capsys):
    source = tmp_path / "small_dh.yaml"
    source.write_text(yaml.safe_dump(description(SMALL_ROWS, SMALL_LINKS, "standard", assignments={"a3": 0.35})))
    out = tmp_path / "small.yaml"
    with pytest.raises(SystemExit) as done:
        main(["convert", str(source), str(out)])
    assert done.value.code == 0
    written = yaml.safe_load(out.read_text())
    assert "dh" not in written and len(written["joint_screw_coord"]) == 3
    assert jaxskid.load(out).joints == jaxskid.load(source).joints


def test_urdf_needs_numbers_and_keeps_files(tmp_path, capsys):
    data = description(SMALL_ROWS, SMALL_LINKS, "standard")  # a3 has no default
    source = tmp_path / "small.yaml"
    source.write_text(yaml.safe_dump(data))
    out = tmp_path / "small.urdf"
    with pytest.raises(ModelError, match="parameter 'a3' has no default value; a URDF holds numbers only"):
        jaxskid.write_urdf(jaxskid.load(source), out)
    with pytest.raises(SystemExit) as done:
        main(["convert", str(source), str(out)])
    assert done.value.code == 1 and "parameter 'a3' has no default value" in capsys.readouterr().err
    assert not out.exists()
    out.write_text("mine")
    data["assignments"] = {"a3": 0.3}
    source.write_text(yaml.safe_dump(data))
    with pytest.raises(SystemExit) as done:
        main(["convert", str(source), str(out)])
    assert done.value.code == 1 and "already exists" in capsys.readouterr().err and out.read_text() == "mine"
    with pytest.raises(SystemExit) as done:
        main(["convert", str(source), str(out), "--symbolify"])
    assert done.value.code == 2
    with pytest.raises(SystemExit) as done:
        main(["convert", str(source), str(out), "--force"])
    assert done.value.code == 0 and "<robot" in out.read_text()


def test_urdf_keeps_gravity_only_as_a_comment_with_a_warning(tmp_path):
    robot = dh_robot("arm", [DH("revolute", 0.5, 0, 0, 0)], [spatial_inertia(1.0, (0.25, 0, 0))],
                     convention="standard", gravity=(0, -9.81, 0))
    out = tmp_path / "arm.urdf"
    with pytest.warns(jaxskid.DescriptionWarning, match=r"gravity \[0.0, -9.81, 0.0\]"):
        jaxskid.write_urdf(robot, out)
    assert "jaxskid.load(path, gravity=...)" in out.read_text()
    back = jaxskid.load(out, gravity=(0, -9.81, 0))
    assert back.joint_names == ("q1",) and back.gravity == robot.gravity


# ---------------------------------------------------------------------------------------------- bad input
GOOD = description(SMALL_ROWS, SMALL_LINKS, "standard", assignments={"a3": 0.35})


def _edit(path, value):
    """A copy of GOOD with the entry at ``path`` (keys and indices) set to ``value`` (``...``: removed)."""
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    *head, last = path
    node = data
    for key in head:
        node = node[key]
    if value is ...:
        del node[last]
    else:
        node[last] = value
    return data


BAD = [
    (("dh", "joints", 2, "d"), [1, 2], "dh.joints[2].d", "expected a number or an expression, got a list of 2 items"),
    (("dh", "joints", 1, "alpha"), ..., "dh.joints[1].alpha", "required key is missing"),
    (("dh", "joints", 0, "theta"), "sin(", "dh.joints[0].theta", "cannot parse 'sin(' as an expression"),
    (("dh", "joints", 1, "offset"), 0.1, "dh.joints[1]",
     "unknown key 'offset'; expected one of type, a, alpha, d, theta"),
    (("dh", "convention"), "craig", "dh.convention", "unknown convention 'craig'; expected standard"),
    (("dh", "convention"), ..., "dh.convention", "required key is missing"),
    (("dh", "joints", 2, "type"), "spherical", "dh.joints[2].type",
     "unknown joint type 'spherical'; expected revolute or prismatic"),
    (("dh", "joints", 1, "d"), "q2", "dh.joints[1].d",
     "'q2' is this joint's variable, which jaxskid adds to d of a prismatic joint; write d as its value at q = 0"),
    (("dh", "joints", 1, "theta"), "q2 + pi/4", "dh.joints[1].theta",
     "'q2' is this joint's variable, but a prismatic joint moves d, not theta"),
    (("dh", "joints", 0, "theta"), "q1", "dh.joints[0].theta",
     "'q1' is this joint's variable, which jaxskid adds to theta of a revolute joint"),
    (("dh", "joints", 2, "a"), "2*q1", "dh.joints[2].a", "'q1' is joint 1's variable"),
    (("dh", "joints"), [], "dh.joints", "expected a non-empty list (one row per joint), got a list of 0 items"),
    (("dh", "base"), {"rotation": [[1, 0, 0], [0, 2, 0], [0, 0, 1]]}, "dh.base.rotation",
     "expected a rotation matrix"),
    (("joint_screw_coord",), [[0, 0, 1, 0, 0, 0]], "joint_screw_coord",
     "give either a dh table or joint_screw_coord"),
    (("representation",), "body_fixed", "representation", "give either a dh table or joint_screw_coord"),
    (("mass_inertia",), GOOD["mass_inertia"][:2], "mass_inertia",
     "expected 3 entries (one per joint in dh.joints), got 2"),
]


@pytest.mark.parametrize("path,value,where,message", BAD, ids=[f"{w}:{m[:30]}" for _, _, w, m in BAD])
def test_bad_dh_table_names_file_and_key(tmp_path, path, value, where, message):
    file = tmp_path / "robot.yaml"
    file.write_text(yaml.safe_dump(_edit(path, value)))
    with pytest.raises(ModelError) as info:
        jaxskid.load(file)
    err = info.value
    assert err.source == str(file) and err.where == where, str(err)
    assert message in err.message, err.message
    assert str(err).startswith(f"{file}: {where}: ") and "\n" not in str(err)
    assert err.__cause__ is None and err.__suppress_context__


def test_joint_names_are_joint_variables_too(tmp_path):
    data = _edit(("joint_names",), ["shoulder", "slider", "wrist"])
    data["dh"]["joints"][1]["d"] = "slider"
    file = tmp_path / "robot.yaml"
    file.write_text(yaml.safe_dump(data))
    with pytest.raises(ModelError, match=r"dh\.joints\[1\]\.d: 'slider' is this joint's variable"):
        jaxskid.load(file)


def test_bad_python_table_names_the_argument():
    inertia = spatial_inertia(1.0, (0, 0, 0), (1, 0, 0, 1, 0, 1))
    cases = [
        (dict(rows=[DH("revolute", 0, 0, [1, 2], 0)]), "rows[0].d: expected a scalar number or expression"),
        (dict(rows=[DH("prismatic", 0, 0, sp.Symbol("q1"), 0)]), "rows[0].d: 'q1' is this joint's variable"),
        (dict(rows=[DH("helical", 0, 0, 0, 0)]), "rows[0].type: unknown joint type 'helical'"),
        (dict(rows=[{"type": "revolute", "a": 0}]), "rows[0].alpha: required key is missing"),
        (dict(convention="craig"), "convention: unknown convention 'craig'"),
        (dict(base_pose=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]), "base_pose: expected a 4x4 matrix with 4 rows"),
        (dict(inertias=[inertia, inertia]), "inertias: expected 1 entries (one per row), got 2"),
        (dict(inertias=[spatial_inertia(-1.0)]), "inertias[0]: expected a non-negative mass"),
    ]
    for changes, message in cases:
        args = {"rows": [DH("revolute", 0.1, 0, 0, 0)], "inertias": [inertia], "convention": "standard", **changes}
        with pytest.raises(ModelError) as info:
            dh_robot("bad", args.pop("rows"), args.pop("inertias"), **args)
        assert str(info.value).startswith(message), (str(info.value), message)
