"""Numerical stability at the extremes, against a 50-digit mpmath evaluation of the same expressions.

Reference: ``jaxskid.testing._reference.mp_reference`` evaluates the derived program at 50 digits at the same (float32-
representable) inputs. Bound: ``jaxskid.testing._reference.error_bound`` gives, for every output entry, the a-priori
bound ``gamma_D * F_abs`` (Higham, "Accuracy and Stability of Numerical Algorithms", 2002, sec. 3.1, Lemma 3.1):
the program uses only +, x and sin/cos of inputs, so the computed value is the exact value of the program with
every operation perturbed by (1 + delta), |delta| <= u; hence |computed - exact| <= gamma_D * F_abs, with D the
largest number of roundings on a path from an input to the entry (the operation count along the recursion) and
F_abs the program evaluated on absolute values (the condition-related scale: large where terms cancel, e.g. where
a 1e6 kg body and a 1e-6 kg body meet in one sum). sin/cos count as 2 roundings in float64 (within one ulp) and 4
in float32 (XLA's vectorised float32 approximations, within two ulps); constants not representable in float32
count one rounding more. These bounds are rigorous for the stated sin/cos accuracy and are asserted entrywise.

Forward dynamics: the perturbation theorem for linear systems (Higham 2002, Thm. 7.2) with the backward error of
a Cholesky-type factorisation (Thm. 10.4) bounds the error of qdd by about cond(M) times the relative errors of M
and of the right-hand side; the reported condition number is checked against mpmath's eigenvalues of the exact M.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest
import sympy as sp

import jaxskid
from helpers import load
from jaxskid import Joint, Robot
from jaxskid.testing import _reference as ref_

QUANTITIES = ("mass_matrix", "gravity_torques", "coriolis_torques", "inverse_dynamics")
ARGS = {"mass_matrix": ("q",), "gravity_torques": ("q",), "coriolis_torques": ("q", "qd"),
        "inverse_dynamics": ("q", "qd", "qdd")}
STANDARD = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
U64, U32 = 2.0**-53, 2.0**-24


def f32_exact(x):
    """Round to float32 and back: inputs that both precisions represent exactly."""
    return np.asarray(x, dtype=np.float32).astype(np.float64)


def body(i: int, mass: float, com, inertia_diag):
    """A body with 10 symbolic standard parameters ``b{i}_*`` and their values for a physically consistent
    solid (mass, centre of mass, principal inertia about it)."""
    names = [f"b{i}_{k}" for k in STANDARD]
    m, mcx, mcy, mcz, ixx, ixy, iyy, ixz, iyz, izz = (jaxskid.symbol(k) for k in names)
    m6 = sp.Matrix([[ixx, ixy, ixz, 0, -mcz, mcy], [ixy, iyy, iyz, mcz, 0, -mcx], [ixz, iyz, izz, -mcy, mcx, 0],
                    [0, mcz, -mcy, m, 0, 0], [-mcz, 0, mcx, 0, m, 0], [mcy, -mcx, 0, 0, 0, m]])
    v = np.array(jaxskid.spatial_inertia(mass, list(com), np.diag(inertia_diag).tolist(), about="com").evalf(),
                 dtype=float)
    values = [v[5, 5], v[2, 4], v[0, 5], v[1, 3], v[0, 0], v[0, 1], v[1, 1], v[0, 2], v[1, 2], v[2, 2]]
    return m6, dict(zip(names, map(float, values)))


def extreme_chain() -> Robot:
    """Five bodies of 1e6, 1e3, 1, 1e-3 and 1e-6 kg (inertias 2e4 .. 2e-8 kg m^2) in one chain: z, y, y, x
    revolute axes and a prismatic leaf. Joints 1 and 2 are parallel (elbow: singular when stretched or folded),
    joint 3's axis meets joint 0's when the arm points up."""
    spec = [  # (type, axis, origin in the parent, mass)
        ("revolute", (0, 0, 1), (0, 0, 0.3), 1e6),
        ("revolute", (0, 1, 0), (0, 0.1, 0), 1e3),
        ("revolute", (0, 1, 0), (0.5, 0, 0), 1.0),
        ("revolute", (1, 0, 0), (0.4, 0, 0), 1e-3),
        ("prismatic", (1, 0, 0), (0.1, 0, 0), 1e-6),
    ]
    joints, defaults = [], {"g": 9.81}
    for i, (kind, axis, origin, mass) in enumerate(spec):
        m6, values = body(i, mass, (0.2, 0.01 * (i + 1), -0.02), (0.02 * mass, 0.03 * mass, 0.04 * mass))
        defaults.update(values)
        joints.append(Joint(f"j{i}", kind, i - 1, jaxskid.pose(None, origin), jaxskid.screw(kind, axis), m6, f"body{i}"))
    return Robot.create("extreme_chain", joints, (0, 0, -jaxskid.symbol("g")), defaults=defaults)


# singular and aligned poses of extreme_chain: q = 0 (stretched, axes 1 and 2 parallel and coplanar), folded
# elbow, arm pointing up (joint 3's axis on joint 0's), both
SINGULAR = np.array([
    [0, 0, 0, 0, 0],
    [0, 0, np.pi, 0, 0],
    [0.3, -np.pi / 2, 0, 0.2, 0.1],
    [1.0, -np.pi / 2, 0, 0, 0],
    [0, np.pi / 2, np.pi, 0, 0],
    [-2.0, 0, 0, np.pi / 2, -0.1],
])


def extreme_states(n_random: int = 10) -> dict[str, np.ndarray]:
    """The singular poses at rest and at 1e3 rad/s; random poses with velocities and accelerations up to
    1e3 rad/s (rad/s^2); the same far from zero (angles of 1e4 rad)."""
    rng = np.random.default_rng(0)
    n = SINGULAR.shape[1]
    q = np.vstack([SINGULAR, SINGULAR, rng.uniform(-np.pi, np.pi, (2 * n_random, n))])
    far = np.arange(len(q)) >= len(q) - n_random
    q[far, :4] += rng.choice([-1e4, 1e4], size=(n_random, 4))  # revolute joints only (the leaf slides)
    qd = np.zeros_like(q)
    qd[len(SINGULAR):] = rng.uniform(-1e3, 1e3, (len(q) - len(SINGULAR), n))
    qdd = rng.uniform(-1e3, 1e3, q.shape)
    return {"q": f32_exact(q), "qd": f32_exact(qd), "qdd": f32_exact(qdd)}


@pytest.fixture(scope="module")
def chain():
    robot = extreme_chain()
    eqs = jaxskid.derive(robot, QUANTITIES)
    dyn = jaxskid.lower(robot, QUANTITIES)
    params = np.array([robot.default_params()[k] for k in eqs.parameters])
    assert dyn.parameters == eqs.parameters
    return robot, eqs, dyn, params


def evaluate_jax(dyn, states, params, dtype):
    out = {}
    p = jnp.asarray(params, dtype=dtype)
    for name in QUANTITIES:
        args = [jnp.asarray(states[a], dtype=dtype) for a in ARGS[name]]
        out[name] = np.asarray(jax.vmap(dyn.raw(name), in_axes=(*([0] * len(args)), None))(*args, p))
        assert out[name].dtype == dtype
    return out


def check_within_bound(chain, params, dtype, trig_roundings: int, normwise: float) -> None:
    """jaxskid's values at the extreme states in ``dtype``, parameters ``params``: finite, each entry within its
    rounding-error bound of the 50-digit value, and the normwise relative error below ``normwise``."""
    _, eqs, dyn, _ = chain
    states = extreme_states()
    exact = ref_.mp_reference(eqs, QUANTITIES, states, params)
    bound = ref_.error_bound(eqs, QUANTITIES, states, params, dtype=dtype, trig_roundings=trig_roundings)
    got = evaluate_jax(dyn, states, params, dtype)
    for name in QUANTITIES:
        assert np.all(np.isfinite(got[name])), name
        err = ref_.abs_error(got[name], exact[name])
        worst = np.unravel_index(np.argmax(err - bound[name]), err.shape)
        assert np.all(err <= bound[name]), (name, worst, err[worst], bound[name][worst])
        assert ref_.rel_error(got[name], exact[name]).max() < normwise, name


def test_masses_1e_6_to_1e6_velocities_1e3_far_angles_float64(chain):
    params = chain[-1]
    # what the bound means normwise here (measured: 2e-16 .. 1.4e-15)
    check_within_bound(chain, params, np.float64, trig_roundings=2, normwise=1e-14)


def test_float32_errors_are_bounded(chain):
    p32 = f32_exact(chain[-1])  # the parameters a float32 user passes, exactly
    # reported: normwise 7e-8 (M) .. 8e-7 (Q_grav); light links lose more, componentwise up to ~2e-4
    check_within_bound(chain, p32, np.float32, trig_roundings=4, normwise=1e-5)


def complex_step(eqs, states, params, wrt: str, k: int, h: float = 1e-30) -> np.ndarray:
    """d/dx_k of L (see test_grad_is_finite...) by the complex step: Im L(x + i h e_k) / h, exact to rounding."""
    states = {a: np.asarray(v, dtype=complex) for a, v in states.items()}
    params = np.asarray(params, dtype=complex)
    if wrt == "p":
        params = params.copy()
        params[k] += 1j * h
    else:
        states[wrt] = states[wrt].copy()
        states[wrt][:, k] += 1j * h
    out = ref_.evaluate(eqs, QUANTITIES, states, params)
    return np.imag(scalar(out, np)) / h


def scalar(out, xp):
    """L = sum of every output entry times a fixed weight: one scalar that depends on all of them."""
    total = 0.0
    for k, name in enumerate(QUANTITIES):
        v = out[name].reshape(out[name].shape[0], -1)
        w = xp.cos(xp.arange(v.shape[1]) + k)
        total = total + xp.sum(v * w[None, :], axis=1)
    return total


@pytest.mark.slow
def test_grad_is_finite_and_exact_at_zero_and_singular_poses(chain):
    robot, eqs, dyn, params = chain
    n = robot.n_dof
    rng = np.random.default_rng(1)
    states = {"q": SINGULAR, "qd": rng.uniform(-3, 3, SINGULAR.shape), "qdd": rng.uniform(-3, 3, SINGULAR.shape)}

    def loss(q, qd, qdd, p):
        out = {name: dyn.raw(name)(*[{"q": q, "qd": qd, "qdd": qdd}[a] for a in ARGS[name]], p)[None]
               for name in QUANTITIES}
        return scalar(out, jnp)[0]

    grad = jax.jit(jax.vmap(jax.grad(loss, argnums=(0, 3)), in_axes=(0, 0, 0, None)))
    gq, gp = (np.asarray(g) for g in grad(*(jnp.asarray(states[a]) for a in ("q", "qd", "qdd")), jnp.asarray(params)))
    assert np.all(np.isfinite(gq)) and np.all(np.isfinite(gp))
    for k in range(n):
        ref = complex_step(eqs, states, params, "q", k)
        np.testing.assert_allclose(gq[:, k], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    for k in range(len(params)):
        ref = complex_step(eqs, states, params, "p", k)
        np.testing.assert_allclose(gp[:, k], ref, rtol=1e-12, atol=1e-12 * max(np.abs(ref).max(), 1e-300))


# ---------------------------------------------------------------------------------------------- a real robot
@pytest.fixture(scope="module")
def panda():
    robot = load("panda7")
    names = ("mass_matrix", "gravity_torques", "inverse_dynamics")
    eqs = jaxskid.derive(robot, names)
    dyn = jaxskid.lower(robot, names)
    return robot, eqs, dyn, np.array([robot.default_params()[k] for k in eqs.parameters])


def test_panda_aligned_poses_far_angles_and_high_speed(panda):
    robot, eqs, dyn, params = panda
    names = ("mass_matrix", "gravity_torques", "inverse_dynamics")
    rng = np.random.default_rng(2)
    aligned = np.array([  # q = 0: axes 1, 3, 5, 7 vertical and in line; stretched elbow; wrist on the forearm axis
        [0, 0, 0, 0, 0, 0, 0],
        [0, 0, 0, 0, 0, np.pi, 0],
        [0.5, 0, -0.5, 0, 1.0, 0, 0.3],
        [0, np.pi / 2, 0, 0, 0, 0, 0],
    ])
    random = rng.uniform(-np.pi, np.pi, (8, 7))
    q = np.vstack([aligned, aligned + 1e4, random, random - 1e4])
    states = {"q": f32_exact(q), "qd": f32_exact(rng.uniform(-1e3, 1e3, q.shape)),
              "qdd": f32_exact(rng.uniform(-1e3, 1e3, q.shape))}
    exact = ref_.mp_reference(eqs, names, states, params)
    bound = ref_.error_bound(eqs, names, states, params, dtype=np.float64)
    got = {"mass_matrix": dyn.mass_matrix(states["q"]), "gravity_torques": dyn.gravity_torques(states["q"]),
           "inverse_dynamics": dyn.inverse_dynamics(states["q"], states["qd"], states["qdd"])}
    for name in names:
        value = np.asarray(got[name])
        assert np.all(np.isfinite(value)), name
        assert np.all(ref_.abs_error(value, exact[name]) <= bound[name]), name
        assert ref_.rel_error(value, exact[name]).max() < 1e-14, name


# ---------------------------------------------------------------------------------------------- nearly singular M
def coaxial(mu: float) -> Robot:
    """Two coaxial revolute joints with a body of mass ``mu`` between them, then an arm link: as mu -> 0 the
    two joints make the same motion and M becomes singular (cond(M) ~ 1/mu)."""
    spec = [((0, 0, 1), (0, 0, 0.3), mu, (0, 0, 0)), ((0, 0, 1), (0, 0, 0), 1.0, (0.2, 0.05, 0.01)),
            ((0, 1, 0), (0.4, 0, 0), 0.5, (0.2, 0.05, 0.01))]
    joints, defaults = [], {"g": 9.81}
    for i, (axis, origin, mass, com) in enumerate(spec):
        m6, values = body(i, mass, com, (0.02 * mass, 0.03 * mass, 0.04 * mass))
        defaults.update(values)
        joints.append(Joint(f"j{i}", "revolute", i - 1, jaxskid.pose(None, origin), jaxskid.screw("revolute", axis),
                            m6, f"body{i}"))
    return Robot.create("coaxial", joints, (0, -jaxskid.symbol("g"), 0), defaults=defaults)


@pytest.fixture(scope="module")
def coaxial_dynamics():
    robot = coaxial(1.0)  # the structure; the masses are parameters
    names = ("mass_matrix", "inverse_dynamics")
    return robot, jaxskid.derive(robot, names), jaxskid.lower(robot, names)


def mp_matrix(reference, k):
    hi, lo = reference.hi[k], reference.lo[k]
    return mpmath.matrix([[mpmath.mpf(hi[r, c]) + mpmath.mpf(lo[r, c]) for c in range(hi.shape[1])]
                          for r in range(hi.shape[0])])


@pytest.mark.parametrize("mu", [1e-2, 1e-6, 1e-10, 1e-14, 1e-17, 0.0])
def test_condition_number_is_reported_and_bounds_the_forward_dynamics_error(coaxial_dynamics, mu):
    robot, eqs, dyn = coaxial_dynamics
    params_map = coaxial(mu).default_params()
    params = np.array([params_map[k] for k in eqs.parameters])
    n = robot.n_dof
    rng = np.random.default_rng(3)
    q = f32_exact(np.vstack([np.zeros(n), rng.uniform(-2, 2, (5, n))]))
    qd = f32_exact(rng.uniform(-3, 3, q.shape))
    tau = f32_exact(rng.uniform(-1, 1, q.shape))
    states = {"q": q, "qd": qd, "qdd": np.zeros_like(q)}  # the bias C qd + Q_grav is tau at qdd = 0
    exact = ref_.mp_reference(eqs, ("mass_matrix", "inverse_dynamics"), states, params)
    bound = ref_.error_bound(eqs, ("mass_matrix", "inverse_dynamics"), states, params)
    cond = np.asarray(jaxskid.mass_matrix_condition(dyn, q, params))
    qdd = np.asarray(jaxskid.forward_dynamics(dyn, q, qd, tau, params))
    for k in range(len(q)):
        m = mp_matrix(exact["mass_matrix"], k)
        with mpmath.workdps(50):
            ev = mpmath.eigsy(m, eigvals_only=True)
            lam = sorted(float(x) for x in ev)
            true_cond = lam[-1] / lam[0] if lam[0] > 0 else np.inf
            rhs = mpmath.matrix([mpmath.mpf(tau[k, i]) - (mpmath.mpf(exact["inverse_dynamics"].hi[k, i])
                                                           + mpmath.mpf(exact["inverse_dynamics"].lo[k, i]))
                                 for i in range(n)])
            x = None if lam[0] <= 0 else mpmath.lu_solve(m, rhs)
        norm_m = lam[-1]
        # relative perturbation of M: its evaluation (the entry bounds, Frobenius) plus the backward error of
        # the LDL^T solve, ||dM||_2 <= 4 n (3 n + 1) u ||M||_2 (Higham 2002, Thm. 10.4) and a few u for the
        # pivots' reciprocals
        eps_m = np.linalg.norm(bound["mass_matrix"][k]) / norm_m + (4 * n * (3 * n + 1) + 8) * U64
        if true_cond * eps_m < 0.1:
            # Weyl: |lambda_min error| <= ||dM||_2, so the reported cond is within 2 cond eps_m (relative)
            assert abs(cond[k] / true_cond - 1) <= 2 * true_cond * eps_m + 1e-12, (mu, k, cond[k], true_cond)
            # Higham 2002, Thm. 7.2: ||dx|| / ||x|| <= 2 eps cond / (1 - eps cond)
            x = np.array([float(v) for v in x])
            rhs_norm = float(mpmath.norm(rhs))
            eps_b = (np.linalg.norm(bound["inverse_dynamics"][k]) + U64 * np.linalg.norm(tau[k])) / rhs_norm + U64
            eps = max(eps_m, eps_b)
            err = np.linalg.norm(qdd[k] - x) / np.linalg.norm(x)
            assert err <= 2 * eps * true_cond / (1 - eps * true_cond), (mu, k, err, true_cond)
        else:
            # too ill-conditioned for float64: the reported number must say so instead of passing as fine.
            # (jaxskid.mass_matrix_condition returns lambda_max / lambda_min, which is negative when M is
            # numerically indefinite; a negative value is flagged too: no SPD matrix has one.)
            assert not (0 < cond[k] < 0.01 / (4 * n * (3 * n + 1) * U64)), (mu, k, cond[k], true_cond)


def test_lowering_two_robots_that_differ_only_in_defaults_keeps_each_ones_defaults(tmp_path):
    # regression: the cache key left out the default values that the cached module's METADATA holds, so the
    # second robot silently got the first one's defaults (here: a 1e-6 kg body reported with 1e-2 kg)
    first = jaxskid.lower(coaxial(1e-2), ["gravity_torques"], cache_dir=tmp_path)
    second = jaxskid.lower(coaxial(1e-6), ["gravity_torques"], cache_dir=tmp_path)
    assert first.defaults["b0_m"] == 1e-2 and second.defaults["b0_m"] == 1e-6
    assert first.source != second.source and len(list(tmp_path.glob("*.py"))) == 2
