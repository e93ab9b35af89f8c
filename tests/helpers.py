"""Robots, paths and error measures shared by the tests.

Robots come from two places: this repository's ``robots/*.yaml`` and the URDFs of the ``example-robot-data``
package (installed by the test extra; its files sit under the ``cmeel.prefix`` of its distribution).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import sys
from pathlib import Path

import jax
import numpy as np
import pinocchio as pin

import jaxskid
from pinref import to_pinocchio
from randrobot import random_robot

REPO = Path(__file__).resolve().parents[1]
ROBOTS_DIR = REPO / "robots"
ERD = Path(
    importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots")
)
PANDA = ERD / "panda_description/urdf/panda.urdf"
URDFS = {
    "panda": PANDA,
    "ur5": ERD / "ur_description/urdf/ur5_robot.urdf",
    "solo12": ERD / "solo_description/robots/solo12.urdf",
    "double_pendulum": ERD / "double_pendulum_description/urdf/double_pendulum.urdf",
    "double_pendulum_continuous": ERD / "double_pendulum_description/urdf/double_pendulum_continuous.urdf",
}
FINGERS = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}  # locked closed: the Panda as a 7-DOF arm

# Forward dynamics from M(q) and tau(q, qd, qdd) (the numeric L D L^T solve); see ``lowered``.
FD = ["mass_matrix", "inverse_dynamics"]


def load(name: str) -> jaxskid.Robot:
    """A test robot by name.

    ``"panda7"``: the Panda with its fingers locked (``FINGERS``, 7 DOF); a key of ``URDFS``: that URDF from
    example-robot-data (``"double_pendulum"`` is the URDF one); any other name: ``robots/{name}.yaml``.
    """
    if name == "panda7":
        return jaxskid.load(PANDA, lock=FINGERS)
    if name in URDFS:
        return jaxskid.load(URDFS[name])
    return jaxskid.load(ROBOTS_DIR / f"{name}.yaml")


def pinocchio_urdf_model(path: Path, lock: dict[str, float] | None = None):
    """Pinocchio's own model of a URDF (its parser), the joints in ``lock`` removed at the given positions
    (a continuous joint's angle is Pinocchio's (cos, sin) pair)."""
    model = pin.buildModelFromUrdf(str(path))
    if lock:
        q = pin.neutral(model)
        for name, value in lock.items():
            j = model.joints[model.getJointId(name)]
            q[j.idx_q : j.idx_q + j.nq] = [value] if j.nq == 1 else [np.cos(value), np.sin(value)]
        model = pin.buildReducedModel(model, [model.getJointId(name) for name in lock], q)
    return model


def random_tree_regressor(rng, n_dof: int, prismatic: float):
    """A random tree (``randrobot.random_robot``: revolute axes off the body origins, a share ``prismatic`` of
    prismatic joints) lowered with its regressor, beside Pinocchio's model of it: ``(robot, dyn, params, pi,
    model, data)`` with the default parameters ``params``, their standard vector ``pi`` and the model's data."""
    robot = random_robot(rng, n_dof, tree=True, prismatic=prismatic)
    dyn = jaxskid.lower(robot, ["regressor"])
    params = robot.default_params()
    model, _ = to_pinocchio(robot, params)
    return robot, dyn, params, jaxskid.standard_params(robot, params), model, model.createData()


def lowered(robot: jaxskid.Robot, closed: bool, extra=()):
    """Forward dynamics from M and tau (numeric L D L^T) or from the closed-form quantity."""
    return jaxskid.lower(robot, [*FD, *extra, *(["forward_dynamics"] if closed else [])])


def users_rk4(accel, dt: float):
    """A hand-written RK4 rollout, as a user writes one around ``dyn.raw`` (docs/quantities.md): ``accel(q, qd,
    tau, p)`` maps a batch of states, each (batch, n); ``rollout(q, qd, u, p)``, torques ``u`` of shape (steps,
    batch, n) held over each step of ``dt``, returns ``[q, qd]`` after each step, each (steps, batch, n)."""

    def rollout(q, qd, u, p):
        def deriv(x, tau):
            return x[1], accel(x[0], x[1], tau, p)

        def step(x, tau):
            k1 = deriv(x, tau)
            k2 = deriv([a + dt / 2 * k for a, k in zip(x, k1)], tau)
            k3 = deriv([a + dt / 2 * k for a, k in zip(x, k2)], tau)
            k4 = deriv([a + dt * k for a, k in zip(x, k3)], tau)
            x = [a + dt / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]
            return x, x

        return jax.lax.scan(step, [q, qd], u)[1]

    return rollout


class Integral(jaxskid.Controller):
    """PI control to q = 0 with the integral of q as the controller state: a rollout saves ``z`` too."""

    def init(self, x0):
        return 0.0 * x0[: x0.shape[0] // 2]

    def __call__(self, t, x, z):
        n = x.shape[0] // 2
        return -4.0 * x[:n] - 1.0 * x[n:] - 2.0 * z, x[:n]


def rel_err(ours, ref, floor: float = 1e-12) -> float:
    """Normwise relative error ``||ours - ref|| / max(||ref||, floor)``, 2-norm over all entries.

    ``floor`` is the size below which ``ref`` counts as zero; the error is then absolute, scaled by 1 / floor.
    """
    ours, ref = np.asarray(ours), np.asarray(ref)
    den = max(float(np.linalg.norm(ref.ravel())), floor, np.finfo(float).tiny)
    return float(np.linalg.norm((ours - ref).ravel()) / den)


def max_rel_err(ours, ref, floor: float = 1e-12) -> float:
    """The largest ``rel_err`` over the leading (state) axis of ``ours`` and ``ref``."""
    return max(rel_err(a, b, floor) for a, b in zip(ours, ref, strict=True))


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load_example(name: str):
    """The example ``examples/{name}.py`` as a module, with ``examples/`` on the import path as when it runs as a
    script (for ``examples/_common.py``)."""
    if str(EXAMPLES) not in sys.path:
        sys.path.insert(0, str(EXAMPLES))
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
