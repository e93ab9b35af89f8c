"""Closed-form time derivatives of M, C, Q_grav, tau and Q_ext against independent references.

* every first derivative against ``jax.jvp`` of the lowered lower-order quantity along the trajectory
  (q, qd, qdd, q3d, q4d and wrench, wrench_d, wrench_dd), every second derivative against nested jvp;
* dtau/dt and dQ_grav/dt against Pinocchio's analytical derivatives (``computeRNEADerivatives``,
  ``computeGeneralizedGravityDerivatives``) contracted with the trajectory;
* dM/dt = C + C^T and d^2M/dt^2 = dC/dt + dC/dt^T (C is Christoffel-consistent);
* the 2R arm's dM/dt and d^2M/dt^2 against the textbook closed form, symbolically.

Robots: Panda (7 DOF, fingers locked), solo12 (fixed base, a tree) and the hopping leg, random states,
float64, relative error at most 1e-9 (normwise, per state). The functions are evaluated eagerly under
``jax.disable_jit``: the check is about the derivation, and compiling the second-order Coriolis matrix
of a 7-DOF arm would dominate the suite; ``test_compiled_matches_eager`` covers the jit path.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import sympy as sp

import jaxskid
from jaxskid.testing import closed_form
from helpers import ROBOTS_DIR, load, max_rel_err
from pinref import to_pinocchio

BASES = ["mass_matrix", "coriolis_matrix", "gravity_torques", "inverse_dynamics", "external_torques"]
ALL = [f"{b}{s}" for b in BASES for s in ("", "_dot", "_ddot")]
NEXT = {"q": "qd", "qd": "qdd", "qdd": "q3d", "q3d": "q4d", "wrench": "wrench_d", "wrench_d": "wrench_dd"}
N_STATES = 4
TOL = 1e-9


SLOW = pytest.mark.slow


@pytest.fixture(scope="module", params=[pytest.param("panda7", marks=SLOW), pytest.param("solo12", marks=SLOW),
                                        "hopping_leg"])
def case(request):
    robot = load(request.param)
    dyn = jaxskid.lower(robot, ALL)
    rng = np.random.default_rng(17)
    n, n_ee = robot.n_dof, len(robot.end_effectors)
    state = {"q": rng.uniform(-np.pi, np.pi, size=(N_STATES, n))}
    for k in ("qd", "qdd", "q3d", "q4d"):
        state[k] = rng.normal(size=(N_STATES, n)) * 2.0
    for k in ("wrench", "wrench_d", "wrench_dd"):
        state[k] = rng.normal(size=(N_STATES, n_ee, 6)) * 10.0
    return request.param, robot, dyn, {k: jnp.asarray(v) for k, v in state.items()}


def evaluate(dyn, name, state):
    args, _ = dyn.signature(name)
    with jax.disable_jit():
        return np.asarray(getattr(dyn, name)(*(state[a] for a in args)))


def jvp_references(dyn, base, state):
    """(first, second) time derivative of ``base`` by jax.jvp and nested jax.jvp of its generated function."""
    args, _ = dyn.signature(base)
    p = dyn.param_vector()
    f = dyn.raw(base)
    first_args = (*args, *(NEXT[a] for a in args))

    def d1(*x):  # x = (args..., their derivatives...)
        k = len(args)
        return jax.jvp(lambda *y: f(*y, p), x[:k], x[k:])[1]

    def d2(*x):  # x = (first_args..., their derivatives...)
        k = len(first_args)
        return jax.jvp(d1, x[:k], x[k:])[1]

    with jax.disable_jit():
        first = jax.vmap(d1)(*(state[a] for a in first_args))
        second = jax.vmap(d2)(*(state[a] for a in (*first_args, *(NEXT[a] for a in first_args))))
    return np.asarray(first), np.asarray(second)


@pytest.mark.parametrize("base", BASES)
def test_time_derivatives_match_nested_jvp(case, base):
    name, robot, dyn, state = case
    first, second = jvp_references(dyn, base, state)
    err1 = max_rel_err(evaluate(dyn, f"{base}_dot", state), first)
    err2 = max_rel_err(evaluate(dyn, f"{base}_ddot", state), second)
    assert err1 <= TOL, f"{name} {base}_dot: relative error {err1:.3g} against jax.jvp"
    assert err2 <= TOL, f"{name} {base}_ddot: relative error {err2:.3g} against nested jax.jvp"


def test_signatures(case):
    _, robot, dyn, _ = case
    n = robot.n_dof
    expected = {
        "mass_matrix_dot": (("q", "qd"), (n, n)),
        "mass_matrix_ddot": (("q", "qd", "qdd"), (n, n)),
        "coriolis_matrix_dot": (("q", "qd", "qdd"), (n, n)),
        "coriolis_matrix_ddot": (("q", "qd", "qdd", "q3d"), (n, n)),
        "gravity_torques_dot": (("q", "qd"), (n,)),
        "gravity_torques_ddot": (("q", "qd", "qdd"), (n,)),
        "inverse_dynamics_dot": (("q", "qd", "qdd", "q3d"), (n,)),
        "inverse_dynamics_ddot": (("q", "qd", "qdd", "q3d", "q4d"), (n,)),
        "external_torques_dot": (("q", "qd", "wrench", "wrench_d"), (n,)),
        "external_torques_ddot": (("q", "qd", "qdd", "wrench", "wrench_d", "wrench_dd"), (n,)),
    }
    for name, sig in expected.items():
        assert dyn.signature(name) == sig, name


def test_mass_matrix_derivatives_from_coriolis(case):
    """dM/dt = C + C^T and d^2M/dt^2 = dC/dt + dC/dt^T, for the Christoffel-consistent C."""
    name, _, dyn, state = case
    c, cd = evaluate(dyn, "coriolis_matrix", state), evaluate(dyn, "coriolis_matrix_dot", state)
    assert max_rel_err(evaluate(dyn, "mass_matrix_dot", state), c + np.swapaxes(c, 1, 2)) <= TOL, name
    assert max_rel_err(evaluate(dyn, "mass_matrix_ddot", state), cd + np.swapaxes(cd, 1, 2)) <= TOL, name


def test_first_derivatives_match_pinocchio(case):
    """dtau/dt = dtau/dq qd + dtau/dqd qdd + dtau/dqdd q3d and dQ_grav/dt = dg/dq qd, Pinocchio's analytical
    partial derivatives (computeRNEADerivatives, computeGeneralizedGravityDerivatives)."""
    name, robot, dyn, state = case
    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    tau_dot = evaluate(dyn, "inverse_dynamics_dot", state)
    grav_dot = evaluate(dyn, "gravity_torques_dot", state)
    q, qd, qdd, q3d = (np.asarray(state[k]) for k in ("q", "qd", "qdd", "q3d"))
    for k in range(N_STATES):
        dq, dv, da = pin.computeRNEADerivatives(model, data, q[k], qd[k], qdd[k])
        ref = dq @ qd[k] + dv @ qdd[k] + np.triu(da) @ q3d[k] + np.triu(da, 1).T @ q3d[k]
        assert max_rel_err(tau_dot[k:k + 1], ref[None]) <= TOL, f"{name} inverse_dynamics_dot vs Pinocchio"
        dg = pin.computeGeneralizedGravityDerivatives(model, data, q[k])
        assert max_rel_err(grav_dot[k:k + 1], (dg @ qd[k])[None]) <= TOL, f"{name} gravity_torques_dot vs Pinocchio"


def test_compiled_matches_eager():
    """The jit-compiled functions (the user's path) agree with the eager evaluation, on the hopping leg."""
    robot = load("hopping_leg")
    dyn = jaxskid.lower(robot, ALL)
    rng = np.random.default_rng(3)
    state = {k: rng.normal(size=(N_STATES, robot.n_dof)) for k in ("q", "qd", "qdd", "q3d", "q4d")}
    state.update({k: rng.normal(size=(N_STATES, 1, 6)) for k in ("wrench", "wrench_d", "wrench_dd")})
    for q in ALL:
        args, _ = dyn.signature(q)
        compiled = np.asarray(getattr(dyn, q)(*(state[a] for a in args)))
        np.testing.assert_allclose(compiled, evaluate(dyn, q, state), rtol=1e-12, atol=1e-12, err_msg=q)


# ------------------------------------------------------------------------------------------- 2R arm
def test_arm_2r_mass_matrix_derivatives_closed_form():
    """Lynch & Park (2017) sec. 8.1.1: M11 = m1 l1^2 + m2 (l1^2 + 2 l1 l2 cos q2 + l2^2),
    M12 = m2 (l1 l2 cos q2 + l2^2), M22 = m2 l2^2, so (by hand)
    dM/dt = -m2 l1 l2 sin(q2) qd2 [[2, 1], [1, 0]] and
    d^2M/dt^2 = -m2 l1 l2 (cos(q2) qd2^2 + sin(q2) qdd2) [[2, 1], [1, 0]]."""
    robot = jaxskid.load(ROBOTS_DIR / "arm_2r.yaml")
    eqs = jaxskid.derive(robot, ["mass_matrix_dot", "mass_matrix_ddot"])
    m2, l1, l2 = (jaxskid.symbol(x) for x in ("m2", "l1", "l2"))
    q2 = eqs.arguments["q"].symbols[1]
    qd2 = eqs.arguments["qd"].symbols[1]
    qdd2 = eqs.arguments["qdd"].symbols[1]
    pattern = [2, 1, 1, 0]
    first = [-m2 * l1 * l2 * sp.sin(q2) * qd2 * k for k in pattern]
    second = [-m2 * l1 * l2 * (sp.cos(q2) * qd2**2 + sp.sin(q2) * qdd2) * k for k in pattern]
    for name, ref in (("mass_matrix_dot", first), ("mass_matrix_ddot", second)):
        for ours, want in zip(closed_form(eqs, name), ref):
            assert sp.simplify(sp.expand_trig(ours - want)) == 0, (name, ours, want)
