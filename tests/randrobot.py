"""Random physically consistent robots (trees of revolute and prismatic joints) for property tests."""

from __future__ import annotations

import numpy as np
import sympy as sp

import jaxskid
from jaxskid import Frame, Joint, Robot


def _rotation(rng):
    a = rng.normal(size=3)
    a /= np.linalg.norm(a)
    return np.array(jaxskid.rot_axis_angle(a.tolist(), float(rng.uniform(-np.pi, np.pi))).evalf(), dtype=float)


def random_inertia(rng, mass_scale=1.0):
    """(mass, com, 3x3 inertia about the com) of a random solid box: physically consistent."""
    m = float(rng.uniform(0.2, 3.0)) * mass_scale
    dims = rng.uniform(0.05, 0.5, size=3)
    i_box = m / 12 * np.diag([dims[1] ** 2 + dims[2] ** 2, dims[0] ** 2 + dims[2] ** 2, dims[0] ** 2 + dims[1] ** 2])
    r = _rotation(rng)
    return m, rng.uniform(-0.2, 0.2, size=3), r @ i_box @ r.T


def random_robot(rng, n: int, *, tree: bool = True, symbolic: bool = True, prismatic: float = 0.3) -> Robot:
    """A random tree with n joints in depth-first order (as Pinocchio requires); with ``symbolic`` every
    body's 10 inertial parameters are symbols with the drawn values as defaults."""
    joints = []
    defaults = {}
    path: list[int] = []  # bodies from the root to the last body: parents drawn from it keep depth-first order
    for i in range(n):
        if tree and i > 0:
            parent = int(rng.choice([-1, *path]))
        else:
            parent = i - 1
        path = [*path[: path.index(parent) + 1], i] if parent >= 0 else [i]
        kind = "prismatic" if rng.uniform() < prismatic else "revolute"
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        point = rng.uniform(-0.3, 0.3, size=3) if kind == "revolute" else None
        screw = jaxskid.screw(kind, axis.tolist(), None if point is None else point.tolist())
        origin = jaxskid.pose(_rotation(rng).tolist(), rng.uniform(-0.5, 0.5, size=3).tolist())
        m, c, ic = random_inertia(rng)
        m6 = np.array(jaxskid.spatial_inertia(m, c.tolist(), ic.tolist(), about="com").evalf(), dtype=float)
        if symbolic:
            names = [f"b{i}_{k}" for k in ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")]
            s = [jaxskid.symbol(x) for x in names]
            mm, mcx, mcy, mcz, ixx, ixy, iyy, ixz, iyz, izz = s
            inertia = sp.Matrix([
                [ixx, ixy, ixz, 0, -mcz, mcy],
                [ixy, iyy, iyz, mcz, 0, -mcx],
                [ixz, iyz, izz, -mcy, mcx, 0],
                [0, mcz, -mcy, mm, 0, 0],
                [-mcz, 0, mcx, 0, mm, 0],
                [mcy, -mcx, 0, 0, 0, mm],
            ])
            vals = [m6[5, 5], m6[2, 4], m6[0, 5], m6[1, 3], m6[0, 0], m6[0, 1], m6[1, 1], m6[0, 2], m6[1, 2], m6[2, 2]]
            defaults.update(dict(zip(names, map(float, vals))))
        else:
            inertia = sp.Matrix(m6)
        joints.append(Joint(f"j{i}", kind, parent, origin, screw, inertia, f"body{i}"))
    frames = [Frame(f"ee{i}", i, jaxskid.pose(_rotation(rng).tolist(), rng.uniform(-0.3, 0.3, size=3).tolist()))
              for i in range(n) if not any(j.parent == i for j in joints)]
    g = jaxskid.symbol("g")
    defaults["g"] = 9.81
    return Robot.create(f"random{n}", joints, (0, 0, -g), frames, [f.name for f in frames], defaults)
