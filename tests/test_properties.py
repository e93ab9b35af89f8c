"""Property tests (hypothesis) on random kinematic trees, against Pinocchio and mathematical identities.

Each example draws a tree of 1 to 12 revolute and prismatic joints, with axes along the coordinate axes or in
random directions, joint axes through random points, random reference poses and random physically consistent
inertias (solid boxes: principal moments that satisfy the triangle inequality, a positive mass, any centre of
mass), numeric or as 10 symbolic standard parameters per body. The same robot is built in Pinocchio
(tests/pinref.py) and:

* M, C qd, Q_grav and tau agree with crba, nonLinearEffects - Q_grav, computeGeneralizedGravity and rnea;
* M is symmetric positive definite;
* dM/dt - 2 C is skew-symmetric, with dM/dt by the complex step (exact to rounding, independent of C);
* the YAML round trip (write_description, read_description) gives an equal Robot.

The derived program is evaluated with NumPy by ``jaxskid.testing._reference.evaluate`` (nothing compiled), so that a
few hundred fresh robots take a few minutes; a few examples go through the real JAX lowering, and through the
numeric recursive evaluation of ``jaxskid.testing._recursive``.
"""

from __future__ import annotations

from dataclasses import replace

import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxskid
from jaxskid import Frame, Joint, Robot
from jaxskid.testing import _reference as ref_
from jaxskid.testing._recursive import recursive_dynamics
from pinref import to_pinocchio
from helpers import rel_err

QUANTITIES = ("mass_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics")
STANDARD = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
AXES = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (-1, 0, 0), (0, -1, 0), (0, 0, -1)]
TOL = 1e-9  # normwise relative, as the other Pinocchio comparisons
N_STATES = 4


def deterministic(examples: int):
    """Hypothesis settings for CI: a fixed sequence of examples, no deadline (derivation takes seconds)."""
    return settings(max_examples=examples, deadline=None, derandomize=True, database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _rotation(rng) -> np.ndarray:
    quat = rng.normal(size=4)
    w, x, y, z = quat / np.linalg.norm(quat)
    return np.array(jaxskid.rot_quaternion(w, x, y, z).evalf(), dtype=float)


def _exact_rotation(rng):
    """A right-angle rotation about a coordinate axis, exact in SymPy."""
    k = int(rng.integers(0, 4))
    axis = AXES[int(rng.integers(0, 3))]
    return jaxskid.rot_axis_angle(axis, sp.pi * k / 2)


@st.composite
def random_trees(draw, max_joints: int = 12):
    """A random Robot; structure from hypothesis, real numbers from a generator seeded by hypothesis."""
    n = draw(st.integers(1, max_joints))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    parents = [draw(st.integers(-1, i - 1)) for i in range(n)]
    kinds = [draw(st.sampled_from(["revolute", "prismatic"])) for _ in range(n)]
    aligned = [draw(st.booleans()) for _ in range(n)]  # coordinate axes and right angles: exact zeros and ones
    symbolic = draw(st.booleans())
    joints, defaults = [], {}
    for i in range(n):
        if aligned[i]:
            axis = list(AXES[int(rng.integers(0, 6))])
            rotation = _exact_rotation(rng)
            translation = [sp.Rational(int(k), 10) for k in rng.integers(-5, 6, size=3)]
            point = [sp.Rational(int(k), 10) for k in rng.integers(-3, 4, size=3)]
        else:
            a = rng.normal(size=3)
            axis = (a / np.linalg.norm(a)).tolist()
            rotation = _rotation(rng).tolist()
            translation = rng.uniform(-0.5, 0.5, size=3).tolist()
            point = rng.uniform(-0.3, 0.3, size=3).tolist()
        screw = jaxskid.screw(kinds[i], axis, point if kinds[i] == "revolute" else None)
        mass = float(rng.uniform(0.1, 5.0))
        dims = rng.uniform(0.02, 0.5, size=3)
        box = mass / 12 * np.diag([dims[1] ** 2 + dims[2] ** 2, dims[0] ** 2 + dims[2] ** 2, dims[0] ** 2 + dims[1] ** 2])
        r = _rotation(rng)
        m6 = np.array(jaxskid.spatial_inertia(mass, rng.uniform(-0.2, 0.2, size=3).tolist(), (r @ box @ r.T).tolist(),
                                              about="com").evalf(), dtype=float)
        m6 = (m6 + m6.T) / 2
        if symbolic:
            names = [f"b{i}_{k}" for k in STANDARD]
            m, mcx, mcy, mcz, ixx, ixy, iyy, ixz, iyz, izz = (jaxskid.symbol(k) for k in names)
            inertia = sp.Matrix([[ixx, ixy, ixz, 0, -mcz, mcy], [ixy, iyy, iyz, mcz, 0, -mcx],
                                 [ixz, iyz, izz, -mcy, mcx, 0], [0, mcz, -mcy, m, 0, 0], [-mcz, 0, mcx, 0, m, 0],
                                 [mcy, -mcx, 0, 0, 0, m]])
            values = [m6[5, 5], m6[2, 4], m6[0, 5], m6[1, 3], m6[0, 0], m6[0, 1], m6[1, 1], m6[0, 2], m6[1, 2], m6[2, 2]]
            defaults.update(dict(zip(names, map(float, values))))
        else:
            inertia = sp.Matrix(m6)
        joints.append(Joint(f"j{i}", kinds[i], parents[i], jaxskid.pose(rotation, translation), screw, inertia,
                            f"body{i}"))
    leaves = [i for i in range(n) if i not in parents]
    frames = [Frame(f"tip{i}", i, jaxskid.pose(None, rng.uniform(-0.2, 0.2, size=3).tolist())) for i in leaves[:2]]
    g = draw(st.sampled_from([(0, 0, -9.81), (0, 0, "-g"), (1.2, -0.5, "-g")]))
    if "-g" in g:
        defaults["g"] = 9.81
    return Robot.create(f"tree{n}", joints, g, frames, [f.name for f in frames], defaults)


def term_scale(expected, s, k) -> float:
    """``rel_err``'s floor at state k: 1e-3 times the size of the terms that make up M, C qd, Q_grav and tau.
    The error is relative, except for results that vanish (C qd of one joint), where round-off of those
    terms is all there is."""
    m = np.linalg.norm(expected["mass_matrix"][k])
    return 1e-3 * (m * (1 + np.linalg.norm(s["qd"][k]) ** 2 + np.linalg.norm(s["qdd"][k])) + np.linalg.norm(
        expected["gravity_torques"][k]))


def states(robot, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = robot.n_dof
    return {k: rng.uniform(-2, 2, (N_STATES, n)) for k in ("q", "qd", "qdd")}


def depth_first(robot) -> list[int]:
    """The joints in depth-first order. Pinocchio needs it (each subtree's velocities contiguous); jaxskid
    takes any order with parents first, and the random trees use any."""
    order, stack = [], [i for i in reversed(range(robot.n_dof)) if robot.parents[i] < 0]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(robot.children(i)))
    return order


def pinocchio_values(robot, s):
    """Pinocchio's M, C qd, Q_grav and tau of the same robot, in jaxskid's joint order."""
    order = depth_first(robot)
    new = {old: k for k, old in enumerate(order)}
    joints = [replace(robot.joints[i], parent=new.get(robot.joints[i].parent, -1)) for i in order]
    frames = [replace(f, body=new[f.body]) for f in robot.frames]
    same = Robot.create(robot.name, joints, robot.gravity, frames, robot.end_effectors, dict(robot.defaults), robot.base)
    model, _ = to_pinocchio(same, same.default_params())
    data = model.createData()
    out = {k: [] for k in QUANTITIES}
    for q, qd, qdd in zip(s["q"], s["qd"], s["qdd"]):
        q, qd, qdd = q[order], qd[order], qdd[order]
        m = pin.crba(model, data, q)
        out["mass_matrix"].append(np.triu(m) + np.triu(m, 1).T)
        g = pin.computeGeneralizedGravity(model, data, q).copy()
        out["gravity_torques"].append(g)
        out["coriolis_torques"].append(pin.nonLinearEffects(model, data, q, qd) - g)
        out["inverse_dynamics"].append(pin.rnea(model, data, q, qd, qdd).copy())
    back = np.argsort(order)  # position in Pinocchio's order of each jaxskid joint
    out = {k: np.array(v)[:, back] for k, v in out.items()}
    out["mass_matrix"] = out["mass_matrix"][:, :, back]
    return out


def param_vector(robot, eqs) -> np.ndarray:
    d = robot.default_params()
    return np.array([d[k] for k in eqs.parameters])


@pytest.mark.slow
@deterministic(40)
@given(robot=random_trees())
def test_random_trees_match_pinocchio_and_m_is_spd(robot):
    eqs = jaxskid.derive(robot, QUANTITIES)
    s = states(robot)
    got = ref_.evaluate(eqs, QUANTITIES, s, param_vector(robot, eqs))
    expected = pinocchio_values(robot, s)
    for name in QUANTITIES:
        for k in range(N_STATES):
            assert rel_err(got[name][k], expected[name][k], term_scale(expected, s, k)) <= TOL, (name, k, robot.n_dof)
    m = got["mass_matrix"]
    assert np.array_equal(m, np.swapaxes(m, 1, 2))  # the program computes one triangle: exactly symmetric
    assert np.all(np.linalg.eigvalsh(m)[:, 0] > 0)


@pytest.mark.slow
@deterministic(20)
@given(robot=random_trees())
def test_mdot_minus_2c_is_skew_symmetric(robot):
    eqs = jaxskid.derive(robot, ("mass_matrix", "coriolis_matrix"))
    s = states(robot, 1)
    p = param_vector(robot, eqs)
    h = 1e-30
    # complex step along qd: dM/dt = sum_k dM/dq_k qd_k, exact to rounding
    perturbed = ref_.evaluate(eqs, ("mass_matrix",), {"q": s["q"] + 1j * h * s["qd"]}, p)["mass_matrix"]
    mdot = np.imag(perturbed) / h
    c = ref_.evaluate(eqs, ("coriolis_matrix",), {"q": s["q"], "qd": s["qd"]}, p)["coriolis_matrix"]
    skew = mdot - 2 * c
    # the size of the terms: |M| |qd| (one joint: dM/dt and C are both round-off)
    scale = max(np.abs(mdot).max(), np.abs(c).max(), np.abs(np.real(perturbed)).max() * np.abs(s["qd"]).max())
    # plus an absolute floor for robots whose M barely depends on q (dM/dt and C are then round-off)
    assert np.abs(skew + np.swapaxes(skew, 1, 2)).max() <= 1e-12 * scale + 1e-16
    cqd = np.einsum("bij,bj->bi", c, s["qd"])  # and C qd are the Coriolis forces
    expected = pinocchio_values(robot, s)
    for k in range(N_STATES):
        assert rel_err(cqd[k], expected["coriolis_torques"][k], term_scale(expected, s, k)) <= TOL


@pytest.mark.slow
@deterministic(30)
@given(robot=random_trees())
def test_yaml_round_trip_gives_an_identical_model(robot, tmp_path_factory):
    path = tmp_path_factory.mktemp("roundtrip") / f"{robot.name}.yaml"
    jaxskid.write_description(robot, path)
    again = jaxskid.read_description(path)
    assert again == robot
    assert again.fingerprint() == robot.fingerprint()
    assert again.default_params() == robot.default_params()
    assert jaxskid.parse_description(jaxskid.robot_to_dict(robot), source="<dict>") == robot


@pytest.mark.slow
@deterministic(5)
@given(robot=random_trees(max_joints=6))
def test_jax_lowering_and_recursive_evaluation_match_pinocchio(robot, tmp_path_factory):
    dyn = jaxskid.lower(robot, QUANTITIES, cache_dir=tmp_path_factory.mktemp("cache"))
    rec = recursive_dynamics(robot)
    s = states(robot, 2)
    expected = pinocchio_values(robot, s)
    p = dyn.param_vector()
    np.testing.assert_array_equal(np.asarray(rec.param_vector()), np.asarray(p))
    lowered = {"mass_matrix": dyn.mass_matrix(s["q"]), "coriolis_torques": dyn.coriolis_torques(s["q"], s["qd"]),
               "gravity_torques": dyn.gravity_torques(s["q"]),
               "inverse_dynamics": dyn.inverse_dynamics(s["q"], s["qd"], s["qdd"])}
    for name in QUANTITIES:
        for k in range(N_STATES):
            state = [s[a][k] for a in ("q", "qd", "qdd")[: {"mass_matrix": 1, "gravity_torques": 1,
                                                             "coriolis_torques": 2, "inverse_dynamics": 3}[name]]]
            recursive = rec.raw(name)(*(jnp.asarray(x) for x in state), p)  # eager: no compilation of the whole recursion
            scale = term_scale(expected, s, k)
            assert rel_err(lowered[name][k], expected[name][k], scale) <= TOL, (name, k)
            assert rel_err(recursive, expected[name][k], scale) <= TOL, (name, k)


def test_christoffel_matrix_is_the_three_term_product_and_skew():
    """The per-body ``B(V)`` of the Christoffel Coriolis matrix (``jaxskid.symbolic._coriolis.skew_christoffel``)
    applied to a twist equals Echeandia & Wensing's three terms ``1/2 (M [V, X] + V x* (M X) + X x* (M V))``,
    computed here in NumPy with 6x6 spatial matrices, which is skew-symmetric."""
    from randrobot import random_robot

    from jaxskid.symbolic import Derivation, Inputs
    from jaxskid.symbolic._coriolis import skew_christoffel

    def hat(a):
        return np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])

    def ad(v):  # [V, X] = ad(V) X for V = (w, v)
        return np.block([[hat(v[:3]), np.zeros((3, 3))], [hat(v[3:]), hat(v[:3])]])

    rng = np.random.default_rng(3)
    robot = random_robot(rng, 2)
    d = Derivation(robot, Inputs.of(robot))
    a = rng.normal(size=(3, 3))
    h = rng.normal(size=3)
    m = np.block([[a @ a.T + 2 * np.eye(3), hat(h)], [-hat(h), 1.7 * np.eye(3)]])
    v = rng.normal(size=6)
    b = np.array(skew_christoffel(d, [[sp.Float(e) for e in row] for row in m], [sp.Float(e) for e in v]), dtype=float)
    # column c of the three-term map is its value at the unit twist e_c
    expected = np.stack([0.5 * (m @ ad(v) @ x - ad(v).T @ (m @ x) - ad(x).T @ (m @ v)) for x in np.eye(6)], axis=1)
    assert np.allclose(b, expected, rtol=1e-13, atol=1e-13)
    assert np.allclose(expected, -expected.T, rtol=1e-13, atol=1e-13)
