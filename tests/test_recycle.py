"""Large results take the memory of earlier ones that nothing references (jaxskid.runtime._recycle).

The pool itself (what it takes and what it leaves), then calls of the Panda's mass matrix and regressor, in the
JAX form and as native kernels, with the size from which results are recycled lowered to zero: the values
against Pinocchio's ``crba`` and ``computeJointTorqueRegressor``, an array the caller holds (directly or through
a NumPy view) never overwritten, nothing recycled inside a caller's ``jit`` or with ``JAXSKID_RECYCLE=0``.
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import FINGERS, PANDA, pinocchio_urdf_model

import jaxskid
from jaxskid.runtime import _recycle

CPU = jax.devices("cpu")[0]


def test_the_pool_takes_only_what_nothing_else_references():
    pool = _recycle.Recycler()
    a = jnp.arange(6.0).reshape(2, 3)
    pool.keep(a)
    assert pool.take((2, 3), a.dtype, CPU) is None  # held by `a`
    pointer = a.unsafe_buffer_pointer()
    del a
    assert pool.take((3, 2), jnp.float64, CPU) is None  # another shape
    taken = pool.take((2, 3), jnp.float64, CPU)
    assert taken is not None and taken.unsafe_buffer_pointer() == pointer and len(pool) == 0
    b = jnp.ones((2, 3))
    pool.keep(b)
    view = np.asarray(b)
    del b
    assert pool.take((2, 3), jnp.float64, CPU) is None  # a NumPy view holds its memory
    del view
    assert pool.take((2, 3), jnp.float64, CPU) is not None
    for _ in range(5):
        pool.keep(jnp.zeros(3))
    assert len(pool) == _recycle.KEPT
    fresh = pool.out((4,), jnp.dtype(jnp.float32), CPU)
    assert fresh.shape == (4,) and fresh.dtype == jnp.float32


def test_which_calls_are_recycled(monkeypatch):
    """Real arrays of one floating dtype on the CPU, from MIN_BYTES to MAX_BYTES; the batch broadcast over the
    arguments."""
    q32, q64 = np.zeros((8, 7), np.float32), jnp.zeros((8, 7))
    params = (None, (70,))
    assert _recycle.recycled_result([q64], [(7,)], params, (7, 7)) is None  # 3 kB
    monkeypatch.setattr(_recycle, "MIN_BYTES", 0)
    assert _recycle.recycled_result([q64], [(7,)], params, (7, 7)) == ((8, 7, 7), jnp.float64, CPU)
    assert _recycle.recycled_result([q32, q32[:1]], [(7,), (7,)], params, (7,)) == ((8, 7), jnp.float32, CPU)
    assert _recycle.recycled_result([q64], [(7,)], (jnp.zeros((3, 1, 70)), (70,)), (2,)) == ((3, 8, 2),
                                                                                              jnp.float64, CPU)
    for states, cores in (([q64.astype(jnp.complex128)], [(7,)]), ([q32, q64], [(7,), (7,)]), ([1.0], [()])):
        assert _recycle.recycled_result(states, cores, params, (7, 7)) is None
    assert _recycle.recycled_result([q64], [(7,)], (jnp.zeros(70, jnp.complex64), (70,)), (7,)) is None
    assert _recycle.recycled_result([q64, q64[:3]], [(7,), (7,)], params, (7,)) is None  # the call's error
    monkeypatch.setattr(_recycle, "MAX_BYTES", 8 * 7 * 7 * 8 - 1)
    assert _recycle.recycled_result([q64], [(7,)], params, (7, 7)) is None  # one byte too many
    monkeypatch.setenv(_recycle.VARIABLE, "0")
    assert _recycle.recycled_result([q64], [(7,)], params, (7, 7)) is None


@pytest.fixture(params=["jax", "native"], scope="module")
def panda(request):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JAXSKID_NATIVE", "0" if request.param == "jax" else "1")
        dyn = jaxskid.lower(jaxskid.read_urdf(PANDA, lock=FINGERS), quantities=["mass_matrix", "regressor"])
    return dyn, pinocchio_urdf_model(PANDA, FINGERS)


def _taken(monkeypatch) -> list:
    """What each call's pool gave: True for an earlier result, False for a new array."""
    given, take = [], _recycle.Recycler.take

    def spy(self, *args):
        kept = take(self, *args)
        given.append(kept is not None)
        return kept

    monkeypatch.setattr(_recycle.Recycler, "take", spy)
    monkeypatch.setattr(_recycle, "MIN_BYTES", 0)
    return given


def _crba(model, q):
    m = pin.crba(model, model.createData(), np.asarray(q))
    return np.triu(m) + np.triu(m, 1).T


def test_a_dropped_result_gives_its_memory_and_a_held_one_is_kept(monkeypatch, panda):
    dyn, model = panda
    given = _taken(monkeypatch)
    q = np.random.default_rng(0).uniform(-1.5, 1.5, (6, 16, 7))
    first = dyn.mass_matrix(q[0])
    pointer = first.unsafe_buffer_pointer()
    del first
    second = dyn.mass_matrix(q[1])
    assert given == [False, True] and second.unsafe_buffer_pointer() == pointer
    held = [second, dyn.mass_matrix(q[2])]
    view = np.asarray(dyn.mass_matrix(q[3]))  # only a NumPy view holds this one
    for k in (4, 5):
        held.append(dyn.mass_matrix(q[k]))
    assert given == [False, True, False, False, False, False]
    for k, m in zip((1, 2, 4, 5), held):
        assert not m.is_deleted()
        np.testing.assert_allclose(m, np.stack([_crba(model, x) for x in q[k]]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(view, np.stack([_crba(model, x) for x in q[3]]), rtol=1e-12, atol=1e-12)


def test_a_loop_reuses_the_result_before_last(monkeypatch, panda):
    """``Y = f(q)`` in a loop: from the third call on, each takes the result of two calls before."""
    dyn, model = panda
    given = _taken(monkeypatch)
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, qd, qdd = rng.uniform(-1.5, 1.5, (3, 9, 7))
        y = dyn.regressor(q, qd, qdd)
    assert given == [False, False, True, True, True]
    data = model.createData()
    for k in range(9):
        np.testing.assert_allclose(y[k], pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]),
                                   rtol=1e-10, atol=1e-10)


def test_nothing_is_recycled_inside_a_trace_or_when_turned_off(monkeypatch, panda):
    dyn, model = panda
    given = _taken(monkeypatch)
    q = np.random.default_rng(2).uniform(-1.5, 1.5, (4, 7))
    traced = jax.jit(dyn.mass_matrix)(q)
    monkeypatch.setenv(_recycle.VARIABLE, "0")
    off = dyn.mass_matrix(q)
    assert given == []
    for m in (traced, off):
        np.testing.assert_allclose(m, np.stack([_crba(model, x) for x in q]), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("native", ["0", "1"])
def test_every_quantity_recycles_to_the_same_values(monkeypatch, native):
    """Each quantity of the 3-DOF arm of robots/ (its end-effector's wrenches, the pullbacks' cotangents), with
    every result recycled, called three times on other states: the values of calls with recycling off, and no
    warning (a donated buffer XLA could not use would warn); every quantity but two takes an earlier result."""
    from helpers import ROBOTS_DIR

    monkeypatch.setenv("JAXSKID_NATIVE", native)
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    names = [n for n, spec in jaxskid.QUANTITIES.items() if not spec.needs_constraints]
    dyn = jaxskid.lower(robot, quantities=names)
    given, unpooled = _taken(monkeypatch), set()
    rng = np.random.default_rng(5)
    for name in names:
        fn, args = getattr(dyn, name), dyn.signature(name)[0]
        calls = [[rng.uniform(-1, 1, (5, *dyn.argument_shape(a))) for a in args] for _ in range(3)]
        with monkeypatch.context() as off:
            off.setenv(_recycle.VARIABLE, "0")
            expected = [np.asarray(jax.tree_util.tree_leaves(fn(*c))[0]) for c in calls]
        del given[:]
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            for c, e in zip(calls, expected):
                got = jax.tree_util.tree_leaves(fn(*c))[0]
                np.testing.assert_array_equal(got, e, err_msg=name)
                del got
        unpooled.update({name} if not given else set())
        assert given in ([], [False, True, True]), name
    # the poses are a dict of arrays; forward dynamics is a method of its own (a vector: large only for a batch
    # of millions)
    assert unpooled == {"forward_kinematics", "forward_dynamics"}
