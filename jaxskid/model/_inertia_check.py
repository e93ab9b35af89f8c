"""Whether a robot's default inertias make a usable model: checked when a description is loaded.

Three checks, at the default parameter values (a robot with parameters that have no default, or with bodies
whose mass-inertia is unknown, :attr:`~jaxskid.Robot.without_inertia`, is not checked):

* **A joint that moves nothing.** The mass matrix is positive definite only if every moving joint carries
  inertia along its own axis: for joint ``i`` with unit screw ``X_i`` and the composite inertia ``I^c_i``
  of the subtree it moves (Featherstone 2008, sec. 6.2), ``M_ii = X_i^T I^c_i X_i > 0``. A subtree with
  zero mass and zero inertia (a massless leaf link on a moving joint, a point mass on the joint's axis)
  makes ``M`` singular in every configuration, and forward dynamics and rollouts NaN. It is an error
  (:class:`~jaxskid.ModelError`) when ``M_ii`` vanishes at the reference configuration and at random ones.
  With a floating base, the whole robot's composite inertia must be positive definite.
* **Joints that move together without moving mass.** Each joint may carry inertia along its axis while a
  combination of joints moves none: two coaxial joints with a massless link between them, a massless floating
  base turned against its first joint. The mass matrix (composite-rigid-body algorithm) scaled to a unit
  diagonal then has an eigenvalue of zero; below ``1e-10`` at the reference configuration and at every random
  one is an error naming the joints of its eigenvector. A singularity of some configurations only (two axes
  that align at zero, as iCub's neck) is none.
* **A body that no rigid body can be** (Wensing, Kim & Slotine, RA-L 2017): zero mass with a nonzero
  rotational inertia, or principal moments about the centre of mass that break the triangle inequality
  ``I_1 + I_2 >= I_3`` (a planar model that gives the moment about its axis only is let be). Published URDFs carry such bodies (placeholders, rounding), and every algorithm
  still runs on them, so each is a :class:`~jaxskid.PhysicalConsistencyWarning` naming the file and the
  body, not an error; turn it into one with ``warnings.simplefilter("error", jaxskid.PhysicalConsistencyWarning)``.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
import scipy.linalg
import sympy as sp

from .._errors import ModelError, PhysicalConsistencyWarning
from ._validate import symbol

_RANDOM_CONFIGURATIONS = 3
_TOLERANCE = 1e-12  # relative to the robot's largest inertia entry
_SINGULAR = 1e-10  # smallest eigenvalue of the mass matrix scaled to a unit diagonal


def _numeric(matrix, values: dict) -> np.ndarray | None:
    try:
        return np.array(sp.Matrix(matrix).xreplace(values), dtype=float)
    except (TypeError, ValueError):  # a parameter without a default
        return None


def _adjoint(pose: np.ndarray) -> np.ndarray:
    """``Ad_T`` acting on twists ``(omega, v)``: ``[[R, 0], [p~ R, R]]``."""
    r, p = pose[:3, :3], pose[:3, 3]
    px = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = r
    out[3:, :3] = px @ r
    return out


def _screw_pose(screw: np.ndarray, q: float) -> np.ndarray:
    w, v = screw[:3], screw[3:]
    twist = np.zeros((4, 4))
    twist[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    twist[:3, 3] = v
    return scipy.linalg.expm(twist * q)


def check_inertias(robot, source: str | None = None, where: Callable[[int], str] | None = None) -> None:
    """Raise :class:`ModelError` for a moving joint that carries no inertia along its axis, and warn about
    bodies that are not physically consistent (module docstring). ``where(i)``: the key of body ``i`` in
    the description (default ``"body '<link>'"``); ``source``: the file, for the messages."""
    defaults = robot.default_params()
    if robot.without_inertia or any(k not in defaults for k in robot.parameters):
        return  # kinematics only (Robot.without_inertia), or parameters without a number
    values = {symbol(k): sp.Float(v) for k, v in defaults.items()}
    joints = robot.joints
    origins = [_numeric(j.origin, values) for j in joints]
    screws = [_numeric(sp.Matrix(list(j.screw)), values) for j in joints]
    inertias = [_numeric(j.inertia, values) for j in joints]
    if any(x is None for x in (*origins, *screws, *inertias)):
        return
    screws = [s.reshape(6) for s in screws]
    where = where or (lambda i: f"body {joints[i].link!r}")
    for i, m6 in enumerate(inertias):
        _warn_inconsistent(m6, source, where(i))
    base = _numeric(robot.base_inertia, values) if robot.floating_base and robot.base_inertia is not None else None
    scale = max([float(np.abs(m).max()) for m in inertias] + [0.0 if base is None else float(np.abs(base).max())])
    moving = [i for i, j in enumerate(joints) if j.type != "fixed" and j.mimic is None]
    if not moving and not robot.floating_base:
        return
    if scale == 0.0:
        links = ", ".join(repr(j.link) for j in joints)
        raise ModelError(f"every body ({links}) has zero mass and zero inertia; the equations of motion are empty",
                         source=source)
    rng = np.random.default_rng(0)
    configurations = [np.zeros(len(joints))] + [rng.uniform(-np.pi, np.pi, len(joints))
                                                for _ in range(_RANDOM_CONFIGURATIONS)]
    singular = None
    for q in configurations:
        composite = _composite(robot, origins, screws, inertias, q)
        bad = [i for i, j in enumerate(joints)
               if j.type != "fixed" and j.mimic is None
               and screws[i] @ composite[i] @ screws[i] <= _TOLERANCE * scale]
        singular = bad if singular is None else [i for i in singular if i in bad]
        if not singular:
            break
    if singular:
        i = singular[0]
        moved = [joints[k].link for k in _subtree(robot, i)]
        raise ModelError(
            f"joint {joints[i].name!r} moves bodies with no inertia along its axis ({', '.join(map(repr, moved))}: "
            f"no mass off the axis and no moment of inertia about it), so the mass matrix is singular and forward "
            f"dynamics undefined; give them mass and inertia, or fix the joint "
            f"(load(..., lock={{{joints[i].name!r}: 0.0}}))",
            where=where(i), source=source)
    if base is not None:
        total = base + sum((_adjoint(_inverse(origins[i])).T @ composite[i] @ _adjoint(_inverse(origins[i]))
                            for i, j in enumerate(joints) if j.parent < 0), np.zeros((6, 6)))
        if np.linalg.eigvalsh(total)[0] <= _TOLERANCE * scale:
            raise ModelError("the floating base and the bodies it carries have no mass or inertia in some "
                             "direction; the mass matrix is singular", where="base_inertia", source=source)
    _check_mass_matrix(robot, (origins, screws, inertias, base), configurations, source)


def _check_mass_matrix(robot, numbers, configurations, source) -> None:
    """Raise :class:`ModelError` where the mass matrix is singular at every configuration tried although each
    joint carries inertia along its own axis: joints that move together without moving any mass (two coaxial
    joints with a massless link between them; a massless floating base turned against its first joint).
    ``numbers``: the bodies' ``(origins, screws, inertias, base inertia or None)``."""
    rows = robot.coupling()
    if not all(sp.sympify(a).is_number for _, a, _ in rows) or not rows and numbers[3] is None:
        return  # a mimic multiplier without a number, or nothing moves
    coupling = [(k, float(a)) for k, a, _ in rows]
    null = None
    for q in configurations:
        m = _mass_matrix(robot, *numbers, coupling, q)
        d = np.sqrt(np.diag(m))
        if not (d > 0).all() or not np.isfinite(m).all():  # below the per-joint check's tolerance: underflow
            null = (~(d > 0)).astype(float)
            continue
        values, vectors = np.linalg.eigh(m / np.outer(d, d))  # scaled to a unit diagonal: no units left
        if values[0] > _SINGULAR:
            return
        null = vectors[:, 0] / d
    names = (["the floating base"] * 6 if numbers[3] is not None else []) + list(robot.joint_names)
    null = np.abs(null) / np.abs(null).max() if np.abs(null).max() > 0 else np.ones(len(names))
    moved = list(dict.fromkeys(n if n.startswith("the ") else repr(n) for n, x in zip(names, null) if x > 0.01))
    raise ModelError(
        f"the mass matrix is singular in every configuration tried: {' and '.join(moved)} can move together "
        "without moving any mass or inertia (joints on one axis with massless links between them, or a base "
        "without inertia turned against its first joints); give the links between them mass and inertia, or "
        "fix one of the joints (load(..., lock={name: 0.0}))", source=source)


def _mass_matrix(robot, origins, screws, inertias, base, coupling, q) -> np.ndarray:
    """The joint-space mass matrix at body positions ``q`` (composite-rigid-body algorithm, Featherstone 2008,
    sec. 6.2), the floating base's six coordinates first (in its body frame), mimic joints folded into the
    joints they follow by ``coupling`` (per body: coordinate, multiplier)."""
    joints, base6 = robot.joints, 6 if base is not None else 0
    composite = _composite(robot, origins, screws, inertias, q)
    up = [_adjoint(_inverse(origins[c] @ _screw_pose(screws[c], q[c]))).T for c in range(len(joints))]
    g = np.zeros((base6 + len(joints), base6 + robot.n_dof))  # body (and base) velocities from coordinates
    g[:base6, :base6] = np.eye(base6)
    for i, (k, a) in enumerate(coupling):
        g[base6 + i, base6 + k] = a
    full = np.zeros((base6 + len(joints),) * 2)
    if base6:
        full[:6, :6] = base + sum((up[c] @ composite[c] @ up[c].T for c, j in enumerate(joints) if j.parent < 0),
                                  np.zeros((6, 6)))
    for j in range(len(joints)):
        f, k = composite[j] @ screws[j], j
        full[base6 + j, base6 + j] = screws[j] @ f
        while joints[k].parent >= 0:
            f, k = up[k] @ f, joints[k].parent
            full[base6 + k, base6 + j] = full[base6 + j, base6 + k] = screws[k] @ f
        if base6:
            full[:6, base6 + j] = full[base6 + j, :6] = up[k] @ f
    return g.T @ full @ g


def _inverse(pose: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = pose[:3, :3].T
    out[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return out


def _subtree(robot, i: int) -> list[int]:
    inside = {i}
    for k, j in enumerate(robot.joints):
        if j.parent in inside:
            inside.add(k)
    return sorted(inside)


def _composite(robot, origins, screws, inertias, q) -> list[np.ndarray]:
    """The composite inertia of each body's subtree in its own frame, at configuration ``q``."""
    composite = [m.copy() for m in inertias]
    for c in range(len(robot.joints) - 1, -1, -1):  # children come after their parents
        parent = robot.joints[c].parent
        if parent < 0:
            continue
        pose = origins[c] @ _screw_pose(screws[c], q[c])  # body c in its parent's frame
        ad = _adjoint(_inverse(pose))  # parent-frame twists to body c's frame
        composite[parent] = composite[parent] + ad.T @ composite[c] @ ad
    return composite


def breaks_triangle(moments: np.ndarray) -> bool:
    """Whether sorted principal moments about the centre of mass break ``I1 + I2 >= I3`` beyond round-off (relative
    1e-6); the moment about one axis only, a planar model's shortcut, does not count."""
    planar = moments[1] <= 1e-12 * moments[2]
    return not planar and moments[0] + moments[1] - moments[2] < -1e-6 * max(moments[2], 1e-300)


def _warn_inconsistent(m6: np.ndarray, source: str | None, key: str) -> None:
    mass = m6[3, 3]
    rotational = m6[:3, :3]
    place = ": ".join(p for p in (source, key) if p)
    if mass <= 0:
        if np.abs(rotational).max() > 0:
            warnings.warn(f"{place}: zero mass with a nonzero rotational inertia (max {np.abs(rotational).max():.3g}); "
                          "no rigid body has that", PhysicalConsistencyWarning, stacklevel=4)
        return
    c = np.array([m6[2, 4], m6[0, 5], m6[1, 3]]) / mass  # m c~ in the upper-right block
    cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
    about_com = rotational + mass * cx @ cx  # I_O = I_C - m c~ c~
    moments = np.sort(np.linalg.eigvalsh(0.5 * (about_com + about_com.T)))
    if breaks_triangle(moments):
        warnings.warn(f"{place}: principal moments of inertia {np.round(moments, 9).tolist()} about the centre of "
                      f"mass break the triangle inequality I1 + I2 >= I3; no rigid body has them",
                      PhysicalConsistencyWarning, stacklevel=4)
