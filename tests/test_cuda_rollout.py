"""The rollout kernels of a GPU (jaxskid/lowering/_cuda_rollout.py, jaxskid/runtime/_cuda_rollout.py), where no GPU
is: their source compiles with NVRTC (to PTX, float64 and float32), the same source built as C for the host
integrates what the JAX rollout integrates and pulls back what ``jax.vjp`` of it pulls back, at 1e-12, over a
batch of two axes with torques, parameters and steps shared along some of them (the indexing each GPU thread
does); and a rollout lowered for CUDA calls the kernels, batch and all, and nothing else of the dynamics."""

import jax
import jax.numpy as jnp
import numpy as np

import jaxskid
from helpers import ROBOTS_DIR, load
from jaxskid.lowering import _cuda, _cuda_rollout
from jaxskid.runtime._cuda import TARGET
from jaxskid._generated import ROLLOUT_PARTS, ROLLOUT_STRIDE
from jaxskid.runtime._cuda_rollout import rollout_kernels

STEPS = 6


def _builds(dyn):
    return list({id(b): b for b in dyn._native_build.values()}.values())


def test_kernels_agree_with_the_jax_rollout_and_its_pullback(tmp_path):
    dyn = jaxskid.lower(load("panda7"), ["forward_dynamics"])
    n, n_params = dyn.nv, len(dyn.parameters)
    kernels = dict(zip(ROLLOUT_PARTS, rollout_kernels(_builds(dyn), n, n_params, STEPS)))
    for part, kernel in kernels.items():
        for io in ("float64", "float32"):
            source = _cuda_rollout.rollout_source(kernel.vectors, "panda", n, n_params, STEPS, io, part)
            ptx = _cuda.compile_kernel(source, "compute_90").decode()
            assert ".entry jaxskid_kernel" in ptx and ".f64" in ptx
    rng = np.random.default_rng(0)
    # batch (2, 3): x0 varies along both axes, the torques along the second, the step along the first; the
    # angles span many quadrants (the kernels' own sine and cosine)
    x0, u = rng.uniform(-0.5, 0.5, (2, 3, 2 * n)), rng.uniform(-5, 5, (3, STEPS, n))
    x0[..., :n] *= 40.0
    p, h = np.asarray(dyn.param_vector()), np.array([0.01, 0.02]).reshape(2, 1, 1)

    def run(part, inputs, shape, shared=True):  # the parameters in constant memory, or read from their input
        kernel = kernels[part]
        lib = _cuda.host_library(_cuda_rollout.rollout_source(kernel.vectors, "panda", n, n_params, STEPS,
                                                              part=part, shared=shared), tmp_path)
        _, cores, _, out_rank, _, constant, _ = kernel._layout(shared)
        assert (constant >= 0) == shared
        out = np.full(shape, np.nan)
        _cuda.run_on_host(lib, inputs, cores, out, out_rank, constant)
        return out

    x = run("forward", [x0, u, p, h], (2, 3, STEPS + 1, 2 * n))
    np.testing.assert_array_equal(run("forward", [x0, u, p, h], x.shape, shared=False), x)

    def one(x0, u, p, h):
        return jaxskid.rollout(dyn, x0, u, h[0], STEPS, params=p, autodiff="reverse").x

    def batched(fn):
        return jax.vmap(jax.vmap(fn, (0, 0, None, None, 0)), (0, None, None, 0, 0))

    want = batched(lambda x0, u, p, h, _: one(x0, u, p, h))(x0, u, p, h.reshape(2, 1), x0)
    np.testing.assert_allclose(x, want, rtol=0, atol=1e-12 * np.abs(want).max())
    g = rng.normal(size=x.shape)
    adjoint = run("adjoint", [x, u, p, h, g], (2, 3, 2 * n + STEPS * n + 1 + 4 * STEPS * n))
    cut = 2 * n + STEPS * n
    lam = np.ascontiguousarray(adjoint[..., cut + 1:]).reshape(2, 3, 1, STEPS, 4 * n)
    blocks = -(-STEPS // ROLLOUT_STRIDE)  # the steps in blocks, each a thread: batch (2, 3, blocks)
    pbar = run("parameters", [x[:, :, None], u[:, None], lam, p, h[..., None], np.arange(float(blocks))],
               (2, 3, blocks, n_params)).sum(axis=2)
    bar = np.concatenate([adjoint[..., :cut], pbar, adjoint[..., cut:cut + 1]], axis=-1)

    def pullback(x0, u, p, h, g):
        return jnp.concatenate([c.ravel() for c in jax.vjp(one, x0, u, p, h)[1](g)])

    want = batched(pullback)(x0, u, p, h.reshape(2, 1), g)
    cuts = np.cumsum([2 * n, STEPS * n, n_params])
    for got, ref, what in zip(np.split(bar, cuts, axis=-1), np.split(want, cuts, axis=-1), ("x0", "u", "p", "h")):
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max(), err_msg=what)


def test_programs_for_a_gpu_call_the_rollout_kernels(monkeypatch, tmp_path):
    """With CUDA kernels on, a batched rollout under held torques is one call of the forward kernel, and its
    gradient with respect to the parameters adds the adjoint and the parameters' kernels: no loop over the
    steps."""
    import jaxskid._api
    import jaxskid.runtime._dynamics

    for module in (jaxskid._api, jaxskid.runtime._dynamics):
        monkeypatch.setattr(module, "cuda_enabled", lambda: True)
    dyn = jaxskid.lower(jaxskid.load(ROBOTS_DIR / "arm_2r.yaml"), ["forward_dynamics"], cache_dir=tmp_path)
    x0 = jax.ShapeDtypeStruct((16, 4), jnp.float64)
    u = jnp.ones((STEPS, 2))
    skip = [jax.export.DisabledSafetyCheck.custom_call(TARGET)]

    def exported(fn) -> str:
        return jax.export.export(jax.jit(fn), platforms=["cuda"], disabled_checks=skip)(x0).mlir_module()

    def loss(x0, p):
        return jnp.sum(jaxskid.rollout(dyn, x0, u, 0.01, STEPS, params=p).x ** 2)

    text = exported(lambda x0: jaxskid.rollout(dyn, x0, u, 0.01, STEPS).x)
    calls = [line for line in text.splitlines() if "custom_call" in line]
    assert len(calls) == 1 and TARGET in calls[0] and "-> tensor<16x7x4xf64>" in calls[0]
    assert "stablehlo.while" not in text
    text = exported(lambda x0: jax.grad(loss, argnums=1)(x0, dyn.param_vector()))
    calls = [line for line in text.splitlines() if "custom_call" in line]
    assert len(calls) == 3 and all(TARGET in line for line in calls) and "stablehlo.while" not in text
    # second order (forward over reverse) differentiates the kernels' fallback, the loop of steps
    text = exported(lambda x0: jax.hessian(loss, argnums=1)(x0, dyn.param_vector()))
    assert "stablehlo.while" in text and TARGET in text
