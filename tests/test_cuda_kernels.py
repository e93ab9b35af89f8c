"""The CUDA kernels of the matrix-valued quantities (jaxskid/lowering/_cuda.py), where no GPU is: their source
compiles with NVRTC (to PTX, for float64 and float32 inputs), the XLA FFI handler that launches them builds,
and the same source built as C for the host computes what the JAX form computes, at 1e-12, over batches with
two axes and parameters shared by all states (the indexing each GPU thread does)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import ERD, ROBOTS_DIR, load
from jaxskid._generated import by_entry
from jaxskid.lowering import _cuda

QUANTITIES = ["mass_matrix", "coriolis_matrix", "regressor", "forward_dynamics", "mass_matrix_dot", "inverse_dynamics",
              "gravity_torques"]
G1 = ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf"


def _kernels(dyn):
    """``{quantity: (native source, its kernel entry)}`` for every quantity of ``dyn`` with a CUDA kernel."""
    found = {}
    for build in {id(b): b for b in dyn._native_build.values()}.values():
        for entry in build.sources.kernels:
            if _cuda.kernel_source(build.sources, entry[0]) is not None:
                found[entry[0]] = (build.sources, entry)
    return found


def _check(dyn, names, tmp_path, rng, io=("float64", "float32"), spread=1.0, shared=(True, False)):
    """Each quantity of ``names``: its kernel compiles to PTX for each dtype of ``io``, and built for the host it
    agrees at 1e-12 with the JAX form, at states drawn from [-spread, spread]. Each kernel of ``shared``: the
    parameters read from constant memory (True: the handler's copy is the host's, into ``jaxskid_p``), or from
    their input, shared by every state (the input's step is 0)."""
    kernels = _kernels(dyn)
    assert set(names) <= set(kernels)
    p = np.asarray(dyn.param_vector())
    for name in names:
        sources, (_, sizes, cores, n_out, out_rank) = kernels[name]
        args, shape = dyn.signature(name)
        for dtype in io:
            ptx = _cuda.compile_kernel(_cuda.kernel_source(sources, name, dtype), "compute_90").decode()
            assert ".entry jaxskid_kernel" in ptx and ".f64" in ptx
            assert (".const .align" in ptx and " jaxskid_p[" in ptx) == (True in shared)
        # a batch of (2, 3): q varies along both axes, the other state arguments along the second only
        states = [spread * rng.uniform(-1, 1, (2, 3, dyn.argument_shape(a)[0]) if k == 0
                                       else (3, dyn.argument_shape(a)[0])) for k, a in enumerate(args)]
        inner = jax.vmap(dyn.raw(name), in_axes=(*[0] * len(args), None))
        reference_of = jax.vmap(inner, in_axes=(0, *[None] * (len(args) - 1), None))
        want = np.asarray(reference_of(*(jnp.asarray(x) for x in states), jnp.asarray(p)))
        for constant in shared:
            host = _cuda.host_library(_cuda.kernel_source(sources, name, shared=constant), tmp_path)
            out = np.full((2, 3, *shape), np.nan)
            _cuda.run_on_host(host, [*states, p], cores, out, out_rank, len(sizes) - 1 if constant else -1,
                              by_entry(n_out))
            np.testing.assert_allclose(out, want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()),
                                       err_msg=f"{name}, parameters in constant memory: {constant}")


def test_thread_order():
    """:func:`_cuda.thread_order` reads each input just before its first use and writes each output just after
    the last value it reads, and keeps every statement once."""
    from jaxskid._generated import Statement, VectorKernel

    kernel = VectorKernel(("q", "p"), (
        Statement("input", "_q0", "q[0]", ()), Statement("input", "_q1", "q[1]", ()),
        Statement("input", "_p0", "p[0]", ()), Statement("define", "_x0", "_q0*_p0", ("_q0", "_p0")),
        Statement("define", "_x1", "_x0*_q1", ("_x0", "_q1")), Statement("output", "0", "_x0", ("_x0",)),
        Statement("output", "1", "_x1", ("_x1",)), Statement("output", "2", "_p0", ("_p0",))), ())
    order = [s.name for s in _cuda.thread_order(kernel).statements]
    assert order == ["_p0", "2", "_q0", "_x0", "0", "_q1", "_x1", "1"]
    constant = _cuda.constant_parameters(kernel)
    assert [s.value for s in constant.statements[:3]] == ["q[0]", "q[1]", "jaxskid_p[0]"]


def test_program_order_and_parameters_from_their_input(monkeypatch, tmp_path):
    """JAXSKID_CUDA_ORDER=program (the program's own order, every input read first) and JAXSKID_CUDA_CONSTANT=0
    (the parameters always from their input) build kernels that agree too."""
    monkeypatch.setenv("JAXSKID_CUDA_ORDER", "program")
    monkeypatch.setenv("JAXSKID_CUDA_CONSTANT", "0")
    names = ["mass_matrix", "forward_dynamics"]
    dyn = jaxskid.lower(load("panda7"), QUANTITIES)
    source = _cuda.kernel_source(_kernels(dyn)["mass_matrix"][0], "mass_matrix")
    assert "jaxskid_p" not in source and "__restrict__" not in source
    _check(dyn, names, tmp_path, np.random.default_rng(7), io=("float64",), shared=(False,))


def test_handler_builds(tmp_path):
    """The handler's library builds against jaxlib's FFI header and exports the handler and the registration."""
    import ctypes

    lib = ctypes.CDLL(str(_cuda.handler_library(tmp_path)))
    assert lib.jaxskid_cuda_quantity and lib.jaxskid_cuda_register


def test_panda(tmp_path):
    dyn = jaxskid.lower(load("panda7"), QUANTITIES)
    _check(dyn, QUANTITIES, tmp_path, np.random.default_rng(0))


def test_solo12_floating_base(tmp_path):
    """solo12 on a free-flyer base: a configuration of 7 + n entries, velocities of 6 + n (the lowering of
    test_pullbacks' solo12, so a run derives it once)."""
    names = ["mass_matrix", "inverse_dynamics"]
    dyn = jaxskid.lower(jaxskid.load(ERD / "solo_description/robots/solo12.urdf", floating_base=True), names)
    _check(dyn, names, tmp_path, np.random.default_rng(1), io=("float64",))


def test_long_kernels_in_pieces(monkeypatch, tmp_path):
    """Kernels longer than JAXSKID_CUDA_LONG statements, split into device functions that pass values through a
    workspace (the G1's Coriolis matrix and regressor are), forced here on the Panda."""
    monkeypatch.setenv("JAXSKID_CUDA_LONG", "200")
    monkeypatch.setenv("JAXSKID_CUDA_CHUNK", "64")
    names = ["coriolis_matrix", "regressor"]
    dyn = jaxskid.lower(load("panda7"), QUANTITIES)
    source = _cuda.kernel_source(_kernels(dyn)["coriolis_matrix"][0], "coriolis_matrix")
    assert source.count("__attribute__((noinline))") > 3
    _check(dyn, names, tmp_path, np.random.default_rng(5), io=("float64",))


def test_sine_and_cosine_at_many_quadrants(monkeypatch, tmp_path):
    """Sine and cosine by multiply-adds (c/cuda_trig.h, the default), and CUDA's (JAXSKID_CUDA_TRIG=library), at
    angles over many quadrants."""
    names = ["mass_matrix", "coriolis_matrix"]
    dyn = jaxskid.lower(load("panda7"), QUANTITIES)
    for trig, own in (("fused", True), ("library", False)):
        monkeypatch.setenv("JAXSKID_CUDA_TRIG", trig)
        assert ("jaxskid_trig" in _cuda.kernel_source(_kernels(dyn)["mass_matrix"][0], "mass_matrix")) == own
        _check(dyn, names, tmp_path, np.random.default_rng(6), io=("float64",), spread=30.0, shared=(True,))


@pytest.mark.slow
def test_g1(tmp_path):
    """The 29-DOF humanoid: M and tau (the lowering of test_pullbacks' G1, so a run derives it once)."""
    names = ["mass_matrix", "inverse_dynamics"]
    dyn = jaxskid.lower(jaxskid.load(G1), names)
    _check(dyn, names, tmp_path, np.random.default_rng(2), io=("float64",))


def test_programs_for_a_gpu_call_the_kernels(monkeypatch, tmp_path):
    """With CUDA kernels on (as where JAX's backend is a CUDA GPU), a program lowered for CUDA calls the handler
    with the kernel's number, the batch inside one call and the parameters shared by all states (one row);
    so does its gradient, through the mass matrix's pullback kernel; and no JAX form of M is left in it."""
    import jaxskid._api
    import jaxskid._generated
    import jaxskid.runtime._dynamics

    for module in (jaxskid._api, jaxskid.runtime._dynamics):
        monkeypatch.setattr(module, "cuda_enabled", lambda: True)
    dyn = jaxskid.lower(jaxskid.load(ROBOTS_DIR / "arm_2r.yaml"), ["mass_matrix"], cache_dir=tmp_path)
    assert dyn.report()["mass_matrix"] == "CUDA kernel"
    q = jax.ShapeDtypeStruct((16, 2), jnp.float64)
    skip = [jax.export.DisabledSafetyCheck.custom_call(_cuda_target())]

    def exported(fn) -> list[str]:
        text = jax.export.export(jax.jit(fn), platforms=["cuda"], disabled_checks=skip)(q).mlir_module()
        return [line for line in text.splitlines() if "custom_call" in line]

    calls = exported(lambda q: dyn.mass_matrix(q))
    assert len(calls) == 1 and "kernel = " in calls[0]
    assert "tensor<16x2xf64>, tensor<1x" in calls[0] and "-> tensor<16x2x2xf64>" in calls[0]
    grads = exported(jax.grad(lambda q: jnp.sum(dyn.mass_matrix(q) ** 2)))
    assert len(grads) == 2 and all(_cuda_target() in line for line in grads)
    # the states share the parameters: the kernel reads them from constant memory; mapped over, from their input
    kernel = dyn._cuda_kernels["mass_matrix"]
    assert set(kernel._ids) == {("float64", True)}
    p = jnp.stack([dyn.param_vector()] * 16)
    mapped = exported(lambda q: jax.vmap(lambda qi, pi: dyn.mass_matrix(qi, params=pi))(q, p))
    assert len(mapped) == 1 and f"tensor<16x{p.shape[1]}xf64>" in mapped[0]
    assert set(kernel._ids) == {("float64", True), ("float64", False)}
    assert kernel._ids[("float64", False)] != kernel._ids[("float64", True)]
    # a result of many entries is written by entry (here forced for M's four): the call's result holds the
    # entries first, and XLA transposes it into a row per state
    monkeypatch.setattr(jaxskid._generated, "BY_ENTRY", 4)
    dyn = jaxskid.lower(jaxskid.load(ROBOTS_DIR / "arm_2r.yaml"), ["mass_matrix"], cache_dir=tmp_path)
    text = jax.export.export(jax.jit(lambda q: dyn.mass_matrix(q)), platforms=["cuda"], disabled_checks=skip)(q)
    text = text.mlir_module()
    calls = [line for line in text.splitlines() if "custom_call" in line]
    assert len(calls) == 1 and "-> tensor<4x16xf64>" in calls[0] and "stablehlo.transpose" in text
    # given memory to write into (out=), such a result is still fresh memory, transposed the same way
    text = jax.export.export(jax.jit(lambda q: dyn.mass_matrix(q, out=jnp.zeros((16, 2, 2)))), platforms=["cuda"],
                             disabled_checks=skip)(q).mlir_module()
    calls = [line for line in text.splitlines() if "custom_call" in line]
    assert len(calls) == 1 and "-> tensor<4x16xf64>" in calls[0] and "output_operand_aliases" not in calls[0]


def _cuda_target() -> str:
    from jaxskid.runtime._cuda import TARGET

    return TARGET
