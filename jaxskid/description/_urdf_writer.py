"""Writing a :class:`Robot` as a URDF file (https://wiki.ros.org/urdf/XML), with numbers only.

A URDF joint turns about (slides along) an axis through the origin of its child link's frame, while a body
frame of jaxskid's model may sit anywhere off its joint's axis. So link i's URDF frame is body i's frame
moved, axes unchanged, to ``r_i = omega x v``, the point of the axis nearest the body's origin (revolute
screw ``X_i = (omega, v)``; ``r_i = 0`` for a prismatic joint). Then, with ``B_i`` body i's pose in its
parent's frame at q = 0 (:mod:`jaxskid.model._robot`):

* the joint's ``<origin>`` is ``T(-r_p) B_i T(r_i)`` (``r_p`` the parent's shift; 0 for the base link), as
  ``xyz`` and ``rpy`` with ``R = Rz(yaw) Ry(pitch) Rx(roll)``; its ``<axis>`` is ``omega`` or ``v``;
* the link's ``<inertial>`` holds the mass ``m``, the centre of mass ``c - r_i`` (``rpy`` zero) and the
  inertia about the centre of mass in the body's axes, ``I_c = I_o + m c~ c~`` (the parallel-axis theorem
  on the 6x6 ``[[I_o, m c~], [-m c~, m 1]]``); a body without mass or inertia gets none;
* every named frame (an end-effector, a merged link) is a link on a ``fixed`` joint, at ``T(-r_b) offset``.

Reading the file back (:func:`jaxskid.load`, or Pinocchio's ``buildModelFromUrdf``) gives the same dynamics,
in the reader's joint order (a depth-first walk, children by name). URDF holds neither parameters nor
gravity: every parameter takes its default value (one without raises :class:`ModelError` naming it), and a
gravity other than the URDF readers' (0, 0, -9.81) is written as a comment, with a
:class:`DescriptionWarning` (load it with ``jaxskid.load(path, gravity=...)``).

* A joint's drive (:class:`~jaxskid.Drive`) gives its ``<dynamics damping="fv" friction="fc">`` (viscous and
  Coulomb friction, which ``jaxskid.load(path, drives=True)`` reads back as the defaults of ``J_fv`` and
  ``J_fc``). URDF has no field for the armature or the torque offset: those that are not zero are listed in
  the file's comment.
* Revolute and prismatic joints need a ``<limit>`` element (urdfdom). A joint's ``limits`` (lower, upper,
  velocity, effort; infinite where unknown), when the model holds them, give its attributes; unknown bounds
  are left out (URDF readers take 0) and an unknown velocity or effort is written as the placeholder 0, as is
  every limit of a joint without ``limits``; the file's comment says so.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import sympy as sp

from .._errors import DescriptionWarning, ModelError
from ..model._robot import Robot

URDF_GRAVITY = (0.0, 0.0, -9.81)


def numeric_robot(robot: Robot, *, what: str = "a URDF") -> Robot:
    """``robot`` with every parameter replaced by its default value; a parameter without one raises."""
    defaults = robot.default_params()
    missing = [repr(p) for p in robot.parameters if p not in defaults]
    if missing:
        which = (f"parameter {missing[0]} has no default value" if len(missing) == 1 else
                 f"parameters {', '.join(missing)} have no default values")
        them = "it a value" if len(missing) == 1 else "them values"
        raise ModelError(f"{which}; {what} holds numbers only: give {them} (assignments in a description, "
                         f"defaults in Python)")
    return robot.substitute(list(robot.parameters)) if robot.parameters else robot


def _array(m) -> np.ndarray:
    """A SymPy matrix of numbers as floats, each entry rounded once from its exact value."""
    m = sp.Matrix(m)
    return np.array([[float(m[r, c]) for c in range(m.cols)] for r in range(m.rows)])


def rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of a rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (URDF).

    Yaw first, then pitch and roll from ``Rz(yaw)^T R = Ry(pitch) Rx(roll)``, so that the angles rebuild
    ``R`` to round-off everywhere, at pitch = +-pi/2 too (yaw is then 0 and roll takes the whole turn).
    """
    yaw = math.atan2(r[1, 0], r[0, 0]) if abs(r[1, 0]) + abs(r[0, 0]) > 1e-12 else 0.0
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ r
    return math.atan2(-m[1, 2], m[1, 1]), math.atan2(-m[2, 0], m[0, 0]), yaw


def _numbers(values) -> str:
    return " ".join(repr(float(x) + 0.0) for x in values)  # + 0.0: no -0.0


def _origin(parent: ET.Element, c: np.ndarray) -> None:
    ET.SubElement(parent, "origin", xyz=_numbers(c[:3, 3]), rpy=_numbers(rpy_of(c[:3, :3])))


def _shift(x: np.ndarray, kind: str) -> np.ndarray:
    """The point of a revolute joint's axis nearest the body origin, ``omega x v``; zero for a prismatic one."""
    return np.cross(x[:3], x[3:]) if kind == "revolute" else np.zeros(3)


def _translation(p) -> np.ndarray:
    c = np.eye(4)
    c[:3, 3] = p
    return c


def _inertial(link: ET.Element, m6: np.ndarray, r: np.ndarray) -> None:
    """The ``<inertial>`` of a body with 6x6 mass-inertia ``m6`` in a link frame shifted by ``r``."""
    m, io = m6[5, 5], m6[:3, :3]
    if m == 0 and not io.any():
        return
    c = np.array([m6[2, 4], m6[0, 5], m6[1, 3]]) / m if m > 0 else np.zeros(3)
    cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
    ic = io + m * cx @ cx
    ic = 0.5 * (ic + ic.T)
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "origin", xyz=_numbers(c - r), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=_numbers([m]))
    ET.SubElement(inertial, "inertia", **{k: _numbers([ic[a, b]]) for k, (a, b) in
                                          (("ixx", (0, 0)), ("ixy", (0, 1)), ("ixz", (0, 2)),
                                           ("iyy", (1, 1)), ("iyz", (1, 2)), ("izz", (2, 2)))})


def _joint(root, name, kind, parent, child, origin) -> ET.Element:
    joint = ET.SubElement(root, "joint", name=name, type=kind)
    _origin(joint, origin)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    return joint


def _known(value) -> float | None:
    """A limit as a float, ``None`` where it is unknown (infinite, NaN or not a number)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _limits(j) -> dict[str, str]:
    """The ``<limit>`` attributes of joint ``j``: its ``limits`` where known, else the placeholders."""
    limits = getattr(j, "limits", None)
    known = {k: _known(getattr(limits, k, None)) for k in ("lower", "upper", "velocity", "effort")}
    out = {k: _numbers([v]) for k, v in known.items() if v is not None}
    return {"effort": "0", "velocity": "0", **out}


def _dynamics_and_limit(joint: ET.Element, j) -> None:
    """The ``<dynamics>`` (from the drive's friction), ``<limit>`` and ``<mimic>`` elements of a moving joint."""
    if j.drive is not None:
        ET.SubElement(joint, "dynamics", damping=_numbers([float(j.drive.viscous)]),
                      friction=_numbers([float(j.drive.coulomb)]))
    ET.SubElement(joint, "limit", **_limits(j))
    mimic = getattr(j, "mimic", None)
    if mimic is not None:
        ET.SubElement(joint, "mimic", joint=mimic.joint, multiplier=_numbers([float(mimic.multiplier)]),
                      offset=_numbers([float(mimic.offset)]))


def robot_to_urdf(robot: Robot) -> str:
    """The URDF text of ``robot`` (its parameters at their defaults); see the module docstring."""
    robot = numeric_robot(robot)
    root = ET.Element("robot", name=robot.name)
    base = ET.SubElement(root, "link", name=robot.base)
    if robot.floating_base:
        _inertial(base, _array(robot.base_inertia), np.zeros(3))
    shifts = []
    for i, j in enumerate(robot.joints):
        x = _array(sp.Matrix(j.screw)).ravel()
        shifts.append(_shift(x, j.type))
        parent = robot.base if j.parent < 0 else robot.joints[j.parent].link
        parent_shift = np.zeros(3) if j.parent < 0 else shifts[j.parent]
        link = ET.SubElement(root, "link", name=j.link)
        _inertial(link, _array(j.inertia), shifts[i])
        origin = _translation(-parent_shift) @ _array(j.origin) @ _translation(shifts[i])
        joint = _joint(root, j.name, j.type, parent, j.link, origin)
        ET.SubElement(joint, "axis", xyz=_numbers(x[:3] if j.type == "revolute" else x[3:]))
        _dynamics_and_limit(joint, j)
    names = {j.name for j in robot.joints}  # mimic joints included
    for f in robot.frames:
        parent = robot.base if f.body < 0 else robot.joints[f.body].link
        shift = np.zeros(3) if f.body < 0 else shifts[f.body]
        name = f"{f.name}_joint"
        while name in names:
            name += "_"
        names.add(name)
        ET.SubElement(root, "link", name=f.name)
        _joint(root, name, "fixed", parent, f.name, _translation(-shift) @ _array(f.offset))
    ET.indent(root, space="  ")
    return _header(robot) + ET.tostring(root, encoding="unicode") + "\n"


def _header(robot: Robot) -> str:
    gravity = tuple(float(g) for g in robot.gravity)
    lines = ['<?xml version="1.0"?>',
             f"<!-- {robot.name}: written by jaxskid (jaxskid convert); every parameter at its default value."]
    if any(getattr(j, "limits", None) is not None for j in robot.joints):
        lines.append("     Joint limits from the model; unknown ones are placeholders (effort 0, velocity 0; lower and "
                     "upper left out).")
    else:
        lines.append("     Joint limits are placeholders (effort 0, velocity 0): the model holds none.")
    lines += _drive_notes(robot)
    if robot.floating_base:
        lines.append(f"     The root link {robot.base!r} is a floating base (URDF has none): load with "
                     "jaxskid.load(path, floating_base=True).")
    if not np.allclose(gravity, URDF_GRAVITY, rtol=0, atol=1e-15):
        lines.append(f"     Gravity {list(gravity)} (URDF has none): load with jaxskid.load(path, gravity=...).")
    return "\n".join(lines) + " -->\n"


def _drive_notes(robot: Robot) -> list[str]:
    """Comment lines on the drives: friction in ``<dynamics>``; armature and offset, which URDF cannot hold."""
    driven = [j for j in robot.joints if j.drive is not None]
    if not driven:
        return []
    lines = ["     Drives: viscous and Coulomb friction as <dynamics damping friction>. URDF has no field for the",
             "     armature (reflected rotor inertia) or the torque offset; they are not written."]
    for field, what in (("armature", "armature"), ("offset", "torque offset")):
        values = [f"{j.name} {float(getattr(j.drive, field))!r}" for j in driven if float(getattr(j.drive, field))]
        if values:
            lines.append(f"     Not written, {what}: " + ", ".join(values) + ".")
    return lines


def write_urdf(robot: Robot, path, *, force: bool = False) -> None:
    """Write ``robot`` as a URDF file (numbers only: parameters at their defaults); an existing file needs
    ``force=True``. A gravity other than (0, 0, -9.81), which URDF cannot hold, gives a
    :class:`DescriptionWarning`.

    Raises:
        ModelError: a parameter has no default value, or ``path`` does not end in ``.urdf``.
    """
    path = Path(path)
    if path.suffix.lower() != ".urdf":
        raise ModelError(f"expected a file name ending in .urdf, got {path.suffix or 'none'!r}", source=str(path))
    robot = numeric_robot(robot)
    text = robot_to_urdf(robot)
    gravity = tuple(float(g) for g in robot.gravity)
    if not np.allclose(gravity, URDF_GRAVITY, rtol=0, atol=1e-15):
        warnings.warn(f"{path}: gravity {list(gravity)} is not written (URDF has no gravity; readers assume "
                      f"{list(URDF_GRAVITY)}): load it with jaxskid.load(path, gravity=...)",
                      DescriptionWarning, stacklevel=2)
    try:
        with path.open("w" if force else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise FileExistsError(f"{path} already exists; pass force=True to overwrite it") from None
