"""The gathered form's recorded program (jaxskid.runtime._emitted) against the same program traced with jax.numpy.

The recorded program writes the same operations into the lowered module as the trace does, so the two agree to the
last bit: on the Panda (M, C, the regressor and forward dynamics, whose reciprocals are the generated module's
helper) and a floating double pendulum (M and forward dynamics: the base's quaternion), in float64 with the parameters
shared and in float32 with them batched, one state and a batch. The gathered form built on it is checked against
Pinocchio in tests/test_gathered.py. Also here: a program the tape cannot record, arguments of two dtypes and
JAXSKID_RECORD=0 are traced instead, the primitive's own evaluation, mapping and derivative agree with the
traced program's, its trace is one equation, not one per operation, and given the parameters' values it reads
them as constants.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import FINGERS, PANDA, URDFS

import jaxskid
from jaxskid.runtime import _emitted, _gathered

PANDA_QUANTITIES = ["mass_matrix", "coriolis_matrix", "regressor", "forward_dynamics"]


def _lowered(robot, names):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JAXSKID_NATIVE", "0")
        return jaxskid.lower(robot, quantities=names)


@pytest.fixture(scope="module")
def panda():
    return _lowered(jaxskid.read_urdf(PANDA, lock=FINGERS), PANDA_QUANTITIES)


@pytest.fixture(scope="module")
def floating():
    """A double pendulum on a floating base (8 velocities): its forward dynamics reads the base's quaternion."""
    robot = jaxskid.load(URDFS["double_pendulum"], floating_base=True)
    return _lowered(robot, ["mass_matrix", "forward_dynamics"])


def _arguments(dyn, name, batch, dtype, batched_params, seed=0):
    """Arguments as the gathered form's rule passes them: each state argument with the batch on its last axis."""
    rng = np.random.default_rng(seed)
    args = [rng.uniform(-1.2, 1.2, (*dyn.argument_shape(a), *batch)) for a in dyn.signature(name)[0]]
    p = np.asarray(dyn.param_vector())
    if batched_params:
        p = p[:, None] * rng.uniform(0.8, 1.2, (p.size, *batch))
    if dyn.argument_shape("q") != dyn.argument_shape("qd"):  # a floating base: nq = nv + 1
        quat = args[0][3:7]  # a unit quaternion (x, y, z, w) for the base
        args[0][3:7] = quat / np.linalg.norm(quat, axis=0)
    return [jnp.asarray(a, dtype) for a in (*args, p)]


def _both(dyn, name, args, lanes):
    quantity = dyn.module.quantities[name]
    found = jax.jit(lambda *a: _emitted.values(quantity, a, lanes))(*args)
    assert found is not None
    emitted, index = found
    rec = _emitted.recorded(quantity)
    traced = jax.jit(lambda *a: _emitted.traced_values(rec, lanes, None, *a))(*args)
    return emitted, traced, index


@pytest.mark.parametrize(("dtype", "batched_params"), [(jnp.float64, False), (jnp.float32, True)])
def test_panda_bit_for_bit(panda, dtype, batched_params):
    for name in PANDA_QUANTITIES:
        args = _arguments(panda, name, (6,), dtype, batched_params)
        emitted, traced, index = _both(panda, name, args, (_gathered.LANES, 6))
        assert len(emitted) == len(traced) and set(index.tolist()) - {len(emitted)} == set(range(len(emitted)))
        for e, t in zip(emitted, traced):
            assert e.dtype == dtype and e.shape == (_gathered.LANES, 6)
            np.testing.assert_array_equal(e, t)


def test_floating_base_and_one_state(floating):
    for name in ("mass_matrix", "forward_dynamics"):
        for batch in ((), (5,)):
            args = _arguments(floating, name, batch, jnp.float64, False, seed=1)
            emitted, traced, _ = _both(floating, name, args, (_gathered.LANES, *batch))
            for e, t in zip(emitted, traced):
                np.testing.assert_array_equal(e, t)


def test_the_table_is_one_equation(panda, monkeypatch):
    """The gathered form's trace holds the program as one equation; with JAXSKID_RECORD=0, one per operation."""
    quantity = panda.module.quantities["coriolis_matrix"]
    args = _arguments(panda, "coriolis_matrix", (6,), jnp.float64, False)

    def equations():
        jaxpr = jax.make_jaxpr(lambda *a: _gathered._table(quantity, a, 6)[0])(*args)
        return [e.primitive.name for e in jaxpr.jaxpr.eqns]

    names = equations()
    assert names.count("jaxskid_recorded_values") == 1
    assert len(names) < 40
    monkeypatch.setenv("JAXSKID_RECORD", "0")
    assert _emitted.values(quantity, args, (2, 6)) is None
    names = equations()
    assert "jaxskid_recorded_values" not in names
    assert names.count("mul") > 200


def test_unrecorded_programs_are_traced(panda):
    """A program calling a function the tape does not record, and arguments of two dtypes, take the traced path,
    and the gathered form still gives the program's values."""
    quantity = panda.module.quantities["mass_matrix"]
    namespace = dict(quantity.program.__globals__)
    exec("def program(q, p, spread, entries=False):\n"
         "    x = spread(q[0])\n"
         "    return {0: jnp.tanh(x) * p[0], 3: x}\n", namespace)
    odd = dataclasses.replace(quantity, name="odd", shape=(2, 2), program=namespace["program"])
    assert _emitted.recorded(odd) is None
    q, p = jnp.asarray([[0.3, -0.7]]), jnp.asarray([2.0, 1.0])
    assert _emitted.values(odd, (q, p), (2, 2)) is None
    table, index = _gathered._table(odd, (q, p), 2)
    got = jnp.take(table, index, axis=1).reshape(2, 2, 2)
    np.testing.assert_allclose(got[:, 0, 0], 2.0 * np.tanh([0.3, -0.7]), rtol=1e-15)
    np.testing.assert_array_equal(got[:, 1, 1], [0.3, -0.7])
    np.testing.assert_array_equal(got[:, 0, 1], 0.0)
    mixed = _arguments(panda, "mass_matrix", (4,), jnp.float64, False)
    assert _emitted.recorded(quantity) is not None
    assert _emitted.values(quantity, (mixed[0].astype(jnp.float32), mixed[1]), (2, 4)) is None


def test_evaluation_mapping_and_derivative(panda):
    """The primitive evaluated outside a trace, mapped over a further axis and differentiated in forward mode
    agrees with the traced program."""
    name = "coriolis_matrix"
    quantity = panda.module.quantities[name]
    rec = _emitted.recorded(quantity)
    lanes = (_gathered.LANES, 3)
    args = _arguments(panda, name, (3,), jnp.float64, False, seed=2)
    traced = jax.jit(_emitted.traced_values, static_argnums=(0, 1, 2))
    eager, _ = _emitted.values(quantity, args, lanes)
    for e, t in zip(eager, traced(rec, lanes, None, *args)):
        np.testing.assert_array_equal(e, t)
    stacked = [jnp.stack([a, 0.5 * a]) for a in args[:2]]
    mapped = jax.vmap(lambda q, qd: _emitted.values(quantity, (q, qd, args[2]), lanes)[0])(*stacked)
    for k in range(2):
        ref = traced(rec, lanes, None, stacked[0][k], stacked[1][k], args[2])
        for m, t in zip(mapped, ref):
            np.testing.assert_allclose(m[k], t, rtol=1e-14, atol=1e-14)
    tangents = [jnp.ones_like(a) for a in args]
    _, dout = jax.jvp(lambda *a: _emitted.values(quantity, a, lanes)[0], tuple(args), tuple(tangents))
    _, dref = jax.jvp(lambda *a: _emitted.traced_values(rec, lanes, None, *a), tuple(args), tuple(tangents))
    for d, r in zip(dout, dref):
        np.testing.assert_allclose(d, r, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("name", ["coriolis_matrix", "regressor", "forward_dynamics"])
def test_parameters_as_constants(panda, name):
    """Given the parameters' values (a call with the defaults), the program reads them as constants and not
    from its last argument; its entries agree with the program that reads them, and, for the gathered form of
    a call without parameters, with one given the default vector, a batch at once and tile by tile."""
    quantity = panda.module.quantities[name]
    lanes = (_gathered.LANES, 3)
    args = _arguments(panda, name, (3,), jnp.float64, False, seed=5)
    constants = tuple(np.asarray(args[-1]).tolist())
    read, _ = jax.jit(lambda *a: _emitted.values(quantity, a, lanes))(*args)
    folded = jax.jit(lambda *a: _emitted.values(quantity, a, lanes, constants)[0])
    for c, r in zip(folded(*args), read):
        np.testing.assert_allclose(c, r, rtol=1e-14, atol=1e-14 * float(jnp.abs(r).max()))
    for c, r in zip(folded(*args[:-1], jnp.zeros_like(args[-1])), read):  # the argument is not read
        np.testing.assert_allclose(c, r, rtol=1e-14, atol=1e-14 * float(jnp.abs(r).max()))
    states = [jnp.moveaxis(a, -1, 0) for a in args[:-1]]
    defaults = getattr(panda, name)(*states)
    given = getattr(panda, name)(*states, params=panda.param_vector())
    np.testing.assert_allclose(defaults, given, rtol=1e-13, atol=1e-13 * float(jnp.abs(given).max()))
    five = [jnp.moveaxis(a, -1, 0) for a in _arguments(panda, name, (5,), jnp.float64, False, seed=6)[:-1]]
    given = getattr(panda, name)(*five, params=panda.param_vector())
    with pytest.MonkeyPatch.context() as mp:  # five states (a shape not traced before) in tiles of two
        mp.setattr(_gathered, "TILE", 2)
        mp.setattr(_gathered, "TILED_BYTES", 0)
        tiled = jax.jit(lambda *s: jax.vmap(panda.mapped(name, defaults=True), in_axes=(0,) * len(s) + (None,))(
            *s, panda.param_vector()))(*five)
    np.testing.assert_allclose(tiled, given, rtol=1e-13, atol=1e-13 * float(jnp.abs(given).max()))
