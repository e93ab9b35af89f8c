"""What a URDF reader lets a published file through with, on request or with a warning: ``<mimic>`` joints read as
independent joints (one warning per file, a ``<mimic>`` of a joint the file lacks included), and
``balance_inertia=True`` for inertias that no rigid body has (MuJoCo's ``balanceinertia``: the isotropic inertia of
the same trace). Published cases: example-robot-data's TIAGo (two antenna links whose inertia is not positive
semi-definite) and Alex with Psyonic hands (eight ``<mimic>`` of joints it does not have).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import helpers
import jaxskid
from jaxskid import DescriptionWarning, ModelError, PhysicalConsistencyWarning

BAD = Path(__file__).parent / "data" / "bad"
TIAGO = helpers.ERD / "tiago_description/robots/tiago_no_hand.urdf"


def _caught(**kw) -> tuple[list[warnings.WarningMessage], object]:
    path = kw.pop("path")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        robot = jaxskid.load(path, **kw)
    return record, robot


def _messages(record, category) -> list[str]:
    return [str(w.message) for w in record if issubclass(w.category, category)]


def test_a_mimic_of_an_unknown_joint_is_dropped_with_a_warning_and_refused_when_coupled():
    path = BAD / "urdf_mimic_unknown_joint.urdf"
    record, robot = _caught(path=path)
    assert robot.joint_names == ("j1", "j2") and robot.n_dof == 2  # as Pinocchio's default (mimic=False)
    (message,) = _messages(record, DescriptionWarning)
    assert message.startswith(f"{path}: joint[name=j2].mimic: ")
    assert "'j7'" in message and "no joint of that name" in message and "mimic=True" in message
    with pytest.raises(ModelError) as info:
        jaxskid.load(path, mimic=True)
    assert info.value.where == "joint[name=j2].mimic.joint" and "'j7'" in info.value.message


def test_mimic_joints_read_as_independent_make_one_warning_naming_each(tmp_path):
    text = (BAD / "urdf_mimic.urdf").read_text()
    third = """  <link name="l3">
    <inertial><mass value="1.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="j3" type="revolute">
    <parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="1 0 0"/><mimic joint="j1" multiplier="2"/>
  </joint>
</robot>"""
    path = tmp_path / "two_mimics.urdf"
    path.write_text(text.replace("</robot>", third))
    record, robot = _caught(path=path)
    assert robot.n_dof == 3
    (message,) = _messages(record, DescriptionWarning)
    assert message.startswith(f"{path}: joint[name=j2].mimic: ") and "1 more" in message
    assert "'j2' to 'j1'" in message and "'j3' to 'j1'" in message and "no joint of that name" not in message
    assert jaxskid.load(path, mimic=True).n_dof == 1


def test_an_inertia_that_is_not_positive_semidefinite_is_refused_with_the_option_named():
    with pytest.raises(ModelError) as info:
        jaxskid.load(BAD / "urdf_negative_inertia.urdf")
    assert info.value.where == "link[name=l1].inertial.inertia"
    assert "balance_inertia=True" in info.value.message


def test_balance_inertia_makes_it_isotropic_with_its_trace():
    """The file's l1: ixx = -0.01, iyy = izz = 0.01 about the centre of mass at the link origin, so the balanced
    inertia is 0.01 / 3 times the identity (trace kept); l2 is physical and kept as written."""
    path = BAD / "urdf_negative_inertia.urdf"
    record, robot = _caught(path=path, balance_inertia=True)
    (message,) = _messages(record, DescriptionWarning)
    assert message.startswith(f"{path}: link[name=l1].inertial.inertia: 1 inertia(s)") and "l1 (0.00333333)" in message
    p = robot.default_params()
    assert [p[f"l1_I{a}"] for a in ("xx", "yy", "zz")] == pytest.approx([0.01 / 3] * 3, rel=1e-12)
    assert [p[f"l1_I{a}"] for a in ("xy", "xz", "yz")] == [0.0, 0.0, 0.0]
    assert p["l1_m"] == 1.0


def test_balance_inertia_also_mends_a_broken_triangle_inequality(tmp_path):
    """Principal moments 0.01, 0.01, 0.03 (positive definite, but 0.01 + 0.01 < 0.03): a physical-consistency
    warning as written, the isotropic 0.05 / 3 with the option."""
    text = (BAD / "urdf_mimic.urdf").read_text().replace('<mimic joint="j1" multiplier="-1" offset="0.1"/>', "")
    path = tmp_path / "triangle.urdf"
    path.write_text(text.replace('iyz="0" izz="0.01"/></inertial>\n  </link>\n  <link name="l2">',
                                 'iyz="0" izz="0.03"/></inertial>\n  </link>\n  <link name="l2">', 1))
    record, _ = _caught(path=path)
    assert any("l1" in m for m in _messages(record, PhysicalConsistencyWarning))
    record, robot = _caught(path=path, balance_inertia=True)
    assert not _messages(record, PhysicalConsistencyWarning)
    assert robot.default_params()["l1_Izz"] == pytest.approx(0.05 / 3, rel=1e-12)


@pytest.mark.slow
def test_tiago_loads_balanced_and_agrees_with_pinocchio():
    """TIAGo's antenna links have indefinite inertias; they are welded to the base, so the balanced robot's M and
    inverse dynamics equal those of Pinocchio's own model of the unchanged file."""
    with pytest.raises(ModelError, match="balance_inertia=True"):
        jaxskid.load(TIAGO)
    record, robot = _caught(path=TIAGO, balance_inertia=True)
    (message,) = _messages(record, DescriptionWarning)
    assert "base_antenna_left_link" in message and "base_antenna_right_link" in message
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    model = pin.buildModelFromUrdf(str(TIAGO))
    data = model.createData()
    rng = np.random.default_rng(3)
    q, qd, qdd = rng.uniform(-1, 1, (3, robot.n_dof))
    pq, pv, pa, idx = pin.neutral(model), np.zeros(model.nv), np.zeros(model.nv), []
    for k, name in enumerate(robot.joint_names):
        j = model.joints[model.getJointId(name)]
        pq[j.idx_q:j.idx_q + j.nq] = [q[k]] if j.nq == 1 else [np.cos(q[k]), np.sin(q[k])]
        pv[j.idx_v], pa[j.idx_v] = qd[k], qdd[k]
        idx.append(j.idx_v)
    assert sorted(idx) == list(range(model.nv))
    m_ref = pin.crba(model, data, pq)
    m_ref = np.triu(m_ref) + np.triu(m_ref, 1).T
    assert helpers.rel_err(dyn.mass_matrix(q), m_ref[np.ix_(idx, idx)]) < 1e-12
    tau_ref = pin.rnea(model, data, pq, pv, pa)
    assert helpers.rel_err(dyn.inverse_dynamics(q, qd, qdd), tau_ref[idx]) < 1e-12


def _with_world(tmp_path, origin: str = "") -> Path:
    """Solo12 with a ``world`` link and a floating joint from it to the base, as files written for MuJoCo have."""
    text = helpers.URDFS["solo12"].read_text()
    first = text.index("<link ")
    world = ('<link name="world"/>\n<joint name="floating_base_joint" type="floating"><parent link="world"/>'
             f'<child link="base_link"/>{origin}</joint>\n')
    path = tmp_path / "solo12_world.urdf"
    path.write_text(text[:first] + world + text[first:])
    return path


def test_a_floating_joint_from_the_root_is_the_floating_base(tmp_path):
    """Read as ``floating_base=True`` on the file without it, and as Pinocchio reads the file (a free-flyer)."""
    path = _with_world(tmp_path)
    robot = jaxskid.load(path)
    assert robot.floating_base and robot.base == "base_link" and robot.n_dof == 12
    assert robot.fingerprint() == jaxskid.load(helpers.URDFS["solo12"], floating_base=True).fingerprint()
    model = pin.buildModelFromUrdf(str(path))
    assert model.joints[1].shortname() == "JointModelFreeFlyer"
    data = model.createData()
    rng = np.random.default_rng(5)
    quat = rng.normal(size=4)
    q = np.r_[rng.uniform(-1, 1, 3), quat / np.linalg.norm(quat), rng.uniform(-1, 1, 12)]
    qd, qdd = rng.uniform(-1, 1, (2, 18))
    names = [model.names[k] for k in range(2, model.njoints)]
    assert names == list(robot.joint_names)  # the same depth-first order
    swap = np.r_[3:6, 0:3, 6:18]  # jaxskid's base velocity is (omega, v), Pinocchio's (v, omega)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    m_ref = pin.crba(model, data, q)
    m_ref = np.triu(m_ref) + np.triu(m_ref, 1).T
    assert helpers.rel_err(dyn.mass_matrix(q), m_ref[np.ix_(swap, swap)]) < 1e-12
    tau_ref = pin.rnea(model, data, q, qd[swap], qdd[swap])
    assert helpers.rel_err(dyn.inverse_dynamics(q, qd, qdd), tau_ref[swap]) < 1e-12


def test_a_floating_joint_with_an_origin_or_below_the_root_is_refused(tmp_path):
    path = _with_world(tmp_path, '<origin xyz="0 0 1"/>')
    with pytest.raises(ModelError) as info:
        jaxskid.load(path)
    assert info.value.where == "joint[name=floating_base_joint].origin" and "identity" in info.value.message
    text = path.read_text()
    path.write_text(text.replace('<joint name="FL_HAA" type="revolute">', '<joint name="FL_HAA" type="floating">'))
    with pytest.raises(ModelError) as info:
        jaxskid.load(path)
    assert info.value.where == "joint[name=FL_HAA].type" and "below the root" in info.value.message
