"""Build a robot in Python (the 2R arm of robots/arm_2r.yaml), lower it and evaluate it.

    python examples/python_robot.py
"""

from __future__ import annotations

import numpy as np

import jaxskid
from jaxskid import Frame, Joint, Robot, pose, screw, spatial_inertia, symbol


def arm_2r() -> Robot:
    """Planar 2R arm, point masses at the link tips, gravity along -y (body-fixed representation)."""
    m1, m2, l1, l2, g = (symbol(s) for s in ("m1", "m2", "l1", "l2", "g"))
    joints = [
        Joint("shoulder", "revolute", -1, pose(), screw("revolute", (0, 0, 1)),
              spatial_inertia(m1, (l1, 0, 0)), "link1"),
        Joint("elbow", "revolute", 0, pose(translation=(l1, 0, 0)), screw("revolute", (0, 0, 1)),
              spatial_inertia(m2, (l2, 0, 0)), "link2"),
    ]
    tip = Frame("tip", 1, pose(translation=(l2, 0, 0)))
    defaults = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "g": 9.81}
    return Robot.create("arm_2r", joints, (0, -g, 0), [tip], ["tip"], defaults)


def main():
    robot = arm_2r()
    dyn = jaxskid.lower(robot, ["mass_matrix", "gravity_torques", "inverse_dynamics"])
    q = np.array([0.3, -0.5])
    print("parameters:", dict(robot.default_params()))
    print("M(q) =\n", np.asarray(dyn.mass_matrix(q)))
    print("Q_grav(q) =", np.asarray(dyn.gravity_torques(q)))
    return dyn, q


if __name__ == "__main__":
    main()
