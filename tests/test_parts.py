"""A long program called from Python in parts, compiled on several cores (jaxskid.runtime._parts).

With native kernels off, a batch of a long matrix-valued quantity called from Python is computed by one program
per block of its rows, compiled at once. Checked here on solo12, split into parts by ``JAXSKID_COMPILE_PARTS``:
against Pinocchio's algorithms and against the quantity as one program (inside ``jax.jit``), for a batch of two
axes, a batch computed a tile at a time, a batch of parameters, ``out=`` and float32; that only a batch called
from Python is split; the rows of a quantity alone; the count of the work that parts repeat, against the cones
of the program's outputs collected one by one; and when a quantity is split without the variable.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import ERD, pinocchio_urdf_model

import jaxskid
from jaxskid.runtime import _emitted, _gathered, _parts

SOLO = ERD / "solo_description/robots/solo12.urdf"
NAMES = ["coriolis_matrix", "regressor"]


def _solo(monkeypatch, parts: str | None = "3"):
    """solo12's C and regressor in the JAX form, with ``parts`` parts (the variable unset: None), and the calls
    of the parts' compilation: the number of programs of each."""
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    if parts is None:
        monkeypatch.delenv(_parts.VARIABLE, raising=False)
    else:
        monkeypatch.setenv(_parts.VARIABLE, parts)
    compiled = []
    original = _parts._compiled
    monkeypatch.setattr(_parts, "_compiled", lambda jits, *a: compiled.append(len(jits)) or original(jits, *a))
    dyn = jaxskid.lower(jaxskid.read_urdf(SOLO), quantities=NAMES)
    for name in NAMES:
        getattr(dyn, name)  # made now, with the environment above
    return dyn, compiled


def _states(n, batch, seed):
    rng = np.random.default_rng(seed)
    return [jnp.asarray(rng.uniform(-1.5, 1.5, (*batch, n))) for _ in range(3)]


def _pinocchio(model, name, q, qd, qdd):
    data = model.createData()
    if name == "regressor":
        return pin.computeJointTorqueRegressor(model, data, q, qd, qdd)
    return pin.computeCoriolisMatrix(model, data, q, qd)


def test_parts_against_pinocchio_and_one_program(monkeypatch):
    dyn, compiled = _solo(monkeypatch)
    model = pinocchio_urdf_model(SOLO)
    states = _states(dyn.n_dof, (3, 5), seed=1)
    for name in NAMES:
        args = states[: len(dyn.signature(name)[0])]
        got = getattr(dyn, name)(*args)
        assert got.shape == (3, 5, *dyn.signature(name)[1])
        one = jax.jit(getattr(dyn, name))(*args)
        np.testing.assert_allclose(got, one, rtol=1e-12, atol=1e-12 * float(jnp.abs(one).max()))
        for i, j in ((0, 0), (1, 3), (2, 4)):
            ref = _pinocchio(model, name, *(np.asarray(x[i, j]) for x in states))
            np.testing.assert_allclose(got[i, j], ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))
    assert compiled == [3, 3]


def test_tiles_parameters_out_and_float32(monkeypatch):
    """A batch written tile by tile (every size here; the last tile overlaps the one before), a batch of
    parameters, a result written into an earlier one (``out=``), and float32 states, each against one program."""
    monkeypatch.setattr(_gathered, "TILE", 5)
    monkeypatch.setattr(_gathered, "TILED_BYTES", 0)
    dyn, compiled = _solo(monkeypatch, "2")
    q, qd, qdd = _states(dyn.n_dof, (23,), seed=2)
    one = jax.jit(dyn.regressor)(q, qd, qdd)
    np.testing.assert_allclose(dyn.regressor(q, qd, qdd), one, rtol=1e-12, atol=1e-12)
    earlier = dyn.regressor(q, qd, qdd)
    np.testing.assert_allclose(dyn.regressor(q, qd, qdd, out=earlier), one, rtol=1e-12, atol=1e-12)
    p = dyn.param_vector()[None, :] * (1 + 0.1 * np.random.default_rng(3).uniform(size=(23, 1)))
    np.testing.assert_allclose(dyn.coriolis_matrix(q, qd, params=p), jax.jit(dyn.coriolis_matrix)(q, qd, params=p),
                               rtol=1e-12, atol=1e-12)
    low = dyn.coriolis_matrix(q.astype(jnp.float32), qd.astype(jnp.float32))
    assert low.dtype == jnp.float32
    high = jax.jit(dyn.coriolis_matrix)(q, qd)
    np.testing.assert_allclose(low, high, rtol=0, atol=1e-4 * float(jnp.abs(high).max()))
    assert compiled == [2, 2, 2, 2]  # one compilation per argument shape: the regressor's out= is a new one


def test_only_a_batch_from_python_is_split(monkeypatch):
    dyn, compiled = _solo(monkeypatch)
    q, qd, _ = _states(dyn.n_dof, (4,), seed=4)
    jax.jit(dyn.coriolis_matrix)(q, qd)
    jax.jit(jax.grad(lambda x: jnp.sum(dyn.coriolis_matrix(x, qd) ** 2)))(q)
    jax.vmap(dyn.coriolis_matrix)(q, qd)
    single = dyn.coriolis_matrix(q[0], qd[0])
    np.testing.assert_allclose(single, jax.jit(dyn.coriolis_matrix)(q, qd)[0], rtol=1e-12, atol=1e-12)
    assert compiled == []
    dyn.coriolis_matrix(q, qd)
    dyn.coriolis_matrix(q, qd)
    assert compiled == [3]


def test_rows_of_a_quantity(monkeypatch):
    """A block of rows computed alone equals those rows of the whole, by the gathered form and by the program."""
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    dyn = jaxskid.lower(jaxskid.read_urdf(SOLO), quantities=["regressor"])
    quantity = dyn.module.quantities["regressor"]
    part = _emitted.rows(quantity, 4, 9)
    assert part.shape == (5, *quantity.shape[1:]) and _emitted.rows(quantity, 4, 9) is part
    q, qd, qdd = (x[0] for x in _states(dyn.n_dof, (1,), seed=5))
    whole = quantity.single()(q, qd, qdd, dyn.param_vector())
    np.testing.assert_allclose(part.single()(q, qd, qdd, dyn.param_vector()), whole[4:9], rtol=0, atol=0)
    lanes = [x[:, None] for x in (q, qd, qdd)] + [dyn.param_vector()]
    gathered = _gathered._assembled(part, lanes, 1)[0]
    np.testing.assert_allclose(gathered, whole[4:9], rtol=1e-13, atol=1e-13)
    entries = part.entries()(q, qd, qdd, dyn.param_vector())
    width = quantity.shape[1]
    for k, v in entries.items():
        assert jnp.allclose(v, whole[4 + k // width, k % width])


def _cone(rec, at, seen):
    """The tape positions output ``at`` reads, collected recursively: the reference for kernels_work."""
    if at in seen:
        return
    seen.add(at)
    kind, a, b = rec.ops[at]
    if kind in _emitted._BINARY:
        _cone(rec, a, seen)
        _cone(rec, b, seen)
    elif kind in _emitted._UNARY:
        _cone(rec, a, seen)


def test_the_work_that_parts_repeat(monkeypatch):
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    dyn = jaxskid.lower(jaxskid.read_urdf(SOLO), quantities=NAMES)
    for name in NAMES:
        quantity = dyn.module.quantities[name]
        rec = _emitted.recorded(quantity)
        values = np.arange(len(rec.outputs))
        expected = 0
        for start in range(0, len(values), _parts.CHUNK):
            seen: set = set()
            for k in values[start:start + _parts.CHUNK]:
                _cone(rec, rec.outputs[k], seen)
            expected += len(seen)
        assert _parts.kernels_work(rec, values) == expected
        ranges = _parts.plan(quantity, 2, checked=False)
        assert ranges[0][0] == 0 and ranges[-1][1] == quantity.shape[0] and ranges[0][1] == ranges[1][0]
        parts = [np.unique(np.concatenate([np.unique(r[r < len(rec.outputs)])
                                           for r in rec.index.reshape(quantity.shape[0], -1)[a:b]]))
                 for a, b in ranges]
        repeated = sum(_parts.kernels_work(rec, p) for p in parts) / expected
        assert (_parts.plan(quantity, 2) is not None) == (repeated <= 1 + _parts.MAX_REPEATED)


def test_when_a_quantity_is_split(monkeypatch):
    """Without the variable, a program of fewer operations than MIN_OPERATIONS, or one core, is one program; the
    variable, if not a number, is an error that names it."""
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    monkeypatch.delenv(_parts.VARIABLE, raising=False)
    dyn = jaxskid.lower(jaxskid.read_urdf(SOLO), quantities=["regressor"])
    quantity = dyn.module.quantities["regressor"]
    rec = _emitted.recorded(quantity)
    assert len(rec.ops) < _parts.MIN_OPERATIONS and _parts.count(quantity) == 1
    monkeypatch.setattr(_parts, "MIN_OPERATIONS", 0)
    monkeypatch.setattr(_parts, "MIN_VALUES", 1)
    monkeypatch.setattr(_parts, "_cores", lambda: 1)
    assert _parts.count(quantity) == 1
    monkeypatch.setattr(_parts, "_cores", lambda: 4)
    assert _parts.count(quantity) == 4
    monkeypatch.setenv(_parts.VARIABLE, "two")
    with pytest.raises(ValueError, match=_parts.VARIABLE):
        _parts.count(quantity)
    monkeypatch.setenv(_parts.VARIABLE, "1")
    assert _parts.count(quantity) == 1
