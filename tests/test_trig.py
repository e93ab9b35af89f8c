"""The fused sine and cosine (jaxskid._fused: the same code is pasted into every generated module),
against mpmath at 40 digits."""

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest

from jaxskid import _fused


@pytest.fixture(scope="module", params=["imported", "pasted"])
def trig(request):
    """The functions as the runtime imports them, and as the text every generated module carries."""
    if request.param == "imported":
        return _fused.sin, _fused.cos
    ns = {"jax": jax, "jnp": jnp}
    exec(_fused.SOURCE, ns)  # noqa: S102 - the exact text every generated module carries
    return ns["_sin"], ns["_cos"]


def _points(rng, n, scale):
    return np.concatenate([rng.uniform(-scale, scale, n), np.arange(-40, 41) * (np.pi / 4), [0.0, -0.0, 1e-300, 5e-324]])


def _reference(x):
    mpmath.mp.dps = 40
    return (np.array([float(mpmath.sin(mpmath.mpf(float(v)))) for v in x]),
            np.array([float(mpmath.cos(mpmath.mpf(float(v)))) for v in x]))


@pytest.mark.parametrize("scale", [4.0, 1e3, 1e5])
def test_float64_within_an_ulp_of_one(trig, scale):
    x = _points(np.random.default_rng(int(scale)), 3000, scale)
    s_ref, c_ref = _reference(x)
    s, c = (np.asarray(f(jnp.asarray(x))) for f in trig)
    for got, ref in ((s, s_ref), (c, c_ref)):
        err = np.abs(got - ref)
        # absolute error about one ulp of 1.0 (2 ulp of results in [0.5, 1]), at most 2 ulp of larger results
        assert np.all(err <= np.maximum(2 * np.spacing(np.abs(ref)), 2.3e-16)), err.max()


def test_float32(trig):
    x = np.random.default_rng(1).uniform(-10, 10, 5000).astype(np.float32)
    s_ref, c_ref = _reference(x)
    for f, ref in zip(trig, (s_ref, c_ref)):
        got = f(jnp.asarray(x))
        assert got.dtype == jnp.float32
        assert np.max(np.abs(np.asarray(got, np.float64) - ref)) < 1.5e-7


@pytest.mark.parametrize(("dtype", "exact", "tol"), [(np.float32, 1e4, 1.5e-7), (np.float64, 1.6e6, 4.5e-16)])
def test_large_angles(trig, dtype, exact, tol):
    """Within the exact argument reduction the values agree with mpmath; beyond it, in float32 (a wheel's angle
    after half an hour), they stay sines and cosines of some angle: within [-1, 1], s^2 + c^2 = 1 (the
    polynomials of an unreduced argument grow without bound)."""
    near = np.geomspace(10, exact, 40).astype(dtype)
    s_ref, c_ref = _reference(near)
    for f, ref in zip(trig, (s_ref, c_ref)):
        assert np.max(np.abs(np.asarray(f(jnp.asarray(near)), np.float64) - ref)) < tol
    if dtype == np.float32:
        far = np.concatenate([np.geomspace(exact, 3e38, 60), -np.geomspace(exact, 1e30, 20)]).astype(dtype)
        s, c = (np.asarray(f(jnp.asarray(far)), np.float64) for f in trig)
        assert np.all(np.abs(s) <= 1) and np.all(np.abs(c) <= 1)
        np.testing.assert_allclose(s * s + c * c, 1.0, atol=4 * tol)


def test_non_finite(trig):
    for f in trig:
        out = np.asarray(f(jnp.asarray([np.inf, -np.inf, np.nan])))
        assert np.all(np.isnan(out))


def test_derivatives_are_exact(trig):
    sin, cos = trig
    x = jnp.asarray(np.random.default_rng(2).uniform(-20, 20, 200))
    s_ref, c_ref = _reference(np.asarray(x))
    ds = jax.vmap(jax.grad(sin))(x)
    dc = jax.vmap(jax.grad(cos))(x)
    d2s = jax.vmap(jax.grad(jax.grad(sin)))(x)
    np.testing.assert_allclose(np.asarray(ds), c_ref, atol=3e-16)
    np.testing.assert_allclose(np.asarray(dc), -s_ref, atol=3e-16)
    np.testing.assert_allclose(np.asarray(d2s), -s_ref, atol=3e-16)


def test_source_defines_what_the_module_exports():
    """SOURCE is the module's own code: executed alone, it defines every helper generated code calls."""
    ns = {"jax": jax, "jnp": jnp}
    exec(_fused.SOURCE, ns)  # noqa: S102
    for name in ("_sin", "_cos", "_sincos", "_recip", "_spread", "_same", "_plain_jvp"):
        assert name in ns, name
    x = jnp.asarray(np.random.default_rng(3).uniform(0.1, 10.0, 100))
    np.testing.assert_array_equal(np.asarray(ns["_recip"](x)), np.asarray(_fused.recip(x)))
    ref = 1.0 / np.asarray(x)
    assert np.all(np.abs(np.asarray(_fused.recip(x)) - ref) <= np.spacing(ref))  # within one ulp


def test_off_cpu_programs_use_xla_sine_and_cosine(monkeypatch):
    """On a GPU the multiply-adds were the slower choice, so a program lowered for another platform than the
    CPU calls XLA's own sine and cosine; one lowered for the CPU keeps the multiply-adds. Checked on the
    exported StableHLO of each platform, as a machine whose default backend is a GPU lowers it."""
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    spec = jax.ShapeDtypeStruct((4,), jnp.float64)
    for fn, op in ((_fused.sin, "stablehlo.sine"), (_fused.cos, "stablehlo.cosine")):
        for platform, xla in (("cuda", True), ("cpu", False)):
            text = jax.export.export(jax.jit(jax.vmap(fn)), platforms=[platform])(spec).mlir_module()
            assert (op in text) is xla, (fn, platform)
            assert ("stablehlo.round" in text) is not xla, (fn, platform)  # the argument reduction by pi/2
        grad = jax.export.export(jax.jit(jax.vmap(jax.grad(fn))), platforms=["cuda"])(spec).mlir_module()
        assert "stablehlo.round" not in grad
