"""Drives in written files: ``jaxskid template --drives`` loads back with a drive per joint whose torque is
its formula, and ``jaxskid.write_urdf`` writes each drive's friction as ``<dynamics damping friction>`` and a
joint's limits as ``<limit>``, read back by an independent parser (yourdfpy) and by ``jaxskid.load``."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

import numpy as np
import pytest
import yaml
import yourdfpy

import jaxskid
from helpers import ROBOTS_DIR
from jaxskid._cli import main
from jaxskid.description._urdf_writer import numeric_robot

NAMES = ("joint1", "joint2", "joint3")


def _template(tmp_path, capsys, *flags, ext="yaml"):
    path = tmp_path / f"rrp_arm.{ext}"
    with pytest.raises(SystemExit) as done:
        main(["template", *flags, "-S", "RRP", str(path)])
    assert done.value.code == 0 and "with drives" in capsys.readouterr().out
    return path


def _load(path):
    if path.suffix != ".py":
        return jaxskid.load(path, drives=True)
    spec = importlib.util.spec_from_file_location(f"drives_template_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.robot


# ------------------------------------------------------------------------------------------ templates
@pytest.mark.parametrize("flags, ext", [((), "yaml"), (("--dh",), "json"), ((), "py")],
                         ids=["yaml", "dh-json", "py"])
def test_template_with_drives_loads_and_adds_the_drive_torque(tmp_path, capsys, flags, ext):
    """Every joint is driven by the parameters J_Ia, J_fv, J_fc, J_fo (defaults as written); tau minus tau
    with the drives zeroed is Ia qdd + fv qd + fc sign(qd) + fo, with parameter values of our choosing."""
    path = _template(tmp_path, capsys, "--drives", *flags, ext=ext)
    robot = _load(path)
    assert robot.driven == (0, 1, 2)
    defaults = robot.default_params()
    if ext != "py":  # the file's own drives list and assignments
        data = yaml.safe_load(path.read_text())
        assert [d["viscous"] for d in data["drives"]] == [f"{j}_fv" for j in NAMES]
        assert {f"{j}_{p}": defaults[f"{j}_{p}"] for j in NAMES for p in ("Ia", "fv", "fc", "fo")} == {
            f"{j}_{p}": data["assignments"][f"{j}_{p}"] for j in NAMES for p in ("Ia", "fv", "fc", "fo")}
    assert defaults["joint2_Ia"] > 0 and defaults["joint2_fv"] > 0 and defaults["joint2_fc"] > 0
    dyn = jaxskid.lower(robot, ["inverse_dynamics"])
    rng = np.random.default_rng(5)
    ia, fv, fc, fo = rng.uniform(0.05, 0.5, (4, 3))
    drive = {f"{j}_{p}": v[k] for k, j in enumerate(NAMES) for p, v in zip(("Ia", "fv", "fc", "fo"), (ia, fv, fc, fo))}
    bare = {name: 0.0 for name in drive}
    q, qd, qdd = rng.uniform(-2, 2, (3, 3))
    tau = np.asarray(dyn.inverse_dynamics(q, qd, qdd, {**defaults, **drive}))
    rigid = np.asarray(dyn.inverse_dynamics(q, qd, qdd, {**defaults, **bare}))
    np.testing.assert_allclose(tau - rigid, ia * qdd + fv * qd + fc * np.sign(qd) + fo, rtol=1e-12, atol=1e-12)


def test_template_without_drives_is_unchanged_and_drives_need_a_chain(tmp_path, capsys):
    path = tmp_path / "plain.yaml"
    with pytest.raises(SystemExit) as done:
        main(["template", "-S", "RR", str(path)])
    assert done.value.code == 0 and "drives" not in path.read_text()
    assert jaxskid.load(path).driven == ()
    with pytest.raises(SystemExit) as done:
        main(["template", "--drives", "--urdf", str(path), str(tmp_path / "x.py")])
    assert done.value.code == 2 and "--drives" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ URDF writer
@dataclass(frozen=True)
class Limits:
    """What the URDF writer reads of a joint's ``limits`` (lower, upper, velocity, effort; inf if unknown)."""

    lower: float
    upper: float
    velocity: float
    effort: float


def _driven_arm():
    """The 2R arm with drives: friction, armature and offset of our choosing, every parameter a number."""
    values = {"shoulder_Ia": 0.03, "shoulder_fv": 0.25, "shoulder_fc": 0.125, "shoulder_fo": 0.5,
              "elbow_Ia": 0.0, "elbow_fv": 0.0625, "elbow_fc": 0.0, "elbow_fo": 0.0}
    robot = jaxskid.load(ROBOTS_DIR / "arm_2r.yaml").with_drives(values)
    return numeric_robot(robot), values


def test_urdf_writer_writes_drive_friction_as_dynamics(tmp_path):
    robot, values = _driven_arm()
    path = tmp_path / "arm.urdf"
    with pytest.warns(jaxskid.DescriptionWarning, match="gravity"):  # arm_2r's gravity is along -y
        jaxskid.write_urdf(robot, path)
    parsed = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
    joints = {j.name: j for j in parsed.robot.joints}
    for name in robot.joint_names:
        dynamics = joints[name].dynamics  # yourdfpy keeps these two attributes as strings
        assert float(dynamics.damping) == values[f"{name}_fv"] and float(dynamics.friction) == values[f"{name}_fc"]
        assert joints[name].limit.effort == 0 and joints[name].limit.velocity == 0  # placeholders
    back = jaxskid.load(path, drives=True).default_params()
    for name in robot.joint_names:
        assert back[f"{name}_fv"] == values[f"{name}_fv"] and back[f"{name}_fc"] == values[f"{name}_fc"]
    text = path.read_text()
    assert "no field for the" in text and "armature: shoulder 0.03." in text and "torque offset: shoulder 0.5." in text
    assert "elbow 0.0" not in text  # zero armature and offset are not listed
    plain = tmp_path / "plain.urdf"
    with pytest.warns(jaxskid.DescriptionWarning):
        jaxskid.write_urdf(jaxskid.load(ROBOTS_DIR / "arm_2r.yaml"), plain)
    assert all(j.dynamics is None for j in yourdfpy.URDF.load(str(plain), build_scene_graph=False,
                                                                load_meshes=False).robot.joints)


def test_urdf_writer_writes_known_joint_limits(tmp_path):
    """A joint's limits (when the model holds them) fill <limit>; unknown (inf) ones keep the placeholders."""
    robot, _ = _driven_arm()
    given = {"shoulder": Limits(-2.5, 2.0, 3.0, 40.0), "elbow": Limits(-np.inf, 1.5, np.inf, 12.0)}
    for j in robot.joints:
        object.__setattr__(j, "limits", given[j.name])
    path = tmp_path / "limited.urdf"
    with pytest.warns(jaxskid.DescriptionWarning):
        jaxskid.write_urdf(robot, path)
    joints = {j.name: j.limit for j in yourdfpy.URDF.load(str(path), build_scene_graph=False,
                                                          load_meshes=False).robot.joints}
    assert (joints["shoulder"].lower, joints["shoulder"].upper) == (-2.5, 2.0)
    assert (joints["shoulder"].velocity, joints["shoulder"].effort) == (3.0, 40.0)
    assert (joints["elbow"].lower, joints["elbow"].upper) == (None, 1.5)
    assert (joints["elbow"].velocity, joints["elbow"].effort) == (0.0, 12.0)
    assert "Joint limits from the model" in path.read_text()
