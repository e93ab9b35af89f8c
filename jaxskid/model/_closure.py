"""Whether a robot's constraints can be satisfied: a numeric search near the reference configuration.

A loop closure between frames that cannot meet (links too short, an axis that misses the other frame) or a
contact whose frame cannot reach its anchor leaves ``phi(q) = 0`` without a solution, and constrained
dynamics would pull the robot towards it with unbounded forces. :func:`check_satisfiable` looks for a
solution by Levenberg-Marquardt on ``|phi(q)|^2`` (Nocedal & Wright, "Numerical Optimization", 2nd ed.,
sec. 10.3), with the default parameter values, from the reference configuration (or a contact's ``at``), the
floating base free to move if there is one. Each constraint is tried alone first, so that the error names
it, then all of them together. It is a local search: a loop that closes only far from the reference
configuration is reported too, and the message says how close the frames came. Without default values for
every parameter the check is skipped, as the model's other numeric checks are.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .._errors import ModelError
from ._lie import AXES
from ._validate import numeric

TOL = 1e-6
"""The largest residual ``|phi|`` accepted, relative to the robot's size (1 + the sum of its offsets)."""
ITERATIONS = 200


def _exp(xi: np.ndarray) -> np.ndarray:
    """``exp`` of the twist ``xi = (omega, v)`` as a 4x4 pose (Lynch & Park, "Modern Robotics", eq. 3.51, 3.88)."""
    w, v = xi[:3], xi[3:]
    theta = float(np.linalg.norm(w))
    k = _cross_matrix(w)
    if theta < 1e-9:  # second order: exact for a translation
        a, b, c = 1.0, 0.5, 1.0 / 6.0
    else:
        a, b, c = np.sin(theta) / theta, (1 - np.cos(theta)) / theta**2, (theta - np.sin(theta)) / theta**3
    out = np.eye(4)
    out[:3, :3] += a * k + b * k @ k
    out[:3, 3] = (np.eye(3) + b * k + c * k @ k) @ v
    return out


def _array(m, values: Mapping) -> np.ndarray | None:
    entries = [numeric(e, values) for e in m]
    return None if None in entries else np.array(entries, dtype=float)


class _Tree:
    """The robot with numbers: every body's ``B_i`` and ``X_i``, the coupling of its joint to ``q``, its frames."""

    def __init__(self, robot, values: Mapping):
        self.robot = robot
        self.floating = bool(getattr(robot, "floating_base", False))
        self.origins = [_array(j.origin, values) for j in robot.joints]
        self.screws = [_array(j.screw, values) for j in robot.joints]
        self.offsets = {f.name: _array(f.offset, values) for f in robot.frames}
        self.coupling = [(k, numeric(a, values), numeric(b, values)) for k, a, b in robot.coupling()]
        self.complete = not any(x is None for x in (*self.origins, *self.screws, *self.offsets.values()))
        if self.complete:
            self.origins = [m.reshape(4, 4) for m in self.origins]
            self.offsets = {k: m.reshape(4, 4) for k, m in self.offsets.items()}
            self.scale = 1.0 + sum(np.linalg.norm(m[:3, 3]) for m in (*self.origins, *self.offsets.values()))

    @property
    def size(self) -> int:
        """The number of search variables: the base's 6 (floating) and the coordinates."""
        return 6 * self.floating + self.robot.n_dof

    def poses(self, q: np.ndarray, base: np.ndarray) -> list[np.ndarray]:
        """World pose of every body at coordinates ``q`` and base pose ``base``."""
        out = []
        for i, j in enumerate(self.robot.joints):
            k, a, b = self.coupling[i]
            parent = base if j.parent < 0 else out[j.parent]
            out.append(parent @ self.origins[i] @ _exp(self.screws[i] * (a * q[k] + b)))
        return out

    def frame(self, name: str, poses, base) -> tuple[np.ndarray, int]:
        """(world pose, body) of a named frame."""
        f = self.robot.frame(name)
        body = base if f.body < 0 else poses[f.body]
        return body @ self.offsets.get(name, np.eye(4)), f.body

    def jacobian(self, body: int, point: np.ndarray, poses) -> np.ndarray:
        """``(omega, dp/dt)`` of a point of ``body`` per search variable, world axes: 6 x size."""
        out = np.zeros((6, self.size))
        if self.floating:  # the base moves by a world twist: every body with it
            out[:3, :3] = np.eye(3)
            out[3:, :3] = -_cross_matrix(point)
            out[3:, 3:6] = np.eye(3)
        while body >= 0:
            k, a, _ = self.coupling[body]
            r, p = poses[body][:3, :3], poses[body][:3, 3]
            w = r @ self.screws[body][:3]
            v = r @ self.screws[body][3:] + np.cross(p, w)
            out[:3, 6 * self.floating + k] += a * w
            out[3:, 6 * self.floating + k] += a * (v + np.cross(w, point))
            body = self.robot.joints[body].parent
        return out


def _cross_matrix(p: np.ndarray) -> np.ndarray:
    return np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])


def _rows(tree: _Tree, c, anchor, q, base) -> tuple[np.ndarray, np.ndarray]:
    """(phi, d phi) of one constraint (rotation rows: the axis of the skew part of ``R_a R_b^T``)."""
    poses = tree.poses(q, base)
    pa, body_a = tree.frame(c.frames[0], poses, base)
    if c.frames[1] is None:
        pb, jb = anchor, 0.0
    else:
        pb, body_b = tree.frame(c.frames[1], poses, base)
        jb = tree.jacobian(body_b, pb[:3, 3], poses)
    e = pa[:3, :3] @ pb[:3, :3].T
    phi = np.concatenate([0.5 * np.array([e[2, 1] - e[1, 2], e[0, 2] - e[2, 0], e[1, 0] - e[0, 1]]),
                          pa[:3, 3] - pb[:3, 3]])
    jac = tree.jacobian(body_a, pa[:3, 3], poses) - jb
    keep = [AXES.index(a) for a in c.axes]
    return phi[keep], jac[keep]


def _closest(tree: _Tree, constraints, anchors, q) -> float:
    """The smallest ``|phi|`` found by Levenberg-Marquardt from ``q``, the base at the identity."""
    base = np.eye(4)

    def evaluate(q, base):
        parts = [_rows(tree, c, a, q, base) for c, a in zip(constraints, anchors)]
        return np.concatenate([p for p, _ in parts]), np.vstack([j for _, j in parts])

    phi, jac = evaluate(q, base)
    mu = 1e-3
    for _ in range(ITERATIONS):
        if np.linalg.norm(phi) <= 1e-3 * TOL * tree.scale:
            break
        h = jac.T @ jac
        step = -np.linalg.solve(h + mu * (np.diag(np.diag(h)) + 1e-12 * np.eye(tree.size)), jac.T @ phi)
        q1 = q + step[6 * tree.floating:]
        base1 = _exp(step[:6]) @ base if tree.floating else base
        phi1, jac1 = evaluate(q1, base1)
        if phi1 @ phi1 < phi @ phi:
            q, base, phi, jac, mu = q1, base1, phi1, jac1, mu / 3
        else:
            mu *= 4
            if mu > 1e12:
                break
    return float(np.linalg.norm(phi))


def check_satisfiable(robot, constraints: Sequence, starts: Sequence[Mapping], values: Mapping) -> None:
    """:class:`ModelError` at ``constraints[k]`` for a constraint that cannot be satisfied near the reference
    configuration (or its contact's ``at``; ``starts``: joint name -> position), at ``constraints`` when each
    can but not all together."""
    if not constraints:
        return
    tree = _Tree(robot, values)
    anchors = [None if c.anchor is None else _array(c.anchor, values) for c in constraints]
    if not tree.complete or any(a is None for c, a in zip(constraints, anchors) if c.anchor is not None):
        return
    anchors = [None if a is None else a.reshape(4, 4) for a in anchors]
    tol = TOL * tree.scale

    def start(at):
        return np.array([float(numeric(at.get(name, 0), values) or 0.0) for name in robot.joint_names])

    for k, (c, a) in enumerate(zip(constraints, anchors)):
        gap = _closest(tree, [c], [a], start(starts[k]))
        if gap > tol:
            what = (f"frames {c.frames[0]!r} and {c.frames[1]!r} cannot meet" if c.frames[1] is not None
                    else f"frame {c.frames[0]!r} cannot reach its anchor")
            raise ModelError(f"{what} on the axes {', '.join(c.axes)}: near the reference configuration they stay "
                             f"{gap:.3g} apart (|phi|, m and rad, with the default parameter values)",
                             where=f"constraints[{k}]")
    if len(constraints) > 1:
        gap = _closest(tree, constraints, anchors, start(next((s for s in starts if s), {})))
        if gap > tol:
            raise ModelError(f"each constraint can be satisfied, but not all together: near the reference "
                             f"configuration |phi| stays {gap:.3g}", where="constraints")
