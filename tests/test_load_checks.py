"""What :func:`jaxskid.load` checks beyond each value: the mass matrix at the default parameters (singular in every
configuration tried is an error naming the joints that move together without moving mass), the keywords it is
given, and what of a URDF it reads (the links' inertial and the joints, not their visuals)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import sympy

import helpers
import jaxskid
from jaxskid import ModelError
from jaxskid.model import _inertia_check

DATA = Path(__file__).parent / "data"


def _load_check_numbers(monkeypatch, path, **kw):
    """The numbers the mass-matrix check of ``load`` works on: ``(robot, numbers, coupling)``."""
    seen = {}

    def spy(robot, numbers, configurations, source):
        seen.update(robot=robot, numbers=numbers)

    monkeypatch.setattr(_inertia_check, "_check_mass_matrix", spy)
    jaxskid.load(path, **kw)
    robot = seen["robot"]
    return robot, seen["numbers"], [(k, float(a)) for k, a, _ in robot.coupling()]


@pytest.mark.parametrize(("name", "floating"), [("ur5", False), ("solo12", True)])
def test_the_checks_mass_matrix_is_pinocchios_crba(monkeypatch, name, floating):
    """The composite-rigid-body algorithm of the check against Pinocchio's ``crba`` on the same file, joints
    matched by name; a floating base at the identity, its twist ``(omega, v)`` against Pinocchio's ``(v, omega)``."""
    path = helpers.URDFS[name]
    robot, numbers, coupling = _load_check_numbers(monkeypatch, path, floating_base=floating)
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()) if floating else pin.buildModelFromUrdf(str(path))
    data = model.createData()
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, len(robot.joints))
    q_pin = pin.neutral(model)
    order = [6 * floating]  # rows of Pinocchio's M in jaxskid's order
    for i, j in enumerate(robot.joints):
        joint = model.joints[model.getJointId(j.name)]
        assert joint.nq == 1
        q_pin[joint.idx_q] = q[i]
        order.append(joint.idx_v)
    order = ([3, 4, 5, 0, 1, 2] if floating else []) + order[1:]
    reference = pin.crba(model, data, q_pin)
    reference = np.triu(reference) + np.triu(reference, 1).T
    ours = _inertia_check._mass_matrix(robot, *numbers, coupling, q)
    np.testing.assert_allclose(ours, reference[np.ix_(order, order)], rtol=0, atol=1e-12 * np.abs(reference).max())


@pytest.mark.filterwarnings("ignore::jaxskid.PhysicalConsistencyWarning")  # iCub's point-mass links
def test_a_singularity_of_one_configuration_is_no_error(monkeypatch):
    """iCub's neck roll and yaw are coaxial at the zero configuration, where its mass matrix is singular; it loads
    (with a floating base too), since the check asks for a singularity in every configuration tried."""
    path = helpers.ERD / "icub_description/robots/icub.urdf"
    for floating in (False, True):
        robot, numbers, coupling = _load_check_numbers(monkeypatch, path, floating_base=floating)
        m = _inertia_check._mass_matrix(robot, *numbers, coupling, np.zeros(len(robot.joints)))
        d = np.sqrt(np.diag(m))
        assert np.linalg.eigvalsh(m / np.outer(d, d))[0] < 1e-12  # singular there
    monkeypatch.undo()
    assert jaxskid.load(path).n_dof == 32 and jaxskid.load(path, floating_base=True).floating_base


@pytest.mark.parametrize(("kwargs", "where", "message"), [
    ({"bogus": 1}, None, "unknown option 'bogus'; a URDF file takes symbolic_inertia, mimic, floating_base"),
    ({"flaoting_base": True}, None, "'flaoting_base' (did you mean 'floating_base'?)"),
    ({"lock": "j1"}, "lock", "expected a mapping joint name -> position, got the string 'j1'"),
    ({"lock": ["j1"]}, "lock", "got a list of 1 item"),
    ({"balance_inertia": "no"}, "balance_inertia", "expected true or false, got the string 'no'"),
    ({"mimic": None}, "mimic", "expected true or false, got nothing (null)"),
    ({"drives": 1}, "drives", "expected true or false, got the number 1"),
    ({"gravity": None}, "gravity", "expected 3 values, got nothing (null)"),
    ({"gravity": "down"}, "gravity", "expected 3 values, got the string 'down'"),
])
def test_load_keywords_are_checked(kwargs, where, message):
    path = helpers.URDFS["double_pendulum"]
    with pytest.raises(ModelError) as info:
        jaxskid.load(path, **kwargs)
    assert info.value.source == str(path) and info.value.where == where
    assert message in info.value.message


def test_a_yaml_file_refuses_urdf_options_and_non_bool_drives():
    path = helpers.ROBOTS_DIR / "arm_2r.yaml"
    with pytest.raises(ModelError, match="unknown option"):
        jaxskid.load(path, floating_base=True)
    with pytest.raises(ModelError, match="drives: expected true or false"):
        jaxskid.load(path, drives="yes")


def test_visuals_are_not_read(tmp_path):
    """A malformed ``<visual>`` (box sizes that are words) does not stop the dynamics, as in Pinocchio's model
    reader: the robot equals the one read from the file without it."""
    path = DATA / "urdf" / "bad_visual.urdf"
    plain = tmp_path / "plain.urdf"
    plain.write_text(path.read_text().replace('<visual><geometry><box size="a b c"/></geometry></visual>', ""))
    robot, reference = jaxskid.load(path), jaxskid.load(plain)
    assert robot.joints == reference.joints and robot.default_params() == reference.default_params()


def test_what_yourdfpy_is_given_is_what_was_checked(tmp_path):
    """An entity of the file's own DTD arrives expanded (the mass 1.5, not an empty string), and the ``<axis>`` of
    a fixed joint, which urdfdom does not read, is not read here either."""
    link = '<link name="b"><inertial><mass value="&m;"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
    path = tmp_path / "entity.urdf"
    path.write_text(f'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY m "1.5">]><robot name="r"><link name="a"/>{link}'
                    '</inertial></link><link name="c"/><joint name="j" type="revolute"><parent link="a"/>'
                    '<child link="b"/><axis xyz="0 0 1"/></joint><joint name="w" type="fixed"><parent link="b"/>'
                    '<child link="c"/><axis xyz="abc"/></joint></robot>')
    assert jaxskid.load(path).default_params()["b_m"] == 1.5


def test_a_constant_far_angle_is_evaluated_when_read(tmp_path):
    """``sin(10**15)`` in a file is its value (mpmath), not the generated programs' sine of an argument beyond
    their exact reduction."""
    import mpmath

    text = (helpers.ROBOTS_DIR / "single_pendulum.yaml").read_text()
    path = tmp_path / "far.yaml"
    path.write_text(text.replace("gravity: [0, 0, -g]", "gravity: [0, 0, '-g*sin(10**15)']", 1))
    assert "'-g*sin(10**15)'" in path.read_text()
    robot = jaxskid.load(path)
    g = robot.default_params()["g"]
    dyn = jaxskid.lower(robot, ["gravity_torques"])
    reference = jaxskid.load(helpers.ROBOTS_DIR / "single_pendulum.yaml")
    q = np.array([0.7])
    scale = float(mpmath.sin(mpmath.mpf(10) ** 15))
    expected = np.asarray(jaxskid.lower(reference, ["gravity_torques"]).gravity_torques(q)) * scale
    np.testing.assert_allclose(np.asarray(dyn.gravity_torques(q)), expected, rtol=1e-12)
    assert g == reference.default_params()["g"]


def _joint(**kw):
    args = dict(name="j1", type="revolute", parent=-1, origin=np.eye(4), screw=(0, 0, 1, 0, 0, 0),
                inertia=jaxskid.spatial_inertia(1.0, (0.1, 0, 0), np.eye(3) * 0.01), link="l1")
    return jaxskid.Joint(**{**args, **kw})


@pytest.mark.parametrize(("kwargs", "where", "message"), [
    ({"joints": None}, "joints", "expected a sequence of Joint, got nothing (null)"),
    ({"joints": {"a": 1}}, "joints", "got a mapping with keys a"),
    ({"joints": [_joint(name=None)]}, "joints[0].name", "expected a non-empty string, got nothing (null)"),
    ({"joints": [_joint(link=3)]}, "joints[0].link", "expected a non-empty string, got the number 3"),
    ({"joints": [_joint()], "defaults": [1, 2]}, "defaults", "expected a mapping parameter name -> value"),
    ({"joints": [_joint(inertia=np.eye(6) * jaxskid.symbol("m") ** 0.5 * sympy.Max(1, jaxskid.symbol("m")))],
      "defaults": {"m": 1.0}}, "joints[0].inertia[0][0]", "unsupported function 'Max'"),
])
def test_robot_create_names_the_argument(kwargs, where, message):
    """The Python description's containers and names get the errors a file's keys get."""
    with pytest.raises(ModelError) as info:
        jaxskid.Robot.create("r", **kwargs)
    assert info.value.where == where and message in info.value.message


def test_spatial_inertia_takes_arrays_and_names_a_wrong_shape():
    """A NumPy 3x3 inertia is a matrix, as a nested list is; six values are (Ixx, Ixy, Ixz, Iyy, Iyz, Izz)."""
    inertia = np.array([[0.1, 0.01, 0.0], [0.01, 0.2, 0.0], [0.0, 0.0, 0.3]])
    m6 = jaxskid.spatial_inertia(2.0, (0, 0, 0), inertia)
    assert m6[:3, :3] == jaxskid.spatial_inertia(2.0, (0, 0, 0), inertia.tolist())[:3, :3]
    assert m6[:3, :3] == jaxskid.spatial_inertia(2.0, (0, 0, 0), (0.1, 0.01, 0.0, 0.2, 0.0, 0.3))[:3, :3]
    robot = jaxskid.Robot.create("r", [_joint(name="j", link="end")], end_effectors="end")
    assert robot.end_effectors == ("end",)
    with pytest.raises(ModelError, match=r"inertia: expected a 3x3 inertia or its six values"):
        jaxskid.spatial_inertia(1.0, (0, 0, 0), np.eye(2))
