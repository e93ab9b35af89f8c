"""The sparse factorisation and KKT solve on scalars (jaxskid.runtime._sparse) against numpy's dense solves,
on random tree patterns (no fill-in), random patterns with fill-in, and singular constraint rows; and the
generated modules' entries form against their assembled output."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import ROBOTS_DIR
from jaxskid.runtime import _sparse

jax.config.update("jax_enable_x64", True)


def _tree_pattern(rng, n: int) -> np.ndarray:
    """M's pattern of a random tree whose joints come after their parents: i and j couple when one supports
    the other."""
    parent = [-1] + [int(rng.integers(-1, i)) for i in range(1, n)]
    support = np.zeros((n, n), bool)
    for i in range(n):
        k = i
        while k >= 0:
            support[i, k] = True
            k = parent[k]
    return support | support.T


def _spd(rng, pattern: np.ndarray) -> np.ndarray:
    """A symmetric positive definite matrix with exactly ``pattern``'s nonzeros (diagonally dominant)."""
    x = rng.normal(size=pattern.shape) * pattern
    x = (x + x.T) / 2
    return x + np.diag(np.abs(x).sum(axis=1) + 1.0)


def _entries(matrix: np.ndarray) -> dict:
    cols = matrix.shape[1]
    return {i * cols + j: jnp.asarray(v) for (i, j), v in np.ndenumerate(matrix) if v != 0}


def _dense(values) -> np.ndarray:
    return np.array([0.0 if v is None else float(v) for v in values])


@pytest.mark.parametrize("kind", ["tree", "fill"])
def test_factor_and_kkt_match_dense_solves(kind):
    rng = np.random.default_rng(0 if kind == "tree" else 1)
    for trial in range(20):
        n = int(rng.integers(2, 12))
        m = int(rng.integers(1, min(n, 4) + 1))
        pattern = _tree_pattern(rng, n) if kind == "tree" else (lambda p: p | p.T | np.eye(n, dtype=bool))(
            rng.random((n, n)) < 0.3)
        mass = _spd(rng, pattern)
        b = rng.normal(size=n)
        f = _sparse.factor(_entries(mass), n)
        if kind == "tree":  # leaves first: no fill-in, L has M's strictly lower pattern (in elimination order)
            assert len(f.lo) == (pattern.sum() - n) // 2
        np.testing.assert_allclose(_dense(_sparse.solve(f, list(map(jnp.asarray, b)))), np.linalg.solve(mass, b),
                                   rtol=1e-10, atol=1e-12)
        a = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.6)
        a[np.arange(m), rng.choice(n, m, replace=False)] = 1.0  # no zero rows
        if np.linalg.matrix_rank(a) < m:
            continue
        r1, r2 = rng.normal(size=n), rng.normal(size=m)
        x, lam = _sparse.kkt(_entries(mass), _entries(a), list(map(jnp.asarray, r1)), list(map(jnp.asarray, r2)))
        kkt = np.block([[mass, -a.T], [a, np.zeros((m, m))]])
        ref = np.linalg.solve(kkt, np.concatenate([r1, r2]))
        scale = np.abs(ref).max()
        assert np.abs(_dense(x) - ref[:n]).max() < 1e-9 * scale, trial
        assert np.abs(_dense(lam) - ref[n:]).max() < 1e-9 * scale, trial


def test_zero_constraint_rows_are_singular_unless_regularised():
    rng = np.random.default_rng(2)
    n = 5
    mass = _spd(rng, _tree_pattern(rng, n))
    a = rng.normal(size=(2, n))
    a[1] = 0.0
    r1 = list(map(jnp.asarray, rng.normal(size=n)))
    x, lam = _sparse.kkt(_entries(mass), _entries(a), r1, [jnp.asarray(0.3), None])
    assert np.isnan(_dense(x)).all() and np.isnan(_dense(lam)).all()
    x, lam = _sparse.kkt(_entries(mass), _entries(a), r1, [jnp.asarray(0.3), None], eps=1e-12)
    one = np.linalg.solve(np.block([[mass, -a[:1].T], [a[:1], np.zeros((1, 1))]]),
                          np.concatenate([_dense(r1), [0.3]]))
    np.testing.assert_allclose(_dense(x), one[:n], rtol=1e-9)
    assert lam[1] is None  # exactly zero
    assert abs(float(lam[0]) - one[n]) < 1e-9 * abs(one[n])


def test_indefinite_mass_matrix_gives_nan():
    mass = np.array([[1.0, 2.0], [2.0, 1.0]])
    x = _sparse.solve(_sparse.factor(_entries(mass), 2), [jnp.asarray(1.0), jnp.asarray(1.0)])
    assert np.isnan(_dense(x)).all()


def test_entries_are_the_assembled_outputs_nonzeros():
    robot = jaxskid.load(ROBOTS_DIR / "quadruped_contact.yaml")
    dyn = jaxskid.lower(robot, ["mass_matrix", "constraint_jacobian", "inverse_dynamics"])
    rng = np.random.default_rng(3)
    q = np.asarray(dyn.integrate(np.concatenate([[0, 0, 0, 0, 0, 0, 1.0], rng.normal(size=robot.n_dof)]),
                                 rng.normal(size=robot.nv)))
    qd, qdd = rng.normal(size=(2, robot.nv))
    p = dyn.param_vector()
    for name, args in [("mass_matrix", (q,)), ("constraint_jacobian", (q,)), ("inverse_dynamics", (q, qd, qdd))]:
        full = np.asarray(dyn.generated(name, False)(*args, p)).ravel()
        entries = dyn.entries(name)(*args, p)
        dense = np.zeros_like(full)
        for k, v in entries.items():
            dense[k] = v
        np.testing.assert_allclose(dense, full, rtol=1e-13, atol=1e-15)
        assert all(full[k] == 0 for k in range(full.size) if k not in entries)
        assert len(entries) < full.size or name == "inverse_dynamics"  # the zeros are left out
