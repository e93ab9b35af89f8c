"""``jaxskid convert`` then ``jaxskid.load``: a URDF written as YAML (numeric, rounded, and with symbolic
inertial parameters) is the same robot.

Reference: Pinocchio's own model of each URDF (its parser), against Pinocchio's model of the converted
description (``pinref.to_pinocchio``); M (crba), Q_grav (computeGeneralizedGravity) and tau (rnea) at
random states agree to 1e-12 relative to their size (1e-9 for ``--round 1e-10``). Joints are matched by name.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

import jaxskid
from helpers import PANDA, URDFS, pinocchio_urdf_model
from jaxskid._cli import main
from pinref import to_pinocchio

HOPPING_LEG = Path(__file__).parent / "data" / "urdf" / "hopping_leg.urdf"
ROBOTS = {"panda": PANDA, "ur5": URDFS["ur5"], "solo12": URDFS["solo12"], "hopping_leg": HOPPING_LEG}
FORMS = {"numeric": [], "rounded": ["--round", "1e-10"], "symbolic": ["--symbolic-inertia"]}
TOLERANCE = {"numeric": 1e-12, "symbolic": 1e-12, "rounded": 1e-9}
"""Exact forms to round-off; ``--round 1e-10`` moves entries by up to 1e-10, which M feels as 1e-11."""


def _dynamics(model, order, states):
    """M, Q_grav and tau of a Pinocchio model at states given in ``order`` (joint names)."""
    data = model.createData()
    index = [model.joints[model.getJointId(name)].idx_v for name in order]
    out = []
    for q, qd, qdd in states:
        qq, vv, aa = (np.zeros(model.nv) for _ in range(3))
        qq[index], vv[index], aa[index] = q, qd, qdd
        m = pin.crba(model, data, qq)
        m = np.triu(m) + np.triu(m, 1).T
        g = pin.computeGeneralizedGravity(model, data, qq)
        tau = pin.rnea(model, data, qq, vv, aa)
        out.append((m[np.ix_(index, index)], g[index], tau[index]))
    return out


@pytest.mark.parametrize("form", sorted(FORMS))
@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_convert_then_load_is_the_same_robot(tmp_path, capsys, name, form):
    urdf = ROBOTS[name]
    out = tmp_path / f"{name}.yaml"
    with pytest.raises(SystemExit) as done:
        main(["convert", str(urdf), str(out), *FORMS[form]])
    assert done.value.code == 0
    assert f"wrote {out}" in capsys.readouterr().out
    robot = jaxskid.load(out)
    if form == "symbolic":
        assert len(robot.parameters) == 10 * sum(1 for j in robot.joints if j.type != "fixed")
        assert set(yaml.safe_load(out.read_text())["assignments"]) >= set(robot.parameters)
    model, _ = to_pinocchio(robot, robot.default_params())
    reference = pinocchio_urdf_model(urdf)
    names = list(robot.joint_names)
    assert sorted(names) == sorted(n for n in reference.names[1:])
    rng = np.random.default_rng(3)
    states = [rng.uniform(-1.2, 1.2, (3, len(names))) for _ in range(3)]
    for got, ref in zip(_dynamics(model, names, states), _dynamics(reference, names, states)):
        for a, b, what in zip(got, ref, ("M", "Q_grav", "tau")):
            scale = max(1.0, float(np.abs(b).max()))
            assert np.abs(a - b).max() <= TOLERANCE[form] * scale, (name, form, what, np.abs(a - b).max())
