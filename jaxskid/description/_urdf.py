"""Read a fixed-base robot from a URDF file (https://wiki.ros.org/urdf/XML) into a :class:`Robot`.

The file is parsed strictly with lxml and checked here, so that every problem is reported as a
:class:`ModelError` that names the file, the key path (``joint[name=j2].axis``) and what was expected;
the numbers are then read through yourdfpy (without loading meshes).

Conventions, chosen to match Pinocchio's ``buildModelFromUrdf`` (``pinocchio/parsers/urdf``):

* the root link is welded to the world; its inertia is dropped and its name is ``Robot.base``; with
  ``floating_base=True`` it is the free-flyer base body instead (Pinocchio's ``buildModelFromUrdf(path,
  JointModelFreeFlyer())``), which keeps its inertia (10 parameters ``{root}_m, ...`` like every body's); a
  ``floating`` joint from the root link (``world`` -> base, as files written for MuJoCo have) is read the same
  way, its child the base body, as Pinocchio reads it (a ``floating`` joint anywhere else is refused);
* the frame of a child link is its joint's frame, ``B_i = origin(xyz, rpy)`` with
  ``R = Rz(yaw) Ry(pitch) Rx(roll)``; the screw is ``(a, 0)`` (revolute, continuous) or ``(0, a)``
  (prismatic), ``a`` the joint axis normalised to unit length;
* the order of ``q`` is a depth-first walk from the root in which the joints leaving a link are taken in
  the order of their names, as urdfdom stores them (a ``std::map``); fixed joints are walked through;
* fixed and locked links are welded to their parent body (:func:`jaxskid.model._fixed.merge_fixed`, on
  the numeric inertias): their inertia is added to it and they stay reachable as :class:`Frame` s; with
  ``symbolic_inertia`` the 10 parameters describe the merged body;
* the default end-effectors are the leaf links, except those welded to the world;
* a link without ``<inertial>`` is massless;
* with ``drives``, every moving joint gets a drive whose viscous and Coulomb friction default to its
  ``<dynamics damping friction>`` (which Pinocchio stores but no algorithm of it uses);
* a ``<mimic>`` joint is read as an independent joint, as Pinocchio's default, with a warning naming
  ``mimic=True``; with ``mimic=True`` it follows its joint (:mod:`jaxskid.model._mimic`), as Pinocchio's
  ``buildModelFromUrdf(path, mimic=True)``. A ``<mimic>`` on a fixed joint is ignored.
* a joint's ``<limit>`` becomes its :class:`~jaxskid.JointLimits` (:mod:`._urdf_limits`; metadata only).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import sympy as sp

from .._errors import DescriptionWarning, ModelError
from ..model import _lie as lie
from ..model._fixed import lock_joint, merge_fixed
from ..model._drive import Drive, drive_parameter_names
from ..model._mimic import Mimic, follow_locks, resolve
from ..model._robot import Joint, Robot
from ..model._validate import LARGEST, check_mass, check_positive_semidefinite
from ._keymap import KeyMap
from ._urdf_inertia import (balanced, base_parameters, exact, inertial_parameters, link_inertia, put_balanced,
                             root_inertia, rotation_translation)
from ._urdf_limits import NUMERIC_JOINT_ATTRIBUTES, joint_limits
from ._urdf_tree import walk_tree
from ._urdf_xml import dynamics_only, load_yourdfpy, parse_xml, read_bytes

_JOINT_TYPES = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic", "fixed": "fixed"}
_SUPPORTED = ", ".join(_JOINT_TYPES)
_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
_XML_SPACE = " \t\r\n"
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?|[+-]?(inf|infinity|nan)", re.IGNORECASE)
"""A number as urdfdom reads it: ASCII digits (no ``1_0``, no other scripts' digits), separated by XML space."""


def read_urdf(
    path: str | os.PathLike,
    *,
    lock: Mapping[str, float] | None = None,
    symbolic_inertia: bool = True,
    gravity: Sequence = (0, 0, -9.81),
    end_effectors: Sequence[str] | None = None,
    drives: bool = False,
    mimic: bool = False,
    floating_base: bool = False,
    balance_inertia: bool = False,
) -> Robot:
    """Build a :class:`Robot` from the URDF file ``path``.

    Args:
        path: the ``.urdf`` file (already expanded: no xacro).
        lock: joint name -> position; those joints are fixed there and their links merged into the parent.
        symbolic_inertia: if True, the 6x6 inertia of every moving body is written with its 10 standard
            parameters ``{link}_m, {link}_mcx, {link}_mcy, {link}_mcz, {link}_Ixx, {link}_Ixy, {link}_Iyy,
            {link}_Ixz, {link}_Iyz, {link}_Izz`` (about the body frame's origin, Pinocchio's
            ``toDynamicParameters`` order; ``link`` made a valid identifier), with the URDF values (after
            fixed and locked links are merged in) as defaults. If False, inertias are numbers.
        gravity: gravitational acceleration in the world (root link) frame.
        end_effectors: link names marked as end-effectors; default: the leaf links of the tree, except
            those welded to the world (their Jacobian is zero).
        drives: if True, every moving joint ``J`` gets a drive (:class:`~jaxskid.model._drive.Drive`) with
            the parameters ``J_Ia, J_fv, J_fc, J_fo``, defaults ``0, damping, friction, 0`` from the joint's
            ``<dynamics>`` (0 without it), mimic joints included (acting through the coupling).
        mimic: couple ``<mimic joint="j" multiplier="a" offset="b"/>`` joints, ``q = a q_j + b`` (else they
            are independent joints, with a :class:`~jaxskid.DescriptionWarning`).
        floating_base: make the root link a free-flyer base body (:attr:`Robot.floating_base`): ``q`` is then
            ``(x, y, z, qx, qy, qz, qw, joint positions)`` and velocities ``(omega, v, joint velocities)``.
        balance_inertia: replace each ``<inertia>`` that no rigid body has (not positive semi-definite, or
            principal moments that break the triangle inequality) by the isotropic one of the same trace, as
            MuJoCo's ``balanceinertia``, with one :class:`~jaxskid.DescriptionWarning` naming the links (else
            the first that is not positive semi-definite is a :class:`ModelError`).

    Returns:
        the robot, with ``n_dof`` = number of revolute, continuous and prismatic joints, not locked or mimic.

    Raises:
        ModelError: ``"<path>: <key path>: expected ..., got ..."`` for an unreadable or malformed file,
            an unsupported joint (planar; floating other than from the root link), a link tree that is not a
            tree with one root, or invalid inertial values.
    """
    source = os.fspath(path)
    try:
        return _read(source, lock, symbolic_inertia, gravity, end_effectors, drives, mimic, floating_base,
                     balance_inertia)
    except ModelError as err:
        raise err.located(source=source) from None


def _read(source, lock, symbolic_inertia, gravity, end_effectors, drives, mimic, floating_base,
          balance_inertia=False) -> Robot:
    data = read_bytes(source)
    fixes = {} if balance_inertia else None
    document = parse_xml(data)
    _check_document(document, mimic, fixes)
    urdf = load_yourdfpy(dynamics_only(document)).robot
    order, root_link, floating_root = walk_tree(urdf.links, urdf.joints)
    if floating_root and floating_base is False:  # a value other than a bool stays, to be refused by name
        floating_base = True
    links = {link.name: link for link in urdf.links}
    put_balanced(source, links, fixes)
    locked = _check_lock(lock, order)
    mimics = _mimics(order) if mimic else None
    if mimics:
        locked = {k: float(v) for k, v in follow_locks(mimics, locked).items()}
    requested = _check_end_effectors(end_effectors, links)
    # Weld fixed (and locked) links into their parent body first, with numeric inertias, so that with
    # symbolic_inertia the 10 parameters of each moving body describe the merged body.
    base_inertia = root_inertia(floating_base, links[root_link])
    joints, frames, base_inertia = merge_fixed(_joints(source, order, links, locked, mimics), [], base_inertia)
    joints, defaults = inertial_parameters(joints, symbolic_inertia)
    base_inertia, base_defaults = base_parameters(root_link, base_inertia, symbolic_inertia, joints)
    defaults.update(base_defaults)
    if drives:
        joints, more = _drives(joints, {j.name: j for j in order})
        defaults.update(more)
    if requested is None:
        requested = _default_end_effectors(order, frames)
    keys = KeyMap({"end_effectors": "end_effectors", "gravity": "gravity", "floating_base": "floating_base",
                   "base_inertia": f"link[name={root_link}].inertial"})
    for k, j in enumerate(joints):
        for part, key in (("origin", "origin"), ("screw", "axis"), ("name", "name"), ("link", "child")):
            keys.add(f"joints[{k}].{part}", f"joint[name={j.name}].{key}")
        keys.add(f"joints[{k}].inertia", f"link[name={j.link}].inertial")
        keys.add(f"joints[{k}].drive", f"joint[name={j.name}].dynamics")
        keys.add(f"joints[{k}].mimic", f"joint[name={j.name}].mimic")
        keys.add(f"joints[{k}].limits", f"joint[name={j.name}].limit")
    for k, f in enumerate(frames):
        keys.add(f"frames[{k}]", f"link[name={f.name}]")
    try:
        return Robot.create(urdf.name, joints, gravity, frames, requested, defaults, base=root_link,
                            floating_base=floating_base, base_inertia=base_inertia)
    except ModelError as err:
        raise keys.relocate(err) from None


def _mimics(order) -> dict[str, Mimic]:
    """The ``<mimic>`` of every moving joint, chains composed (:func:`jaxskid.model._mimic.resolve`)."""
    given = {j.name: Mimic(j.mimic.joint, exact(1.0 if j.mimic.multiplier is None else j.mimic.multiplier),
                           exact(j.mimic.offset or 0.0)) for j in order if j.mimic is not None and j.type != "fixed"}
    return resolve(given, {j.name: _JOINT_TYPES[j.type] for j in order}, lambda name: f"joint[name={name}].mimic")


def _joints(source, order, links, locked, mimics) -> list[Joint]:
    """The URDF joints in the order of the walk: locked ones fixed, mimic ones coupled by ``mimics`` (or None)."""
    body = {order[0].parent: -1} if order else {}
    joints, dropped = [], []
    for k, j in enumerate(order):
        body[j.child] = k
        kind = _JOINT_TYPES[j.type]
        m6 = link_inertia(links[j.child].inertial)
        joint = Joint(j.name, kind, body[j.parent], _pose(j.origin), _screw(kind, j.axis),
                      sp.ImmutableMatrix(6, 6, [exact(x) for x in m6.flat]), j.child, limits=joint_limits(j))
        if j.name in locked:
            joint = lock_joint(joint, exact(locked[j.name]))
        elif mimics is not None and j.name in mimics:
            joint = replace(joint, mimic=mimics[j.name])
        elif mimics is None and j.mimic is not None and kind != "fixed":
            dropped.append((j.name, j.mimic.joint))
        joints.append(joint)
    _warn_dropped_mimics(source, dropped, {j.name for j in order})
    return joints


def _warn_dropped_mimics(source: str, dropped: list[tuple[str, str]], names: set[str]) -> None:
    """One warning for the ``<mimic>`` joints read as independent joints (``(joint, followed joint)``)."""
    if not dropped:
        return
    (first, target), more = dropped[0], len(dropped) - 1

    def coupling(joint: str, followed: str) -> str:
        return f"{joint!r} to {followed!r}" + ("" if followed in names else " (no joint of that name)")

    if more:
        listed = ", ".join(coupling(a, b) for a, b in dropped)
        text = f"read as independent joints with {more} more <mimic> joints (their couplings dropped: {listed})"
    else:
        text = f"read as an independent joint (its coupling to {target!r} is dropped" + (
            ")" if target in names else "; there is no joint of that name)")
    warnings.warn(f"{source}: joint[name={first}].mimic: {text}; load with mimic=True to couple "
                  f"{'them' if more else 'it'}", DescriptionWarning, stacklevel=6)


def _drives(joints: list[Joint], urdf_joints: Mapping) -> tuple[list[Joint], dict[str, float]]:
    """Every joint with :meth:`Drive.symbolic`, and the defaults of its parameters (``<dynamics>``'s
    ``damping`` and ``friction`` for ``J_fv`` and ``J_fc``)."""
    out, defaults, owner = [], {}, {}
    for j in joints:
        names = drive_parameter_names(j.name)
        if names[0] in owner:
            raise ModelError(f"expected joint names that stay distinct as identifiers, got {owner[names[0]]!r} and "
                             f"{j.name!r} (both give parameters {', '.join(names)})", where=f"joint[name={j.name}].name")
        owner[names[0]] = j.name
        dynamics = urdf_joints[j.name].dynamics
        damping, friction = (0.0, 0.0) if dynamics is None else (dynamics.damping or 0.0, dynamics.friction or 0.0)
        defaults.update(zip(names, (0.0, float(damping), float(friction), 0.0)))
        out.append(replace(j, drive=Drive.symbolic(j.name)))
    return out, defaults


def _default_end_effectors(order, frames) -> tuple[str, ...]:
    """The leaf links, in the order of the walk, except those welded to the world (their Jacobian is zero)."""
    parents = {j.parent for j in order}
    on_world = {f.name for f in frames if f.body < 0}
    return tuple(j.child for j in order if j.child not in parents and j.child not in on_world)


def _check_lock(lock, order) -> dict[str, float]:
    moving = [j.name for j in order if j.type != "fixed"]
    out = {}
    for name, value in (lock or {}).items():
        if name not in moving:
            raise ModelError(
                f"expected the name of a revolute, continuous or prismatic joint, got {name!r}; "
                f"joints are {', '.join(moving)}",
                where="lock",
            )
        try:
            out[name] = float(value)
        except (TypeError, ValueError):
            out[name] = math.nan
        if not math.isfinite(out[name]):
            raise ModelError(f"expected a finite number, got {value!r}", where=f"lock.{name}")
    return out


def _check_end_effectors(end_effectors, links) -> tuple[str, ...] | None:
    if end_effectors is None:
        return None
    end_effectors = (end_effectors,) if isinstance(end_effectors, str) else tuple(end_effectors)
    unknown = [e for e in end_effectors if e not in links]
    if unknown:
        raise ModelError(
            f"expected link names, got {', '.join(map(repr, unknown))}; links are {', '.join(links)}",
            where="end_effectors",
        )
    return end_effectors


# ---------------------------------------------------------------------------------------------- checking


def _check_document(root, coupled: bool = False, fixes: dict | None = None) -> None:
    """Everything yourdfpy would accept silently, misread, or fail on with a bare exception. A ``<mimic>`` of
    an unknown joint is an error only when ``coupled`` (``mimic=True``; else the coupling is dropped anyway);
    with ``fixes`` (a dict), the inertias that :func:`balanced` changes are put there by link name instead of
    refused."""
    if not root.get("name"):
        raise ModelError("expected a non-empty name attribute", where="robot.name")
    links = root.findall("link")
    if not links:
        raise ModelError("expected at least one <link>", where="robot")
    link_names: set[str] = set()
    for k, el in enumerate(links):
        name = el.get("name")
        if not name:
            raise ModelError("expected a non-empty name attribute", where=f"link[{k}].name")
        if name in link_names:
            raise ModelError(f"expected unique link names, got {name!r} twice", where=f"link[name={name}].name")
        link_names.add(name)
        inertial = el.find("inertial")
        if inertial is not None:
            _check_inertial(inertial, f"link[name={name}].inertial", fixes, name)

    joint_names: set[str] = set()
    mimics, floating = [], []
    for k, el in enumerate(root.findall("joint")):
        name = el.get("name")
        if not name:
            raise ModelError("expected a non-empty name attribute", where=f"joint[{k}].name")
        where = f"joint[name={name}]"
        if name in joint_names:
            raise ModelError(f"expected unique joint names, got {name!r} twice", where=f"{where}.name")
        joint_names.add(name)
        kind = el.get("type")
        if kind == "floating":
            floating.append((where, el))
        elif kind not in _JOINT_TYPES:
            if kind == "planar":
                got = f"unsupported type {kind!r} (trees of revolute and prismatic joints, a floating base at the root)"
            else:
                got = "no type" if kind is None else f"unknown type {kind!r}"
            raise ModelError(f"expected one of {_SUPPORTED}, got {got}", where=f"{where}.type")
        for tag in ("parent", "child"):
            sub = el.find(tag)
            link = None if sub is None else sub.get("link")
            if not link:
                raise ModelError(f'expected a <{tag} link="..."/> element', where=f"{where}.{tag}")
            if link not in link_names:
                raise ModelError(f"expected the name of a link, got {link!r}", where=f"{where}.{tag}")
        _check_origin(el.find("origin"), f"{where}.origin")
        axis = el.find("axis")
        if axis is not None and kind != "fixed":
            a = _floats(axis.get("xyz", "1 0 0"), 3, f"{where}.axis")
            if not any(a):
                raise ModelError(f"expected a non-zero axis, got {axis.get('xyz')!r}", where=f"{where}.axis")
        for tag, attrs in NUMERIC_JOINT_ATTRIBUTES.items():
            sub = el.find(tag)
            for attr in attrs if sub is not None else ():
                if sub.get(attr) is not None:  # +-inf is a usable limit (not friction); nan and words are not
                    _floats(sub.get(attr), 1, f"{where}.{tag}.{attr}", infinite=tag != "dynamics")
        mimic = el.find("mimic")
        if mimic is not None:
            for attr in ("multiplier", "offset"):
                if mimic.get(attr) is not None:
                    _floats(mimic.get(attr), 1, f"{where}.mimic.{attr}")
            mimics.append((where, mimic.get("joint")))
    edges = [(j.find("parent").get("link"), j.find("child").get("link")) for j in root.findall("joint")]
    _check_floating(floating, edges)
    for where, target in mimics if coupled else ():
        if target not in joint_names:
            raise ModelError(f"expected the name of a joint, got {target!r}", where=f"{where}.mimic.joint")


def _check_floating(floating: list, edges: list[tuple[str, str]]) -> None:
    """A ``floating`` joint only as the root link's one joint: ``floating`` holds ``(key path, <joint>)`` of each,
    ``edges`` every joint's ``(parent link, child link)``."""
    children = {child for _, child in edges}
    for where, el in floating:
        link = el.find("parent").get("link")
        if link in children or sum(parent == link for parent, _ in edges) > 1:
            raise ModelError("expected one of revolute, continuous, prismatic, fixed, got unsupported type 'floating' "
                             "below the root (a floating joint is read only as the root link's one joint: the "
                             "floating base)", where=f"{where}.type")


def _check_inertial(el, where: str, fixes: dict | None = None, link: str = "") -> None:
    _check_origin(el.find("origin"), f"{where}.origin")
    mass = el.find("mass")
    if mass is None:
        raise ModelError('expected a <mass value="..."/> element', where=f"{where}.mass")
    (m,) = _floats(mass.get("value"), 1, f"{where}.mass")
    check_mass(m, f"{where}.mass")
    inertia = el.find("inertia")
    if inertia is None:
        raise ModelError(
            'expected an <inertia ixx="..." ixy="..." ixz="..." iyy="..." iyz="..." izz="..."/> element',
            where=f"{where}.inertia",
        )
    ixx, ixy, ixz, iyy, iyz, izz = (_floats(inertia.get(k), 1, f"{where}.inertia.{k}")[0] for k in _INERTIA_KEYS)
    ic = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    fixed = None if fixes is None else balanced(ic)
    if fixed is not None:
        fixes[link] = fixed
        return
    check_positive_semidefinite(ic, max(1.0, float(np.abs(ic).max())), f"{where}.inertia",
                                "positive semi-definite inertia about the centre of mass",
                                "; load(..., balance_inertia=True) makes such an inertia isotropic with its trace")


def _check_origin(el, where: str) -> None:
    if el is None:
        return
    for attr in ("xyz", "rpy"):
        if el.get(attr) is not None:
            _floats(el.get(attr), 3, f"{where}.{attr}")


def _floats(text: str | None, n: int, where: str, infinite: bool = False) -> list[float]:
    what = "a number" if n == 1 else f"{n} numbers"
    if text is None:
        raise ModelError(f"expected {what}, got nothing", where=where)
    stripped = text.strip(_XML_SPACE)
    parts = re.split(f"[{_XML_SPACE}]+", stripped) if stripped else []
    values = [float(p) for p in parts] if all(_NUMBER.fullmatch(p) for p in parts) else None
    if values is None or len(values) != n:
        raise ModelError(f"expected {what}, got {text!r}", where=where)
    if not all(math.isfinite(v) or (infinite and math.isinf(v)) for v in values):
        wanted = ("a number, not nan" if infinite else "a finite number") if n == 1 else "finite numbers"
        raise ModelError(f"expected {wanted}, got {text!r}", where=where)
    if any(LARGEST < abs(v) < math.inf for v in values):  # products of such numbers overflow later
        raise ModelError(f"expected magnitudes of at most {LARGEST:g} (check the units), got {text!r}", where=where)
    return values


# ---------------------------------------------------------------------------------------------- numbers


def _pose(pose) -> sp.ImmutableMatrix:
    r, p = rotation_translation(pose)
    return lie.pose(sp.Matrix(3, 3, [exact(x) for x in r.flat]), [exact(x) for x in p])


def _screw(kind: str, axis) -> tuple:
    if kind == "fixed":
        return (0,) * 6
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)  # the file's axis need not be unit, as in urdfdom and Pinocchio
    return lie.screw(kind, [exact(x) for x in a])


