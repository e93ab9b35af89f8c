"""Reverse mode through a generated quantity by its closed-form pullback.

A quantity ``y = f(x_1, ..., x_k, p)`` is a straight-line program of thousands of scalar operations. JAX
differentiates it in reverse mode by linearising that program and transposing it: XLA then compiles and
runs a program several times longer than ``f``, whose size grows with every entry of ``y`` (the G1's mass
matrix, 841 entries: minutes to compile). The lowering stage derives instead the pullback of ``f``,
``W -> (d<W, y>/dx_1, ..., d<W, y>/dp)``, as one more program (``mass_matrix_vjp``, ...; a symbolic reverse
sweep, :func:`jaxskid.symbolic.pullback`), and :func:`with_pullback` gives ``f`` the derivatives that use it:

- forward mode (``jax.jvp``, ``jax.jacfwd``) differentiates ``f``'s program as JAX does;
- reverse mode (``jax.grad``, ``jax.vjp``) calls the pullback. The tangent of ``f`` is one primitive,
  linear in the tangents, whose transpose is the pullback (the way JAX's own linear solvers carry their
  transposes); it batches under ``jax.vmap`` into one call of the mapped pullback.

So a function of ``f`` can be differentiated in any order and composition of ``jax.jvp``, ``jax.grad``,
``jax.vmap`` and ``jax.jit``, with one rule, wherever it was traced first.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax.extend.core import Primitive
from jax.interpreters import ad, batching, mlir


class Rule:
    """The derivatives of one quantity: ``tangent(*primals, *tangents)``, its directional derivative, and
    ``pullback(*primals, w)``, the cotangents of the primals (one array each, their shapes) for a cotangent
    ``w`` of the result, each for one state; ``shape`` is the result's; ``state_pullback``, where given, the same
    with a zero cotangent for the last primal (the parameters), used when nothing asks for that one. Compared
    and hashed by identity, as the primitive's parameters are."""

    def __init__(self, tangent: Callable, pullback: Callable, n_primals: int, shape: tuple[int, ...],
                 state_pullback: Callable | None = None):
        self.tangent, self.pullback, self.n_primals, self.shape = tangent, pullback, n_primals, tuple(shape)
        self.state_pullback = state_pullback


tangent_p = Primitive("jaxskid_tangent")
"""``tangent_p.bind(*primals, *tangents, rule, stack)``: ``rule.tangent``, mapped once per entry of ``stack``
(the ``in_axes`` of each enclosing ``jax.vmap``, innermost first)."""


def _mapped(fn: Callable, stack: tuple) -> Callable:
    for axes in stack:
        fn = jax.vmap(fn, in_axes=axes)
    return fn


def _impl(*args, rule: Rule, stack: tuple):
    return _mapped(rule.tangent, stack)(*args)


def _abstract(*avals, rule: Rule, stack: tuple):
    shapes, sizes = [a.shape for a in avals], []
    for axes in reversed(stack):  # outermost first: its axes index the whole arrays
        k = next(i for i, a in enumerate(axes) if a is not None)
        sizes.append(shapes[k][axes[k]])
        shapes = [s if a is None else s[:a] + s[a + 1:] for s, a in zip(shapes, axes)]
    dtype = jnp.result_type(*(a.dtype for a in avals))
    return jax.core.ShapedArray((*sizes, *rule.shape), dtype)


def _batch(args, dims, *, rule: Rule, stack: tuple):
    axes = tuple(d if isinstance(d, int) else None for d in dims)  # not mapped: None (or a sentinel)
    return tangent_p.bind(*args, rule=rule, stack=(*stack, axes)), 0


def _jvp(primals, tangents, *, rule: Rule, stack: tuple):
    tangents = [ad.instantiate_zeros(t) for t in tangents]
    return jax.jvp(functools.partial(_impl, rule=rule, stack=stack), tuple(primals), tuple(tangents))


def _pull_level(fn: Callable, axes: tuple, n: int) -> Callable:
    """``fn`` of one more batch level: the primals mapped on their axes, the result's cotangent on 0; each
    cotangent summed over the batch where its tangent is not batched, else on the tangent's axis."""
    def pull(*args):
        cts = jax.vmap(fn, in_axes=(*axes[:n], 0))(*args)
        return tuple(c.sum(0) if a is None else jnp.moveaxis(c, 0, a) for c, a in zip(cts, axes[n:]))

    return pull


def _transpose(ct, *args, rule: Rule, stack: tuple):
    n = rule.n_primals
    primals, tangents = args[:n], args[n:]
    if type(ct) is ad.Zero or not any(ad.is_undefined_primal(t) for t in tangents):
        return [None] * len(args)
    if any(ad.is_undefined_primal(x) for x in primals):
        raise NotImplementedError("jaxskid: a quantity's tangent is linear in its tangents, not its primals")
    pull = rule.pullback
    if rule.state_pullback is not None and not ad.is_undefined_primal(tangents[-1]):
        pull = rule.state_pullback  # the parameters' cotangent is not asked for: a shorter program
    for axes in stack:
        pull = _pull_level(pull, axes, n)
    cts = pull(*primals, ct)
    out = [c.astype(t.aval.dtype) if ad.is_undefined_primal(t) else None for c, t in zip(cts, tangents)]
    return [None] * n + out


tangent_p.def_impl(_impl)
tangent_p.def_abstract_eval(_abstract)
batching.primitive_batchers[tangent_p] = _batch
ad.primitive_jvps[tangent_p] = _jvp
ad.primitive_transposes[tangent_p] = _transpose
mlir.register_lowering(tangent_p, mlir.lower_fun(_impl, multiple_results=False))


def with_pullback(primal: Callable, *, program: Callable, pullback: Callable, n_args: int,
                  shape: tuple[int, ...], state_pullback: Callable | None = None) -> Callable:
    """``primal`` (``f(*state, p)`` of one state: ``n_args`` arrays, result ``shape``) differentiated in forward
    mode through ``program`` (the same function as JAX code) and in reverse mode by ``pullback(*state, p, w)``,
    which returns the cotangent of each argument (see the module docstring)."""

    def tangent(*args):
        return jax.jvp(program, args[:n_args], args[n_args:])[1]

    rule = Rule(tangent, pullback, n_args, shape, state_pullback)

    @jax.custom_jvp
    def f(*args):
        return primal(*args)

    @f.defjvp
    def _derivative(primals, tangents):
        return primal(*primals), tangent_p.bind(*primals, *tangents, rule=rule, stack=())

    f.__name__, f.__doc__ = getattr(primal, "__name__", "quantity"), primal.__doc__  # not its __dict__: its rule
    return f
