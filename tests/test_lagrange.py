"""The Euler-Lagrange route (``Options(route="lagrange")``) against the screw route and Pinocchio, and the
energies against Pinocchio's."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from helpers import FINGERS, PANDA, URDFS, load, pinocchio_urdf_model, rel_err
from jaxskid.testing import closed_form, vanishes
from jaxskid.testing._reference import evaluate
from pinref import to_pinocchio
from test_robots import ROBOTS

LAGRANGE = jaxskid.Options(route="lagrange")
ROUTED = ["mass_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics", "kinetic_energy"]
ALL = [*ROUTED, "potential_energy", "momentum"]


def _pinocchio(name: str, robot: jaxskid.Robot):
    """Pinocchio's model of a robot of ``helpers.load(name)``: its own URDF parser for a URDF."""
    if name == "panda7":
        return pinocchio_urdf_model(PANDA, FINGERS)
    if name in URDFS:
        return pinocchio_urdf_model(URDFS[name])
    return to_pinocchio(robot, robot.default_params())[0]


def _values(robot, args, lowered: bool) -> dict:
    """Both routes' quantities at the states ``args``: lowered to JAX, or the derived programs evaluated with
    NumPy (``jaxskid.testing``'s interpreter: what is derived, without compiling a large program)."""
    out = {}
    for route in ("lagrange", "screw"):
        options = jaxskid.Options(route=route)
        if lowered:
            dyn = jaxskid.lower(robot, ALL, options=options)
            out[route] = {k: np.asarray(getattr(dyn, k)(*a)) for k, a in args.items()}
        else:
            eqs = jaxskid.derive(robot, ALL, options=options)
            p = [robot.default_params()[k] for k in robot.parameters]
            state = dict(zip(("q", "qd", "qdd"), args["inverse_dynamics"]))
            out[route] = evaluate(eqs, ALL, state, p)
    return out


def _check_route(name: str, robot: jaxskid.Robot, model, lowered: bool, states: int = 20):
    """Both routes against each other and against ``model`` (Pinocchio's) at random states."""
    data = model.createData()
    rng = np.random.default_rng(3)
    q, qd, qdd = rng.uniform(-2, 2, size=(3, states, robot.n_dof))
    args = {"mass_matrix": (q,), "coriolis_torques": (q, qd), "gravity_torques": (q,),
            "inverse_dynamics": (q, qd, qdd), "kinetic_energy": (q, qd), "potential_energy": (q,), "momentum": (q, qd)}
    values = _values(robot, args, lowered)
    ours, theirs = values["lagrange"], values["screw"]
    for k in range(states):
        g = pin.computeGeneralizedGravity(model, data, q[k]).copy()
        ref = {
            "mass_matrix": pin.crba(model, data, q[k]),
            "gravity_torques": g,
            "coriolis_torques": pin.nonLinearEffects(model, data, q[k], qd[k]) - g,
            "inverse_dynamics": pin.rnea(model, data, q[k], qd[k], qdd[k]),
            "kinetic_energy": pin.computeKineticEnergy(model, data, q[k], qd[k]),
            "potential_energy": pin.computePotentialEnergy(model, data, q[k]),
        }
        ref["mass_matrix"] = np.triu(ref["mass_matrix"]) + np.triu(ref["mass_matrix"], 1).T
        ref["momentum"] = ref["mass_matrix"] @ qd[k]
        for quantity, value in ref.items():
            assert rel_err(ours[quantity][k], value, floor=1e-3) <= 1e-9, (name, quantity, k)
            assert rel_err(ours[quantity][k], theirs[quantity][k], floor=1e-3) <= 1e-9, (name, quantity, k)


# The seed robots the route refuses, and the words of its RequestError: its energies are written for a fixed base.
REFUSED = {"quadruped_contact": "floating base"}


def _seed(path):
    """A file of robots/ as a test parameter; the 12-DOF quadruped is slow (its derived programs are evaluated
    with NumPy, not compiled, as for the larger robots below)."""
    slow = [pytest.mark.slow] if path.stem == "quadruped_12dof" else []
    return pytest.param(path, id=path.stem, marks=slow)


@pytest.mark.parametrize("path", [_seed(p) for p in ROBOTS])
def test_every_seed_robot(path):
    """Every file in robots/, loaded by its path (``robots/double_pendulum.yaml``, not the URDF of that name):
    where the route supports the robot, both routes against each other and against Pinocchio (lowered to JAX
    up to 3 DOF, the derived programs evaluated with NumPy above); where it refuses one (a floating base or
    mimic joints), the refusal and its reason."""
    robot = jaxskid.load(path)
    assert (path.stem in REFUSED) == bool(robot.floating_base or robot.mimic_joints), path.stem
    if path.stem in REFUSED:
        with pytest.raises(jaxskid.RequestError, match=REFUSED[path.stem]):
            jaxskid.derive(robot, ROUTED, options=LAGRANGE)
        return
    model = to_pinocchio(robot, robot.default_params())[0]  # built from this file, whatever its name
    _check_route(path.stem, robot, model, lowered=robot.n_dof <= 3)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["panda7", "ur5", "solo12"])
def test_larger_robots(name):
    """The derived programs of both routes, evaluated without compiling, at 6-12 DOF."""
    robot = load(name)
    _check_route(name, robot, _pinocchio(name, robot), lowered=False)


@pytest.mark.parametrize("name", ["arm_2r", "arm_3dof"])
def test_symbolic_difference_is_zero(name):
    """The two routes' closed forms agree identically, with every parameter symbolic."""
    robot = load(name)
    names = ["mass_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics", "kinetic_energy"]
    lagrange = jaxskid.derive(robot, names, options=LAGRANGE)
    screw = jaxskid.derive(robot, names)
    q = screw.arguments["q"].symbols
    assert robot.parameters, "the comparison is meant with symbolic parameters"
    for quantity in names:
        a, b = closed_form(lagrange, quantity), closed_form(screw, quantity)
        assert all(vanishes(x - y, q) for x, y in zip(a, b, strict=True)), quantity
        # the check has teeth: a perturbed entry does not vanish
        assert not vanishes(a[-1] * (1 + jaxskid.symbol(robot.parameters[0])) - b[-1], q)


def test_lagrange_route_differentiates_in_parameters():
    """jax.grad of a loss in the parameters is the same on both routes."""
    robot = load("arm_3dof")
    lagrange = jaxskid.lower(robot, ["inverse_dynamics"], options=LAGRANGE)
    screw = jaxskid.lower(robot, ["inverse_dynamics"])
    q, qd, qdd = np.random.default_rng(5).uniform(-1, 1, size=(3, 3))

    def loss(dyn):
        return lambda params: jnp.sum(dyn.inverse_dynamics(q, qd, qdd, params) ** 2)

    params = lagrange.param_vector()
    ga, gb = jax.grad(loss(lagrange))(params), jax.grad(loss(screw))(params)
    assert rel_err(np.asarray(ga), np.asarray(gb)) <= 1e-10


def test_unknown_route_is_a_clear_error():
    with pytest.raises(jaxskid.RequestError, match="route.*screw, lagrange"):
        jaxskid.Options(route="newton")
