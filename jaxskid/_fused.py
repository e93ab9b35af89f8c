"""The fused JAX helpers of jaxskid: sine, cosine and reciprocal from multiply-adds, and the broadcast
helpers of generated functions. Written once: the section between the two markers below is both the code
of this module (importable: :func:`sin`, :func:`cos`, :func:`sincos`, :func:`recip`) and :data:`SOURCE`,
the text pasted into every generated JAX module, which therefore stays self-contained.

**Sine and cosine as plain multiply-adds that XLA fuses.** XLA on CPU treats ``sin`` and ``cos`` as
expensive: it will not fuse them into a kernel that uses their value more than once per element, so
every ``sin(q_i)`` of a mass matrix became a kernel of its own and its result a round trip through memory
(``python benchmarks/output_forms.py`` compares the two on the Panda's mass matrix). The method is the
classic one: Cody & Waite argument reduction
``x = n pi/2 + r`` with ``pi/2`` split into pieces of 33 significant bits, so that ``n * piece`` is exact
for ``|n| < 2**20`` (``|x| < 1.6e6`` rad), and the minimax polynomials of Cephes' ``sin.c`` on
[-pi/4, pi/4]. Measured against mpmath (``tests/test_trig.py``): within about one ulp of 1.0 in float64
for ``|x| <= 1e5``, 1.5e-7 in float32 for ``|x| <= 1e4``. Beyond ``|x| ~ 1.6e6`` (float32: ``1e5``) the
reduction loses bits, and the polynomials of an unreduced argument grow without bound. In float32, where that
starts at angles a wheel reaches in half an hour, the reduced argument is clipped to [-pi/4, pi/4], so that the
values stay within [-1, 1]; in float64 the two operations per angle cost the G1's inverse dynamics about 5 %,
for angles beyond 1.6e6 rad, and are left out. The native kernels take libm's values beyond 1e5; XLA's
functions would reduce exactly, but a select between them and the polynomials costs every angle their
evaluation (``benchmarks/rollouts.py``: a Panda rollout at batch 1024 1.5x slower). ``inf`` and ``nan`` give
``nan``. Derivatives are defined exactly (``d sin = cos dx``).
This serves CPU programs only. On a GPU (an H100) the multiply-adds were the slower choice, by far for
the G1's mass matrix (``benchmarks/scaling.py --trig fused`` against the default); there a program uses
XLA's functions (``lax.platform_dependent``, resolved when the program is lowered for its platform).

**Reciprocals by Newton's iteration.** XLA will not fuse a division whose result has several users
either; ``1/x`` is printed as ``_recip(x)``: ``r <- r (2 - x r)`` five times (four in float32) from a
first guess made by negating the exponent's bits (within 12.5 %), which reaches the rounding error. Zero
gives inf or nan, as a singular pivot should.

**One shape for the whole program.** A generated function broadcasts every input entry it reads to the
shape of its output (``_spread``), so that XLA sees one elementwise program and compiles it into one
kernel (see :mod:`jaxskid.codegen._jax`). Broadcast values would make reverse-mode differentiation carry a
cotangent per output entry through the whole program, so each function is a ``jax.custom_jvp`` whose
derivative is that of the same program on unbroadcast values (``_plain_jvp``): gradients cost what they
cost without the broadcast.

This module imports only JAX (no SymPy): the runtime and the applications use the same functions.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp

_BEGIN = "# >>> generated-module helpers"
_END = "# <<< generated-module helpers"

# >>> generated-module helpers
_PIO2 = (1.57079632673412561417e+00, 6.07710050630396597660e-11, 2.02226624871116645580e-21)
_PIO2_F32 = (1.5703125, 4.837512969970703125e-4, 7.54978995489188216e-8)
_SIN = (1.58962301576546568060e-10, -2.50507477628578072866e-8, 2.75573136213857245213e-6,
        -1.98412698295895385996e-4, 8.33333333332211858878e-3, -1.66666666666666307295e-1)
_COS = (-1.13585365213876817300e-11, 2.08757008419747316778e-9, -2.75573141792967388112e-7,
        2.48015872888517045348e-5, -1.38888888888730564116e-3, 4.16666666666665929218e-2)
_SIN_F32 = (-1.9515295891e-4, 8.3321608736e-3, -1.6666654611e-1)
_COS_F32 = (2.443315711809948e-5, -1.388731625493765e-3, 4.166664568298827e-2)


def _sincos(x):
    """(sin x, cos x) from multiply-adds: Cody-Waite reduction by pi/2, polynomials on [-pi/4, pi/4]."""
    x = jnp.asarray(x)
    if jnp.issubdtype(x.dtype, jnp.complexfloating):  # complex steps: XLA's own functions
        return jnp.sin(x), jnp.cos(x)
    if not jnp.issubdtype(x.dtype, jnp.floating):
        x = x.astype(jnp.result_type(float))
    single = x.dtype in (jnp.float32, jnp.float16, jnp.bfloat16)
    pio2, cs, cc = (_PIO2_F32, _SIN_F32, _COS_F32) if single else (_PIO2, _SIN, _COS)
    n = jnp.round(x * 0.63661977236758134308)
    r = ((x - n * pio2[0]) - n * pio2[1]) - n * pio2[2]
    if single:  # beyond the exact reduction (float32: from about 1e4) r can be anything: bound the polynomials
        r = jnp.clip(r, -0.7854, 0.7854)
    z = r * r
    ps, pc = cs[0], cc[0]
    for c in cs[1:]:
        ps = ps * z + c
    for c in cc[1:]:
        pc = pc * z + c
    s = r + r * z * ps
    c = 1.0 - 0.5 * z + z * z * pc
    k = n - 4.0 * jnp.floor(n * 0.25)
    swap = (k == 1.0) | (k == 3.0)
    sin = jnp.where(swap, c, s)
    cos = jnp.where(swap, s, c)
    return jnp.where(k >= 2.0, -sin, sin), jnp.where((k == 1.0) | (k == 2.0), -cos, cos)


def _sincos_here(x):
    """(sin x, cos x): the multiply-adds above in a CPU program, XLA's own functions on other platforms.
    Where JAX's default backend is the CPU, the multiply-adds alone are traced: a choice made when the
    program is lowered would keep XLA from merging the reductions that sin and cos of one angle share."""
    if jax.default_backend() == "cpu":
        return _sincos(x)
    return jax.lax.platform_dependent(x, cpu=_sincos, default=lambda x: (jnp.sin(x), jnp.cos(x)))


@jax.custom_jvp
def _sin(x):
    return _sincos_here(x)[0]


@jax.custom_jvp
def _cos(x):
    return _sincos_here(x)[1]


@_sin.defjvp
def _sin_jvp(primals, tangents):
    s, c = _sincos_here(primals[0])
    return s, c * tangents[0]


@_cos.defjvp
def _cos_jvp(primals, tangents):
    s, c = _sincos_here(primals[0])
    return c, -s * tangents[0]


def _recip(x):
    """1 / x from multiplications only (Newton's iteration from a bit-level first guess)."""
    x = jnp.asarray(x)
    return _newton_recip(x) if x.dtype in (jnp.float64, jnp.float32) else 1.0 / x


@jax.custom_jvp
def _newton_recip(x):
    if x.dtype == jnp.float64:
        bits, magic, iters = jnp.int64, 0x7FDE623822835EEA, 5
    else:
        bits, magic, iters = jnp.int32, 0x7EF311C3, 4
    a = jnp.abs(x)
    r = jax.lax.bitcast_convert_type(jnp.asarray(magic, bits) - jax.lax.bitcast_convert_type(a, bits), x.dtype)
    for _ in range(iters):
        r = r * (2.0 - a * r)
    return jnp.where(x < 0, -r, r)


@_newton_recip.defjvp
def _newton_recip_jvp(primals, tangents):
    r = _newton_recip(primals[0])
    return r, -r * r * tangents[0]


def _spread(shape):
    return lambda x: jnp.broadcast_to(x, shape)


def _same(x):
    return x


def _plain_jvp(body):
    """JVP rule of a generated function: the derivative of its program on unbroadcast values."""
    def rule(primals, tangents):
        return jax.jvp(lambda *args: body(*args, _same), primals, tangents)
    return rule

# <<< generated-module helpers


def _section() -> str:
    """The text between the markers: exactly what this module executed above."""
    text = Path(__file__).read_text(encoding="utf-8")
    begin = text.index(_BEGIN + "\n") + len(_BEGIN) + 1
    return text[begin:text.index(_END, begin)].rstrip() + "\n"


SOURCE: str = "\n" + _section()
"""The helpers as source text, pasted into every generated JAX module after ``import jax`` and
``import jax.numpy as jnp``."""

sin = _sin
"""``sin(x)``, fusible (see the module docstring); elementwise, any shape, exact derivative."""
cos = _cos
"""``cos(x)``, fusible (see the module docstring); elementwise, any shape, exact derivative."""
sincos = _sincos
"""``(sin(x), cos(x))`` from one argument reduction."""
recip = _recip
"""``1 / x`` by Newton's iteration (see the module docstring); elementwise, any shape."""

__all__ = ["SOURCE", "cos", "recip", "sin", "sincos"]
