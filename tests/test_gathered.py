"""The gathered form of the matrix-valued quantities (jaxskid.runtime._gathered): the JAX form's batches on CPU.

With native kernels off, a batch of M, C, the regressor or Ṁ is computed by the gathered form. Checked here
against the generated function it replaces (the select-chain form, mapped with ``jax.vmap``) and against
Pinocchio's algorithms on its own URDF parser's models (``crba``, ``computeCoriolisMatrix``,
``computeJointTorqueRegressor``, and ``C + C^T`` for Ṁ), on the Panda and solo12, and M and the regressor on
(slow) the G1; gradients with respect to the parameters and the state against central differences (the 3-DOF
arm of robots/); float32, complex inputs, several reduces (small chunks), the padded batch and the tiled one.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import ERD, FINGERS, PANDA, ROBOTS_DIR, pinocchio_urdf_model

import jaxskid
from jaxskid.runtime import _gathered

MATRICES = ["mass_matrix", "coriolis_matrix", "regressor", "mass_matrix_dot"]
SOLO = ERD / "solo_description/robots/solo12.urdf"
G1 = ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf"


def _lowered(path, lock=None, names=MATRICES):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JAXSKID_NATIVE", "0")
        robot = jaxskid.read_urdf(path, lock=lock)
        dyn = jaxskid.lower(robot, quantities=names)
    for name in names:
        assert dyn.native_target(name) is None
    return dyn, pinocchio_urdf_model(path, lock)


@pytest.fixture(scope="module")
def panda():
    return _lowered(PANDA, FINGERS)


@pytest.fixture(scope="module")
def arm():
    """The 3-DOF arm of robots/: the gradient checks, which compile the program's derivatives and do not depend
    on the robot's size."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JAXSKID_NATIVE", "0")
        return jaxskid.lower(jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml"), quantities=MATRICES)


@pytest.fixture(scope="module")
def solo():
    return _lowered(SOLO)


def _states(n, batch, seed=0):
    rng = np.random.default_rng(seed)
    return [jnp.asarray(rng.uniform(-1.5, 1.5, (*batch, n))) for _ in range(3)]


def _select_chains(dyn, name, states):
    """The generated function (the form the gathered one replaces), mapped over a flat batch."""
    args = states[: len(dyn.signature(name)[0])]
    return jax.vmap(dyn.generated(name), in_axes=(*[0] * len(args), None))(*args, dyn.param_vector())


def _pinocchio(model, name, q, qd, qdd):
    data = model.createData()
    if name == "mass_matrix":
        m = pin.crba(model, data, q)
        return np.triu(m) + np.triu(m, 1).T
    if name == "regressor":
        return pin.computeJointTorqueRegressor(model, data, q, qd, qdd)
    c = pin.computeCoriolisMatrix(model, data, q, qd)
    return c if name == "coriolis_matrix" else c + c.T  # dM/dt = C + C^T


def _against_references(dyn, model, batch=(3, 5)):
    q, qd, qdd = _states(dyn.n_dof, batch, seed=1)
    flat = [x.reshape(-1, dyn.n_dof) for x in (q, qd, qdd)]
    for name in [m for m in MATRICES if m in dyn.quantities]:
        got = getattr(dyn, name)(*(q, qd, qdd)[: len(dyn.signature(name)[0])])
        assert got.shape == (*batch, *dyn.signature(name)[1])
        got = got.reshape(-1, *got.shape[len(batch):])
        chains = _select_chains(dyn, name, flat)
        np.testing.assert_allclose(got, chains, rtol=1e-12, atol=1e-12 * float(jnp.abs(chains).max()))
        for k in range(len(got)):
            ref = _pinocchio(model, name, *(np.asarray(x[k]) for x in flat))
            np.testing.assert_allclose(got[k], ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))


def test_panda_against_pinocchio_and_the_select_chains(panda):
    _against_references(*panda)


def test_solo12_against_pinocchio_and_the_select_chains(solo):
    _against_references(*solo)


@pytest.mark.slow
def test_g1_against_pinocchio_and_the_select_chains(monkeypatch):
    """M and the regressor (its 1,362 distinct entries in eleven reduces: the table built chunk by chunk),
    computed a tile at a time as a large batch is (here seven states in tiles of three, the last overlapping the
    one before); C and Ṁ, whose programs XLA compiles for far longer at this size, are checked on the Panda and
    solo12."""
    monkeypatch.setattr(_gathered, "TILE", 3)
    monkeypatch.setattr(_gathered, "TILED_BYTES", 0)
    dyn, model = _lowered(G1, names=["mass_matrix", "regressor"])
    assert dyn.n_dof == 29
    _against_references(dyn, model, batch=(7,))


@pytest.mark.parametrize("name", MATRICES)
def test_gradients_against_central_differences(arm, name):
    """jax.grad of a weighted sum of the batch, with respect to the parameters and to q."""
    dyn = arm
    states = _states(dyn.n_dof, (6,), seed=2)
    args = states[: len(dyn.signature(name)[0])]
    weights = jnp.asarray(np.random.default_rng(3).normal(size=(6, *dyn.signature(name)[1])))
    p = dyn.param_vector()

    def loss(q, p):
        return jnp.sum(weights * getattr(dyn, name)(q, *args[1:], params=p))

    gq, gp = jax.grad(loss, argnums=(0, 1))(args[0], p)
    rng = np.random.default_rng(4)
    for x, g, arg in ((args[0], gq, 0), (p, gp, 1)):
        direction = jnp.asarray(rng.normal(size=x.shape))
        h = 1e-6 * float(jnp.abs(x).max())
        shifted = [(args[0], p), (args[0], p)]
        shifted[0] = tuple(v + h * direction if i == arg else v for i, v in enumerate(shifted[0]))
        shifted[1] = tuple(v - h * direction if i == arg else v for i, v in enumerate(shifted[1]))
        central = (loss(*shifted[0]) - loss(*shifted[1])) / (2 * h)
        exact = jnp.sum(g * direction)
        assert abs(float(exact - central)) <= 1e-7 * max(1.0, abs(float(central)))


def test_float32_and_complex_inputs(panda):
    dyn, _ = panda
    q, qd, _ = _states(dyn.n_dof, (5,), seed=5)
    ref = dyn.coriolis_matrix(q, qd)
    single = dyn.coriolis_matrix(q.astype(jnp.float32), qd.astype(jnp.float32))
    assert single.dtype == jnp.float32
    np.testing.assert_allclose(single, ref, rtol=1e-4, atol=1e-5 * float(jnp.abs(ref).max()))
    # complex inputs (max has no order on complex numbers: the select chains serve them)
    form = jax.vmap(_gathered.gathered(dyn.module.quantities["mass_matrix"]), in_axes=(0, None))
    p = dyn.param_vector()
    m = form(q.astype(jnp.complex128), p.astype(jnp.complex128))
    assert m.dtype == jnp.complex128
    np.testing.assert_allclose(m.real, dyn.mass_matrix(q), rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("staged", [1000, 1])
def test_several_reduces(monkeypatch, staged):
    """Outputs split over reduces of a few entries each (CHUNK, for the largest results) give the same result (to
    rounding: XLA contracts multiply-adds differently in other kernels), with the table stacked at once and built
    chunk by chunk (STAGED)."""
    dyn, _ = _lowered(PANDA, FINGERS)
    q, qd, qdd = _states(dyn.n_dof, (4,), seed=7)
    whole = dyn.regressor(q, qd, qdd)
    monkeypatch.setattr(_gathered, "CHUNK", 7)
    monkeypatch.setattr(_gathered, "STAGED", staged)
    chunked, _ = _lowered(PANDA, FINGERS)  # a new Dynamics traces its functions again
    np.testing.assert_allclose(chunked.regressor(q, qd, qdd), whole, rtol=1e-13, atol=1e-13 * float(jnp.abs(whole).max()))
    one = chunked.regressor(q[0], qd[0], qdd[0])
    np.testing.assert_allclose(one, whole[0], rtol=1e-13, atol=1e-13 * float(jnp.abs(whole).max()))


def test_padded_batch():
    """A row of a padded batch spans an odd number of cache lines; small batches and odd ones stay, and so do
    batches of large results (computed a tile at a time), whose tile spans an odd number."""
    assert _gathered.padded_batch(256, jnp.float64) == 264
    assert _gathered.padded_batch(256, jnp.float32) == 272
    assert _gathered.padded_batch(160, jnp.float64) == 168  # 20 lines -> 21
    assert _gathered.padded_batch(168, jnp.float64) == 168
    assert _gathered.padded_batch(40, jnp.float64) == 40
    assert _gathered.padded_batch(4096, jnp.float64) == 4104
    assert _gathered.padded_batch(4096, jnp.float64, (29, 290)) == 4096  # 276 MB: a tile at a time
    assert _gathered.tiled(4096, jnp.float64, (29, 290)) and not _gathered.tiled(4096, jnp.float64, (12, 12))
    assert -(-_gathered.TILE * 8 // 64) % 2 == 1
    for size in (64, 100, 200, 256):
        for dtype in (jnp.float32, jnp.float64):
            padded = _gathered.padded_batch(size, dtype)
            lines = -(-padded * jnp.dtype(dtype).itemsize // 64)
            assert padded >= size and lines % 2 == 1


@pytest.mark.parametrize("tile", [5, 16])
def test_tiled_batch(monkeypatch, tile):
    """A batch of large results (here of any size), computed a tile at a time with the last tile overlapping the
    one before (23 states in tiles of 5: the last starts at state 18; of 16: at 7), equals the select chains; so
    does a batch with two batch axes, and one whose parameters carry the batch too."""
    monkeypatch.setattr(_gathered, "TILE", tile)
    monkeypatch.setattr(_gathered, "TILED_BYTES", 0)
    dyn, _ = _lowered(PANDA, FINGERS, names=["mass_matrix", "coriolis_matrix"])
    q, qd, _ = _states(dyn.n_dof, (23,), seed=11)
    for name, args in (("mass_matrix", [q]), ("coriolis_matrix", [q, qd])):
        got = getattr(dyn, name)(*args)
        np.testing.assert_allclose(got, _select_chains(dyn, name, args), rtol=1e-12, atol=1e-13)
    q2 = _states(dyn.n_dof, (3, 7), seed=12)[0]
    np.testing.assert_allclose(dyn.mass_matrix(q2).reshape(21, dyn.n_dof, dyn.n_dof),
                               _select_chains(dyn, "mass_matrix", [q2.reshape(21, dyn.n_dof)]), rtol=1e-12, atol=1e-13)
    p = dyn.param_vector()[None, :] * (1 + 0.1 * np.random.default_rng(13).uniform(size=(23, 1)))
    chains = jax.vmap(dyn.generated("mass_matrix"), in_axes=(0, 0))(q, p)
    np.testing.assert_allclose(dyn.mass_matrix(q, params=p), chains, rtol=1e-12, atol=1e-13)


def test_a_padded_batch_gives_each_state_its_own_result(panda):
    """A batch of 64 states is computed as 72 (the inputs padded with the last state) and sliced back."""
    dyn, _ = panda
    assert _gathered.padded_batch(64, jnp.float64) == 72
    q = _states(dyn.n_dof, (64,), seed=8)[0]
    got = dyn.mass_matrix(q)
    assert got.shape == (64, dyn.n_dof, dyn.n_dof)
    np.testing.assert_allclose(got, _select_chains(dyn, "mass_matrix", [q]), rtol=1e-12, atol=1e-13)


def test_one_state_outside_vmap_runs_on_the_host(panda):
    """The gathered function called on one state, outside ``jax.vmap`` (the runtime maps it always): its host
    callback gives the generated function's result, plainly and under ``jax.jit``."""
    dyn, model = panda
    q, qd, _ = (x[0] for x in _states(dyn.n_dof, (1,), seed=5))
    fn = _gathered.gathered(dyn.module.quantities["coriolis_matrix"])
    p = dyn.param_vector()
    want = dyn.generated("coriolis_matrix")(q, qd, p)
    np.testing.assert_allclose(fn(q, qd, p), want, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(jax.jit(fn)(q, qd, p), want, rtol=1e-13, atol=1e-13)
    ref = _pinocchio(model, "coriolis_matrix", np.asarray(q), np.asarray(qd), None)
    np.testing.assert_allclose(fn(q, qd, p), ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))


def test_a_batch_traces_the_program_once(panda):
    """Mapped, the program is traced for the rule alone (not also for the unmapped function, which JAX traces
    for its result's shape)."""
    dyn, _ = panda
    quantity = dyn.module.quantities["mass_matrix"]
    calls = []
    program = quantity.program

    def counted(*args, **kwargs):
        calls.append(kwargs.get("entries", False))
        return program(*args, **kwargs)

    q = _states(dyn.n_dof, (4,), seed=6)[0]
    fn = _gathered.gathered(dataclasses.replace(quantity, program=counted))
    jax.jit(jax.vmap(fn, in_axes=(0, None))).lower(q, dyn.param_vector())
    assert calls == [True]


def test_vectors_against_pinocchio_and_the_select_chains():
    """solo12's inverse and forward dynamics (12 entries: their batches run in the gathered form too) against
    ``rnea`` and ``aba`` and against the generated functions mapped with ``jax.vmap``."""
    dyn, model = _lowered(SOLO, names=["inverse_dynamics", "forward_dynamics"])
    assert dyn.mapped("inverse_dynamics") is not dyn.generated("inverse_dynamics")
    q, qd, qdd = _states(dyn.n_dof, (3, 5), seed=8)
    flat = [np.asarray(x).reshape(-1, dyn.n_dof) for x in (q, qd, qdd)]
    data = model.createData()
    tau = dyn.inverse_dynamics(q, qd, qdd).reshape(-1, dyn.n_dof)
    acc = dyn.forward_dynamics(q, qd, qdd).reshape(-1, dyn.n_dof)  # qdd's values as torques
    for got, name in ((tau, "inverse_dynamics"), (acc, "forward_dynamics")):
        chains = _select_chains(dyn, name, [jnp.asarray(x) for x in flat])
        np.testing.assert_allclose(got, chains, rtol=1e-12, atol=1e-12 * float(jnp.abs(chains).max()))
    for k in range(len(flat[0])):
        ref_tau = pin.rnea(model, data, *(x[k] for x in flat))
        np.testing.assert_allclose(tau[k], ref_tau, rtol=0, atol=1e-9 * max(1.0, np.abs(ref_tau).max()))
        ref_acc = pin.aba(model, data, *(x[k] for x in flat))
        np.testing.assert_allclose(acc[k], ref_acc, rtol=0, atol=1e-9 * max(1.0, np.abs(ref_acc).max()))


def test_vector_gradients_against_central_differences():
    """jax.grad of a weighted sum of solo12's batched inverse dynamics (the gathered form), with respect to the
    parameters and to q, against central differences."""
    dyn, _ = _lowered(SOLO, names=["inverse_dynamics"])
    q, qd, qdd = _states(dyn.n_dof, (4,), seed=9)
    weights = jnp.asarray(np.random.default_rng(10).normal(size=(4, dyn.n_dof)))
    p = dyn.param_vector()

    def loss(q, p):
        return jnp.sum(weights * dyn.inverse_dynamics(q, qd, qdd, params=p))

    grads = jax.grad(loss, argnums=(0, 1))(q, p)
    rng = np.random.default_rng(11)
    for arg, (x, g) in enumerate(zip((q, p), grads)):
        direction = jnp.asarray(rng.normal(size=x.shape))
        h = 1e-6 * float(jnp.abs(x).max())
        up = [q, p]
        down = [q, p]
        up[arg], down[arg] = x + h * direction, x - h * direction
        central = (loss(*up) - loss(*down)) / (2 * h)
        assert abs(float(jnp.sum(g * direction) - central)) <= 1e-7 * max(1.0, abs(float(central)))
