"""Native kernels of the matrix-valued quantities (jaxskid.runtime._ffi, jaxskid.lowering._ffi).

On CPU, ``dyn.mass_matrix``, ``dyn.coriolis_matrix``, ``dyn.regressor``, the Jacobians, the time
derivatives of M and C and the poses run as generated C behind an XLA FFI handler. Checked here against
Pinocchio's own algorithms on its own URDF parser's models (``crba``, ``computeCoriolisMatrix``,
``computeJointTorqueRegressor``; the Unitree G1 at 29 DOF among them), against the pure-JAX form they
replace, and gradients against central differences; float32, batches with shared and per-state
parameters, the user's own (nested, partly batched) ``vmap``, and the off switch.
"""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import ERD, FINGERS, PANDA, ROBOTS_DIR, pinocchio_urdf_model

import jaxskid
from jaxskid.lowering._ffi_batch import CHUNK
from jaxskid.runtime._ffi import native_quantity

MATRICES = ["mass_matrix", "coriolis_matrix", "regressor", "mass_matrix_dot", "system_jacobian",
            "forward_kinematics"]
G1 = ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf"


def _states(n, batch, count=3, seed=0):
    rng = np.random.default_rng(seed)
    return [jnp.asarray(rng.uniform(-1.5, 1.5, (*batch, n))) for _ in range(count)]


@pytest.fixture(scope="module")
def panda():
    robot = jaxskid.read_urdf(PANDA, lock=FINGERS)
    return robot, jaxskid.lower(robot, quantities=MATRICES)


@pytest.fixture(scope="module")
def arm():
    """The 3-DOF arm of robots/, its M and C: the checks that compile the JAX form's derivatives or map it
    several times, which do not depend on the robot's size."""
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    return robot, jaxskid.lower(robot, quantities=["mass_matrix", "coriolis_matrix"])


def _pure(dyn, name):
    """The pure-JAX form of a quantity of one state (what the native kernel replaces on CPU)."""
    return dyn.generated(name)


def _args(dyn, name, states):
    return states[: len(dyn.signature(name)[0])]


def _array(dyn, out, axis):
    """A quantity's result as one array: the poses of forward_kinematics (a dict) stacked in frame order."""
    return jnp.stack([out[f] for f in dyn.frame_names], axis=axis) if isinstance(out, dict) else out


@pytest.mark.parametrize("name", MATRICES)
def test_native_kernel_equals_the_jax_form(panda, name):
    robot, dyn = panda
    assert dyn.native_target(name) is not None, "a C compiler is required (apt-get install gcc)"
    p = dyn.param_vector()
    args = _args(dyn, name, _states(dyn.n_dof, (9,)))
    got = getattr(dyn, name)(*args)
    got = _array(dyn, got, 1)
    ref = jax.vmap(_pure(dyn, name), in_axes=(*[0] * len(args), None))(*args, p)
    scale = float(jnp.abs(ref).max())
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-13 * scale)
    one = getattr(dyn, name)(*(a[4] for a in args))  # a single state goes through the same kernel
    one = _array(dyn, one, 0)
    np.testing.assert_allclose(one, ref[4], rtol=1e-12, atol=1e-13 * scale)
    # float32 in, float32 out, computed in double
    got32 = getattr(dyn, name)(*(a.astype(jnp.float32) for a in args), p.astype(jnp.float32))
    got32 = _array(dyn, got32, 1)
    assert got32.dtype == jnp.float32
    np.testing.assert_allclose(got32, ref, rtol=2e-5, atol=2e-5 * scale)


def test_against_pinocchio_with_per_state_parameters(panda):
    robot, dyn = panda
    model = pinocchio_urdf_model(PANDA, FINGERS)
    data = model.createData()
    q, qd, qdd = (np.asarray(x) for x in _states(dyn.n_dof, (6,), seed=3))
    m, c = dyn.mass_matrix(q), dyn.coriolis_matrix(q, qd)
    y = dyn.regressor(q, qd, qdd)
    for k in range(len(q)):
        np.testing.assert_allclose(m[k], pin.crba(model, data, q[k]), atol=1e-11)  # crba fills the upper triangle
        np.testing.assert_allclose(c[k], pin.computeCoriolisMatrix(model, data, q[k], qd[k]), atol=1e-11)
        np.testing.assert_allclose(y[k], pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]),
                                   atol=1e-10)
    # per-state parameters: each state's M with its own scaled parameters (M is linear in them)
    scale = jnp.linspace(0.5, 2.0, len(q))[:, None]
    p = dyn.param_vector()[None, :] * scale
    np.testing.assert_allclose(dyn.mass_matrix(q, p), np.asarray(scale)[:, :, None] * np.asarray(m), rtol=1e-12,
                               atol=1e-12)


def test_result_into_an_earlier_result(panda):
    """``out=``: the kernel writes into an earlier result's memory (donated), the values Pinocchio gives."""
    robot, dyn = panda
    model = pinocchio_urdf_model(PANDA, FINGERS)
    data = model.createData()
    q, qd, qdd = _states(dyn.n_dof, (2, 70), seed=5)  # two batch axes, more than one chunk
    first = dyn.regressor(q, qd, qdd)
    address = first.unsafe_buffer_pointer()
    q, qd, qdd = _states(dyn.n_dof, (2, 70), seed=6)
    y = dyn.regressor(q, qd, qdd, out=first)
    assert first.is_deleted() and y.unsafe_buffer_pointer() == address  # the same memory, no fresh result
    for i, k in [(0, 0), (1, 69), (0, 33)]:
        ref = pin.computeJointTorqueRegressor(model, data, *(np.asarray(x[i, k]) for x in (q, qd, qdd)))
        np.testing.assert_allclose(y[i, k], ref, atol=1e-10)
    # one state, float32, parameters given: as without out
    q1 = q[0, 0].astype(jnp.float32)
    p = dyn.param_vector().astype(jnp.float32) * 1.5
    m = dyn.mass_matrix(q1, p, out=jnp.full((dyn.n_dof, dyn.n_dof), jnp.nan, jnp.float32))
    assert m.dtype == jnp.float32
    np.testing.assert_allclose(m, 1.5 * pin.crba(model, data, np.asarray(q[0, 0])), rtol=2e-5, atol=2e-5)


def test_result_into_out_inside_a_trace_and_a_gradient(arm):
    """In the caller's jit (which donates it or not) and under grad, ``out`` changes nothing but memory."""
    robot, dyn = arm
    q = _states(dyn.n_dof, (8,), count=1)[0]
    ref = dyn.mass_matrix(q)
    mine = jax.jit(lambda q, o: dyn.mass_matrix(q, out=o), donate_argnums=1)(q, jnp.zeros_like(ref))
    np.testing.assert_allclose(mine, ref, rtol=1e-14, atol=1e-14)
    p = dyn.param_vector()

    def loss(p, out=None):
        return jnp.sum(dyn.mass_matrix(q, p, out=out) ** 2)

    np.testing.assert_allclose(jax.grad(loss)(p, jnp.zeros_like(ref)), jax.grad(loss)(p), rtol=1e-12)


def test_result_into_out_without_native_kernels(arm, monkeypatch):
    """The JAX form (off CPU, or switched off) takes out's memory by donation alone."""
    robot, dyn = arm
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    off = jaxskid.lower(robot, quantities=["mass_matrix"])
    q = _states(dyn.n_dof, (16,), count=1)[0]
    first = off.mass_matrix(q)
    address = first.unsafe_buffer_pointer()
    m = off.mass_matrix(2 * q, out=first)
    assert first.is_deleted() and m.unsafe_buffer_pointer() == address
    np.testing.assert_allclose(m, dyn.mass_matrix(2 * q), rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("out, expected", [
    (np.zeros((4, 3, 3)), "expected a JAX array"),
    (jnp.zeros((4, 3, 4)), r"expected float64\[4, 3, 3\]"),
    (jnp.zeros((4, 3, 3), jnp.float32), r".*got float32\[4, 3, 3\]"),
])
def test_result_into_the_wrong_out(arm, out, expected):
    robot, dyn = arm
    q = _states(dyn.n_dof, (4,), count=1)[0]
    with pytest.raises(jaxskid.ShapeError, match=r"mass_matrix: out: " + expected):
        dyn.mass_matrix(q, out=out)


def test_result_into_a_deleted_out_or_an_input(arm):
    robot, dyn = arm
    q, qd = _states(dyn.n_dof, (4,), count=2)
    m = dyn.mass_matrix(q)
    dyn.mass_matrix(q, out=m)
    with pytest.raises(jaxskid.ShapeError, match=r"mass_matrix: out: the array was deleted .* pass the array that"):
        dyn.mass_matrix(q, out=m)
    with pytest.raises(jaxskid.ShapeError, match=r"coriolis_matrix: out: the array is also an input"):
        dyn.coriolis_matrix(q, qd, out=qd)


def test_user_vmaps_nested_and_partly_batched(arm):
    robot, dyn = arm
    assert dyn.native_target("coriolis_matrix") is not None
    q, qd = _states(dyn.n_dof, (3, 4), count=2, seed=5)
    p = dyn.param_vector()
    pure = _pure(dyn, "coriolis_matrix")
    ref = jax.vmap(jax.vmap(pure, (0, None, None)), (None, 0, None))(q[:, 0], qd[0], p)  # (4, 3, n, n)
    got = jax.vmap(jax.vmap(dyn.coriolis_matrix, (0, None)), (None, 0))(q[:, 0], qd[0])
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    got = jax.jit(jax.vmap(lambda qq: dyn.coriolis_matrix(qq, qd[0])))(q)  # a batch inside a batch: (3, 4, n, n)
    ref = jax.vmap(lambda qq: jax.vmap(pure, (0, 0, None))(qq, qd[0], p))(q)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)


def test_batches_of_several_chunks_shared_by_the_pool(panda):
    """Batches longer than one chunk (jaxskid.lowering._ffi_batch) are split among XLA's threads: every state,
    the last partial chunk and the last partial group of lanes included, equals the JAX form; with
    parameters shared and per state, and with two batch axes."""
    robot, dyn = panda
    count = 3 * CHUNK + 7
    q, qd = _states(dyn.n_dof, (count,), count=2, seed=11)
    p = dyn.param_vector()
    pure = jax.vmap(_pure(dyn, "coriolis_matrix"), (0, 0, 0))
    scale = jnp.linspace(0.5, 2.0, count)[:, None]
    per_state = p[None, :] * scale
    np.testing.assert_allclose(dyn.coriolis_matrix(q, qd), pure(q, qd, jnp.broadcast_to(p, (count, len(p)))),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dyn.coriolis_matrix(q, qd, per_state), pure(q, qd, per_state), rtol=1e-12, atol=1e-12)
    grid = jax.jit(jax.vmap(jax.vmap(dyn.mass_matrix, (0, None)), (None, 0)))(q, per_state[:5])  # (5, count, n, n)
    ref = jax.vmap(lambda pp: jax.vmap(_pure(dyn, "mass_matrix"), (0, None))(q, pp))(per_state[:5])
    np.testing.assert_allclose(grid, ref, rtol=1e-12, atol=1e-12)


def test_gradients_match_central_differences(arm):
    robot, dyn = arm
    assert dyn.native_target("coriolis_matrix") is not None
    q, qd = (x[0] for x in _states(dyn.n_dof, (1,), count=2, seed=9))
    p = dyn.param_vector()
    w = jnp.asarray(np.random.default_rng(2).normal(size=(dyn.n_dof, dyn.n_dof)))

    def loss(q, qd, p):
        return jnp.sum(w * dyn.coriolis_matrix(q, qd, p)) + jnp.sum(w * dyn.mass_matrix(q, p) ** 2)

    grads = jax.jit(jax.grad(loss, argnums=(0, 1, 2)))(q, qd, p)
    value = jax.jit(loss)  # the differences: one compiled program, called 18 times
    for arg, g in enumerate(grads):
        x = (q, qd, p)[arg]
        for k in (0, len(x) // 2, len(x) - 1):
            h = 1e-6 * max(1.0, abs(float(x[k])))
            e = jnp.zeros_like(x).at[k].set(h)
            plus = [v + e if i == arg else v for i, v in enumerate((q, qd, p))]
            minus = [v - e if i == arg else v for i, v in enumerate((q, qd, p))]
            fd = (float(value(*plus)) - float(value(*minus))) / (2 * h)
            assert abs(float(g[k]) - fd) < 1e-6 * max(1.0, abs(fd)), (arg, k, float(g[k]), fd)


def test_forward_dynamics_from_python_runs_the_native_kernel(monkeypatch):
    """Called from Python without a wrench, forward dynamics runs its C kernel (one call per batch, no XLA
    program of the closed form to compile); inside a caller's trace it is the JAX form, which XLA fuses with
    the caller's program. Both agree, in float64 and float32, on a batch and on a single state."""
    from jaxskid.runtime import _forward

    robot = jaxskid.load(ROBOTS_DIR / "hopping_leg.yaml")
    dyn = jaxskid.lower(robot, quantities=["forward_dynamics"])
    target = dyn.native_target("forward_dynamics")
    assert target is not None
    used = []
    wrap = _forward.native_quantity
    monkeypatch.setattr(_forward, "native_quantity", lambda name, *rest: (used.append(name), wrap(name, *rest))[1])
    q, qd, tau = _states(dyn.n_dof, (9,), seed=8)
    p = dyn.param_vector()
    ref = jax.vmap(dyn.raw("forward_dynamics"), in_axes=(0, 0, 0, None))(q, qd, tau, p)
    scale = float(jnp.abs(ref).max())
    np.testing.assert_allclose(dyn.forward_dynamics(q, qd, tau), ref, rtol=1e-12, atol=1e-13 * scale)
    np.testing.assert_allclose(dyn.forward_dynamics(q[2], qd[2], tau[2]), ref[2], rtol=1e-12, atol=1e-13 * scale)
    got32 = dyn.forward_dynamics(*(x.astype(jnp.float32) for x in (q, qd, tau)), p.astype(jnp.float32))
    assert got32.dtype == jnp.float32
    np.testing.assert_allclose(got32, ref, rtol=1e-4, atol=1e-5 * scale)
    assert used and set(used) == {target}
    used.clear()
    inside = jax.jit(lambda q: dyn.forward_dynamics(q, qd, tau))(q)
    assert not used
    np.testing.assert_allclose(inside, ref, rtol=1e-12, atol=1e-13 * scale)


def test_off_switch(panda, monkeypatch):
    robot, dyn = panda
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    off = jaxskid.lower(robot, quantities=["mass_matrix"])
    assert off.native_target("mass_matrix") is None
    q = _states(dyn.n_dof, (5,), count=1)[0]
    np.testing.assert_allclose(off.mass_matrix(q), dyn.mass_matrix(q), rtol=1e-12, atol=1e-13)


def test_unknown_dtype_takes_the_jax_form(panda):
    robot, dyn = panda
    name = "mass_matrix"
    shape = dyn.signature(name)[1]
    fn = native_quantity(dyn.native_target(name), shape, _pure(dyn, name))
    q = _states(dyn.n_dof, (1,), count=1)[0][0]
    p = dyn.param_vector()
    out = fn(q.astype(jnp.complex128), p.astype(jnp.complex128))  # complex-step users: no C kernel for complex
    np.testing.assert_allclose(out.real, fn(q, p), rtol=1e-12, atol=1e-13)


@pytest.mark.slow
def test_g1_29dof_against_pinocchio():
    """The 29-DOF humanoid: M, C, the regressor (written into an earlier result, ``out=``) and forward dynamics
    of the native kernels against Pinocchio at 1e-9 (relative to the largest acceleration for forward
    dynamics)."""
    robot = jaxskid.read_urdf(G1)
    dyn = jaxskid.lower(robot, quantities=["mass_matrix", "coriolis_matrix", "regressor", "forward_dynamics"])
    for name in ("mass_matrix", "coriolis_matrix", "regressor", "forward_dynamics"):
        assert dyn.native_target(name) is not None
    model = pinocchio_urdf_model(G1)
    data = model.createData()
    assert model.nv == robot.n_dof == 29
    q, qd, qdd = (np.asarray(x) for x in _states(robot.n_dof, (8,), seed=1))
    m, c = dyn.mass_matrix(q), dyn.coriolis_matrix(q, qd)
    y = dyn.regressor(q, qd, qdd, out=dyn.regressor(qd, qdd, q))  # written into another result's memory
    for k in range(len(q)):
        m_ref = pin.crba(model, data, q[k])
        m_ref = np.triu(m_ref) + np.triu(m_ref, 1).T
        np.testing.assert_allclose(m[k], m_ref, rtol=0, atol=1e-9)
        np.testing.assert_allclose(c[k], pin.computeCoriolisMatrix(model, data, q[k], qd[k]), rtol=0, atol=1e-9)
        np.testing.assert_allclose(y[k], pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]),
                                   rtol=0, atol=1e-9)
    tau = 20.0 * qdd
    qdd_ours = dyn.forward_dynamics(q, qd, tau)
    for k in range(len(q)):
        ref = pin.aba(model, data, q[k], qd[k], tau[k])
        np.testing.assert_allclose(qdd_ours[k], ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))


def test_pieces_built_as_several_translation_units(monkeypatch, tmp_path):
    """A kernel long enough to be split into pieces compiles as one translation unit per core
    (``jaxskid.lowering._ffi_build.split``): forced here on the 3-DOF arm (pieces of 20 statements, two parts),
    the split library gives the JAX form's values, for a quantity kernel and for the backward step."""
    from jaxskid.lowering import _ffi, _ffi_build
    from jaxskid.runtime._forward import accelerations

    monkeypatch.setattr(_ffi, "LONG", 30)
    monkeypatch.setattr(_ffi, "CHUNK", 20)
    monkeypatch.setattr(_ffi_build, "_cores", lambda: 2)
    units = []
    compile_all = _ffi_build._compile_all

    def record(commands, tmp, *rest):  # this test's builds (an earlier test's may still run in the background)
        if tmp_path in tmp.parents:
            units.append(len(commands))
        return compile_all(commands, tmp, *rest)

    monkeypatch.setattr(_ffi_build, "_compile_all", record)
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    dyn = jaxskid.lower(robot, quantities=["coriolis_matrix", "forward_dynamics"], cache_dir=tmp_path)
    p = dyn.param_vector()
    q, qd, tau = _states(dyn.n_dof, (9,), seed=4)
    got = dyn.coriolis_matrix(q, qd)
    assert units[:2] == [2, 1]  # two translation units, then the link (then the backward step's library)
    ref = jax.vmap(_pure(dyn, "coriolis_matrix"), in_axes=(0, 0, None))(q, qd, p)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-13 * float(jnp.abs(ref).max()))

    def loss(p, autodiff):
        fd = jax.vmap(accelerations(dyn, autodiff=autodiff), in_axes=(0, 0, 0, None))
        return jnp.sum(jnp.sin(fd(q, qd, tau, p)))

    native = jax.grad(loss)(p, "reverse")  # the backward kernel of the split library
    np.testing.assert_allclose(native, jax.grad(loss)(p, "forward"), rtol=1e-9, atol=1e-12)


def test_split_glue_defines_each_piece_once():
    """Each piece is defined in exactly one part, declared in the others, and only part 0 has handlers (the
    templates guard them)."""
    from jaxskid.lowering._ffi import QUANTITY, Piece
    from jaxskid.lowering._ffi_build import split

    pieces = [Piece(f"f_{k}", "const V *q, V *w", f"{{\n    w[{k}] = q[{k}];\n}}\n") for k in range(3)]
    glue = [pieces[0], "\n", pieces[1], "\n", pieces[2], QUANTITY]
    text, parts = split(glue, 2)
    assert parts == 2
    assert split(glue, 1) == ("".join(p.text() if isinstance(p, Piece) else p for p in glue), 1)
    for name in ("f_0", "f_1", "f_2"):
        assert text.count(f"PIECE void {name}(const V *q, V *w)\n{{") == 1
        assert text.count(f"PIECE void {name}(const V *q, V *w);") == 1
    handler = text.index("XLA_FFI_Error *jaxskid_@NAME@(")
    assert text.rfind("#if JAXSKID_PART == 0", 0, handler) > text.rfind("#endif", 0, handler)


def test_no_c_where_native_kernels_are_off(monkeypatch, tmp_path):
    """With native kernels off no C is printed, and the module cached then does not serve a process that has
    them: the two are cached apart."""
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    off = jaxskid.lower(robot, quantities=["mass_matrix"], cache_dir=tmp_path)
    assert off.module.native == () and "NATIVE_C" not in off.source
    monkeypatch.delenv("JAXSKID_NATIVE")
    on = jaxskid.lower(robot, quantities=["mass_matrix"], cache_dir=tmp_path)
    assert on.module.native and on.path != off.path
    assert on.native_target("mass_matrix") is not None
    q = _states(on.n_dof, (4,), count=1)[0]
    np.testing.assert_allclose(off.mass_matrix(q), on.mass_matrix(q), rtol=1e-13, atol=1e-14)


def test_the_switch_is_read_when_a_dynamics_is_made(monkeypatch):
    """JAXSKID_NATIVE is read when a Dynamics is made and kept for its life: turned off at the first use of one
    made before, it changes nothing there, and one made while it was off stays without kernels."""
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    on = jaxskid.lower(robot, quantities=["mass_matrix"])
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    off = jaxskid.lower(robot, quantities=["mass_matrix"])
    assert on.native_target("mass_matrix") is not None
    assert off.native_target("mass_matrix") is None
    monkeypatch.delenv("JAXSKID_NATIVE")
    assert off.native_target("mass_matrix") is None


_CHUNKED = """
from jaxskid._generated import Statement, VectorKernel
from jaxskid.lowering._ffi import LONG, _chunked
lines = [Statement("input", f"a{k}", f"x[{k}]", ()) for k in range(40)]
lines += [Statement("define", f"b{k}", f"a{k % 40} * a{(7 * k) % 40} + {k}.0", tuple(sorted({f"a{k % 40}", f"a{(7 * k) % 40}"})))
          for k in range(LONG + 200)]
lines += [Statement("output", str(k), f"b{k} + a{(3 * k) % 40}", tuple(sorted({f"b{k}", f"a{(3 * k) % 40}"})))
          for k in range(LONG + 200)]
import hashlib
pieces = _chunked("f", VectorKernel(("x",), tuple(lines), ()), "double")
source = "".join(p if isinstance(p, str) else p.text() for p in pieces)
print(hashlib.sha256(source.encode()).hexdigest())
"""


def test_split_kernel_source_is_the_same_in_every_process():
    """The pieces of a long kernel read the input entries they need in one order, whatever the process's
    string hashes: the source is part of the native library's key, so another order builds it again."""
    digests = {subprocess.run([sys.executable, "-c", _CHUNKED], check=True, capture_output=True, text=True,
                              env={**os.environ, "PYTHONHASHSEED": str(seed)}).stdout for seed in (1, 2, 3)}
    assert len(digests) == 1


def test_a_build_for_derivatives_alone_runs_at_low_priority(monkeypatch, tmp_path):
    """Forward dynamics brings M and the vector-Jacobian product of inverse dynamics for its derivatives:
    their library (M's kernel and the backward step) is compiled at a low priority, since it serves later
    calls, and still builds; the library of the requested quantity comes first, at the normal priority."""
    from jaxskid.lowering import _ffi_build

    builds = []
    compile_all = _ffi_build._compile_all

    def record(commands, tmp, nice=0):
        if tmp_path in tmp.parents:  # this test's builds (an earlier test's may still run in the background)
            glue = (tmp / "glue.c").read_text()
            handlers = tuple(h for h in ("fd_vjp", "forward_dynamics", "mass_matrix") if f"*jaxskid_{h}(" in glue)
            builds.append((handlers, nice))
        return compile_all(commands, tmp, nice)

    monkeypatch.setattr(_ffi_build, "_compile_all", record)
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    dyn = jaxskid.lower(robot, quantities=["forward_dynamics"], cache_dir=tmp_path)
    for name in ("fd_vjp", "forward_dynamics", "mass_matrix"):
        assert dyn.native_target(name) is not None
    assert builds == [(("forward_dynamics",), 0), (("fd_vjp", "mass_matrix"), _ffi_build._LATER)]
