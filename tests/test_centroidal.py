"""Centre of mass, its Jacobian and the centroidal momentum matrix against Pinocchio's ``centerOfMass``,
``jacobianCenterOfMass`` and ``computeCentroidalMap``: the floating-base solo12 (Pinocchio's v = (v, omega, qd_j),
its A_G rows (linear, angular)) and the fixed-base Panda."""

import numpy as np
import pinocchio as pin
import pytest
from helpers import FINGERS, PANDA, URDFS, pinocchio_urdf_model

import jaxskid

NAMES = ["center_of_mass", "center_of_mass_jacobian", "centroidal_momentum_matrix"]


def base_order(a, axis):
    """Swap the first two triples of ``a`` along ``axis``: jaxskid's (omega, v) <-> Pinocchio's (v, omega)."""
    idx = np.r_[3:6, 0:3, 6:a.shape[axis]]
    return np.take(a, idx, axis=axis)


@pytest.fixture(scope="module", params=["solo12", "panda7"])
def case(request):
    if request.param == "solo12":
        robot = jaxskid.load(URDFS["solo12"], floating_base=True)
        model = pin.buildModelFromUrdf(str(URDFS["solo12"]), pin.JointModelFreeFlyer())
    else:
        robot = jaxskid.load(PANDA, lock=FINGERS)
        model = pinocchio_urdf_model(PANDA, FINGERS)
    return robot, jaxskid.lower(robot, NAMES), model


def test_centroidal_quantities_match_pinocchio(case):
    robot, dyn, model = case
    data = model.createData()
    floating = robot.floating_base
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        c = pin.centerOfMass(model, data, q)
        jc = pin.jacobianCenterOfMass(model, data, q)
        ag = pin.computeCentroidalMap(model, data, q)
        ag = np.concatenate([ag[3:], ag[:3]])  # rows (angular, linear), as jaxskid's
        if floating:
            jc, ag = base_order(jc, 1), base_order(ag, 1)
        assert np.abs(np.asarray(dyn.center_of_mass(q)) - c).max() <= 1e-12
        assert np.abs(np.asarray(dyn.center_of_mass_jacobian(q)) - jc).max() <= 1e-12
        assert np.abs(np.asarray(dyn.centroidal_momentum_matrix(q)) - ag).max() <= 1e-11 * np.abs(ag).max()
        # h_G is conserved in free flight without gravity (angular) / changes by m g (linear): check instead the
        # consistency m dc/dt = linear momentum at a random velocity
        v = rng.normal(size=model.nv)
        mass = sum(i.mass for i in model.inertias[1:]) if not floating else sum(i.mass for i in model.inertias)
        h = np.asarray(dyn.centroidal_momentum_matrix(q)) @ v
        assert np.abs(h[3:] - mass * np.asarray(dyn.center_of_mass_jacobian(q)) @ v).max() <= 1e-12 * mass
