"""Options (CSE strategy, simplification, trig handling): every value gives Pinocchio's M, tau and Q_grav on
the 3-DOF hopping leg, a bad value is rejected naming the field, and different options are cached apart."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from jaxskid._api import module_key as request_key
from jaxskid.testing import _reference as ref_
from pinref import to_pinocchio

ROBOT = Path(__file__).parents[1] / "robots" / "hopping_leg.yaml"
QUANTITIES = ["mass_matrix", "gravity_torques", "inverse_dynamics"]
VALUES = {"cse": ("tape", "sympy", "none"), "simplify": ("none", "expand", "trigsimp"), "trig": ("symbols", "inline")}
CASES = [{field: value} for field, values in VALUES.items() for value in values]
CASES.append({"cse": "sympy", "simplify": "trigsimp", "trig": "inline"})  # every choice away from the default


@pytest.fixture(scope="module")
def leg():
    robot = jaxskid.load(ROBOT)
    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.uniform(-2, 2, size=(3, 16, robot.n_dof))
    expected = {"mass_matrix": [], "gravity_torques": [], "inverse_dynamics": []}
    for k in range(len(q)):
        m = pin.crba(model, data, q[k])
        expected["mass_matrix"].append(np.triu(m) + np.triu(m, 1).T)
        expected["gravity_torques"].append(pin.computeGeneralizedGravity(model, data, q[k]).copy())
        expected["inverse_dynamics"].append(pin.rnea(model, data, q[k], qd[k], qdd[k]).copy())
    return robot, (q, qd, qdd), {k: np.array(v) for k, v in expected.items()}


def assert_matches(got, expected):
    for name in QUANTITIES:
        for k, ref in enumerate(expected[name]):
            assert np.linalg.norm(np.asarray(got[name][k]) - ref) <= 1e-9 * np.linalg.norm(ref), (name, k)


@pytest.mark.parametrize("options", CASES, ids=lambda o: "-".join(f"{k}={v}" for k, v in o.items()))
def test_every_option_matches_pinocchio(leg, options):
    """The derived program of each option, evaluated in NumPy (nothing compiled: cse="none" trees take XLA
    tens of seconds)."""
    robot, (q, qd, qdd), expected = leg
    eqs = jaxskid.derive(robot, QUANTITIES, options=jaxskid.Options(**options))
    params = [robot.default_params()[k] for k in eqs.parameters]
    assert_matches(ref_.evaluate(eqs, QUANTITIES, {"q": q, "qd": qd, "qdd": qdd}, params), expected)


def test_lowered_options_match_pinocchio(leg, tmp_path):
    """The JAX lowering of the program with every choice away from the default."""
    robot, (q, qd, qdd), expected = leg
    dyn = jaxskid.lower(robot, QUANTITIES, options=jaxskid.Options(**CASES[-1]), cache_dir=tmp_path)
    assert "_c0 = " in dyn.source and "_sin(_q" in dyn.source  # sympy.cse's names; sin(q) left inline
    assert_matches({"mass_matrix": dyn.mass_matrix(q), "gravity_torques": dyn.gravity_torques(q),
                    "inverse_dynamics": dyn.inverse_dynamics(q, qd, qdd)}, expected)


@pytest.mark.parametrize("field", list(VALUES))
def test_a_bad_value_names_the_field(field):
    with pytest.raises(jaxskid.RequestError, match=rf"Options\.{field}: expected one of .*got 'fast'"):
        jaxskid.Options(**{field: "fast"})


def test_different_options_give_different_cache_keys():
    robot = jaxskid.load(ROBOT)
    every = [jaxskid.Options(*values) for values in itertools.product(*VALUES.values())]
    keys = {request_key(robot, QUANTITIES, o) for o in every}
    assert len(keys) == len(every) == 18
    assert request_key(robot, QUANTITIES, jaxskid.Options()) == request_key(robot, QUANTITIES, None)
