"""The gathered form's program written into the lowered module directly, without tracing its operations.

The gathered form (:mod:`jaxskid.runtime._gathered`) runs a quantity's program once on vectors of the batch.
Traced with ``jax.numpy``, every operation of the program costs JAX an equation, its checks and its lowering:
the G1 with hands' Coriolis matrix (43 DOF, 36,000 operations) takes 1.2 s to trace and 0.7 s to lower, a
tenth of its cold first call. Here the program runs once on :class:`_Value` objects that record each operation
on a tape (:func:`recorded`, kept per quantity), and one primitive stands for all of its outputs. Its lowering
rule writes the tape's operations into the module as StableHLO: 0.1 s to record and 0.4 s to lower in all.

The module is the one the trace makes: the same operations on the same operands in the same order, so the
results agree to the last bit (``tests/test_emitted.py`` compares them). Two things differ, both in what
XLA would merge anyway: a constant is broadcast once for all its uses, and the sine and cosine of an angle
are one evaluation of :func:`jaxskid._fused` ``_sincos_here`` (traced, both are computed for each).

A program that does anything the tape does not record (an operation on two different dtypes, a function the
generated module calls that is not one of its helpers) is traced instead: :func:`recorded` returns None.
``JAXSKID_RECORD=0`` in the environment traces every program (read when a program is lowered), to compare.
The primitive evaluates, maps (``jax.vmap``) and differentiates in forward mode through that traced program;
the gathered form itself never asks it to, since its rules run above it.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import types
import weakref
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import Primitive
from jax.extend.mlir import ir
from jax.extend.mlir.dialects import stablehlo as hlo
from jax.interpreters import ad, batching, mlir

from .._generated import GeneratedQuantity
from ._whole import result_aval

log = logging.getLogger("jaxskid")

VARIABLE = "JAXSKID_RECORD"
"""Set to 0 to trace every program instead of recording it (module docstring)."""

_BINARY = {"add": hlo.add, "sub": hlo.subtract, "mul": hlo.multiply, "div": hlo.divide}
_UNARY = frozenset({"neg", "pow", "sin", "cos", "call"})


def distinct(entries: dict, size: int) -> tuple[list, np.ndarray]:
    """``(values, index)``: the distinct values of ``entries`` (``{flat index: value}``; one object stored under
    several indices counts once) in the dict's order, which is the order the program computes them, and, for
    each of the result's ``size`` flat indices, the position of its value (``len(values)``, the zero column,
    where ``entries`` has none)."""
    values, seen = [], {}
    index = np.full(size, -1, dtype=np.int32)
    for k, v in entries.items():
        if id(v) not in seen:
            seen[id(v)] = len(values)
            values.append(v)
        index[k] = seen[id(v)]
    index[index < 0] = len(values)
    return values, index


class _Tape:
    """The operations of one run of a program: ``(kind, a, b)``, where ``a`` and ``b`` are earlier positions
    on the tape, a constant, an argument's index and entry, or a helper (the lowering rule's ``_lower_op``)."""

    def __init__(self):
        self.ops: list[tuple] = []
        self._reads: dict = {}
        self._constants: dict = {}

    def push(self, kind: str, a, b=None) -> _Value:
        self.ops.append((kind, a, b))
        return _Value(self, len(self.ops) - 1)

    def operand(self, x) -> int:
        """The tape position of ``x``: a value of this tape, or a Python number (a constant)."""
        if type(x) is _Value and x.tape is self:
            return x.at
        if type(x) in (int, float):
            value = float(x)
            if value not in self._constants:
                self._constants[value] = self.push("const", value).at
            return self._constants[value]
        raise TypeError(f"the tape records no operand of type {type(x).__name__}")

    def read(self, arg: int, entry: tuple) -> _Value:
        if (arg, entry) not in self._reads:
            self._reads[arg, entry] = self.push("read", arg, entry)
        return self._reads[arg, entry]


class _Value:
    """A value of the program on the tape: arithmetic records an operation and returns its value."""

    __slots__ = ("tape", "at")

    def __init__(self, tape: _Tape, at: int):
        self.tape, self.at = tape, at

    def _binary(self, kind: str, a, b) -> _Value:
        return self.tape.push(kind, self.tape.operand(a), self.tape.operand(b))

    def __add__(self, other):
        return self._binary("add", self, other)

    def __radd__(self, other):
        return self._binary("add", other, self)

    def __sub__(self, other):
        return self._binary("sub", self, other)

    def __rsub__(self, other):
        return self._binary("sub", other, self)

    def __mul__(self, other):
        return self._binary("mul", self, other)

    def __rmul__(self, other):
        return self._binary("mul", other, self)

    def __truediv__(self, other):
        return self._binary("div", self, other)

    def __rtruediv__(self, other):
        return self._binary("div", other, self)

    def __neg__(self):
        return self.tape.push("neg", self.at)

    def __pow__(self, exponent):
        if type(exponent) is not int or exponent < 1:
            raise TypeError("the tape records positive integer powers only")
        return self.tape.push("pow", self.at, exponent)

    def __bool__(self):
        raise TypeError("a recorded value has no truth value")


class _Argument:
    """An argument of the program: indexing it reads an entry (``q[3]``, ``w[0, 2]``)."""

    __slots__ = ("tape", "k")

    def __init__(self, tape: _Tape, k: int):
        self.tape, self.k = tape, k

    def __getitem__(self, entry):
        entry = entry if isinstance(entry, tuple) else (entry,)
        if not all(type(i) is int for i in entry):
            raise TypeError("the tape records reads of single entries only")
        return self.tape.read(self.k, entry)


class Recorded:
    """A program's tape: its operations, the positions of its distinct nonzero entries in the order it computes
    them, the result's index into them (:func:`distinct`), and the quantity and helpers it came from."""

    def __init__(self, quantity: GeneratedQuantity, ops: tuple, outputs: tuple, index: np.ndarray,
                 sincos: Callable):
        self.quantity, self.ops, self.outputs, self.index, self.sincos = quantity, ops, outputs, index, sincos


_RECORDED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def recorded(quantity: GeneratedQuantity) -> Recorded | None:
    """The tape of ``quantity``'s program (module docstring), made once per quantity; None where the program
    does something the tape does not record."""
    if quantity not in _RECORDED:
        _RECORDED[quantity] = _record(quantity)
    return _RECORDED[quantity]


def _record(quantity: GeneratedQuantity) -> Recorded | None:
    program, tape = quantity.program, _Tape()
    namespace = dict(program.__globals__)
    if not all(callable(namespace.get(name)) for name in ("_sin", "_cos", "_recip", "_sincos_here")):
        return None
    recip = namespace["_recip"]
    namespace["_sin"] = lambda x: tape.push("sin", tape.operand(x))
    namespace["_cos"] = lambda x: tape.push("cos", tape.operand(x))
    namespace["_recip"] = lambda x: tape.push("call", tape.operand(x), recip)
    run = types.FunctionType(program.__code__, namespace, program.__name__, program.__defaults__,
                             program.__closure__)
    try:
        entries = run(*(_Argument(tape, k) for k in range(len(quantity.args) + 1)), _identity, entries=True)
        values, index = distinct(entries, math.prod(quantity.shape))
        outputs = tuple(tape.operand(v) for v in values)
    except Exception as exc:  # an operation the tape does not record: the program is traced instead
        log.debug("jaxskid: %s is traced, not recorded (%s)", quantity.name, exc)
        return None
    return Recorded(quantity, tuple(tape.ops), outputs, index, namespace["_sincos_here"])


def operands(rec: Recorded) -> list[tuple]:
    """For each operation of ``rec``'s tape, the positions of the operations it reads."""
    return [(a, b) if kind in _BINARY else (a,) if kind in _UNARY else () for kind, a, b in rec.ops]


_ROWS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def rows(quantity: GeneratedQuantity, start: int, stop: int) -> GeneratedQuantity | None:
    """``quantity`` restricted to the rows ``[start, stop)`` of its result, for the gathered form to compute
    apart (:mod:`jaxskid.runtime._parts`): a quantity named ``name[start:stop]`` whose tape is ``quantity``'s,
    with the outputs those rows read, in the program's order; None where the program is not recorded. Made once
    per range and kept as long as ``quantity`` is (a collected copy would drop an equal one's tape from
    :data:`_RECORDED`)."""
    rec = recorded(quantity)
    if rec is None:
        return None
    made = _ROWS.setdefault(quantity, {})
    if (start, stop) not in made:
        width = math.prod(quantity.shape[1:])
        index = rec.index[start * width:stop * width]
        used = np.unique(index[index < len(rec.outputs)])
        position = np.full(len(rec.outputs) + 1, len(used), dtype=np.int32)
        position[used] = np.arange(len(used), dtype=np.int32)
        made[(start, stop)] = part = dataclasses.replace(
            quantity, name=f"{quantity.name}[{start}:{stop}]", shape=(stop - start, *quantity.shape[1:]),
            program=_RowsProgram(quantity.program, start, stop, width))
        _RECORDED[part] = Recorded(part, rec.ops, tuple(rec.outputs[k] for k in used), position[index],
                                   rec.sincos)
    return made[(start, stop)]


class _RowsProgram:
    """A generated program restricted to the rows ``[start, stop)`` of its result (``width`` entries each), with
    the program's signature: what :func:`traced` and the one-state program of :func:`rows` run."""

    def __init__(self, program: Callable, start: int, stop: int, width: int):
        self.program, self.start, self.stop, self.width = program, start, stop, width

    def __call__(self, *args, entries: bool = False):
        if not entries:
            return self.program(*args)[self.start:self.stop]
        low, high = self.start * self.width, self.stop * self.width
        return {k - low: v for k, v in self.program(*args, entries=True).items() if low <= k < high}


def _identity(x):
    return x


def values(quantity: GeneratedQuantity, args, lanes_shape: tuple,
           constants: tuple | None = None) -> tuple[list, np.ndarray] | None:
    """``(values, index)`` of ``quantity``'s program on ``args`` (their batch, if any, on their last axis),
    every distinct nonzero entry an array of ``lanes_shape``, as the gathered form's first step needs them; None
    where the program is not recorded or the arguments differ in dtype or are not real floats (then the
    gathered form traces the program).

    ``constants``: the values of the parameter vector (``args[-1]``, then not read), written into the module as
    constants, which XLA folds where they meet: a call with the default parameters. Read from its argument
    inside the loop of a large batch, the G1 with hands' Coriolis matrix took 16.9 s to compile, as constants
    14.7 to 15.0 s (one core)."""
    if os.environ.get(VARIABLE, "1") == "0":
        return None
    rec = recorded(quantity)
    dtypes = {jnp.result_type(a) for a in args}
    if rec is None or len(dtypes) != 1 or dtypes.pop() not in (jnp.float32, jnp.float64):
        return None
    if not rec.outputs:  # every entry is zero
        return [], rec.index
    if constants is not None:
        args = args[:-1]
    return _values_p.bind(*args, recorded=rec, lanes_shape=tuple(lanes_shape), constants=constants), rec.index


def traced(quantity: GeneratedQuantity, args, lanes_shape: tuple) -> tuple[list, np.ndarray]:
    """``(values, index)`` as :func:`values` gives them, by tracing the program with ``jax.numpy``."""
    dtype = jnp.result_type(*args)
    entries = quantity.program(*args, lambda x: jnp.broadcast_to(x, lanes_shape), entries=True)
    found, index = distinct(entries, math.prod(quantity.shape))
    return [jnp.broadcast_to(jnp.asarray(v, dtype), lanes_shape) for v in found], index


def traced_values(recorded: Recorded, lanes_shape: tuple, constants: tuple | None, *args) -> list:
    """The primitive's outputs by tracing the program (its evaluation, mapping and derivatives)."""
    if constants is not None:
        args = (*args, jnp.asarray(constants, jnp.result_type(*args)))
    return traced(recorded.quantity, args, lanes_shape)[0]


_values_p = Primitive("jaxskid_recorded_values")
_values_p.multiple_results = True


def _impl(*args, recorded, lanes_shape, constants):
    return jax.jit(traced_values, static_argnums=(0, 1, 2))(recorded, lanes_shape, constants, *args)


def _abstract(*avals, recorded, lanes_shape, constants):
    return [result_aval(avals, lanes_shape, avals[0].dtype)] * len(recorded.outputs)


def _batch(args, dims, *, recorded, lanes_shape, constants):
    mapped = jax.vmap(lambda *a: traced_values(recorded, lanes_shape, constants, *a), in_axes=tuple(dims))
    return mapped(*args), [0] * len(recorded.outputs)


def _jvp(primals, tangents, *, recorded, lanes_shape, constants):
    tangents = [ad.instantiate_zeros(t) for t in tangents]
    return jax.jvp(lambda *a: traced_values(recorded, lanes_shape, constants, *a), tuple(primals), tuple(tangents))


def _lower(ctx, *args, recorded, lanes_shape, constants):
    """The tape's live operations (those an output needs) as StableHLO, in the tape's order."""
    aval = ctx.avals_out[0]
    lowering = _Lowering(ctx, args, aval, recorded, constants)
    live = [False] * len(recorded.ops)
    for at in recorded.outputs:
        live[at] = True
    for at in range(len(recorded.ops) - 1, -1, -1):
        kind, a, b = recorded.ops[at]
        if live[at] and kind in _BINARY:
            live[a] = live[b] = True
        elif live[at] and kind in _UNARY:
            live[a] = True
    for at, op in enumerate(recorded.ops):
        if live[at]:
            lowering.emit(at, *op)
    return [lowering.values[at] for at in recorded.outputs]


class _Lowering:
    """The tape's operations written into the module of ``ctx``: ``values[at]`` is the IR value of position
    ``at``, an array of the primitive's output type."""

    def __init__(self, ctx, args, aval, recorded: Recorded, constants: tuple | None = None):
        self.ctx, self.args, self.aval, self.recorded, self.constants = ctx, args, aval, recorded, constants
        self.type = mlir.aval_to_ir_type(ctx.module_context, aval)
        self.values: list = [None] * len(recorded.ops)
        self._sincos: dict[int, tuple] = {}

    def emit(self, at: int, kind: str, a, b) -> None:
        values = self.values
        if kind in _BINARY:
            values[at] = _BINARY[kind](values[a], values[b])
        elif kind == "neg":
            values[at] = hlo.negate(values[a])
        elif kind == "const":
            constant = mlir.ir_constant(np.asarray(a, self.aval.dtype))
            values[at] = hlo.broadcast_in_dim(self.type, constant, mlir.dense_int_array([]))
        elif kind == "read":
            values[at] = self._read(a, b)
        elif kind == "pow":
            values[at] = _integer_power(values[a], b)
        elif kind in ("sin", "cos"):
            if a not in self._sincos:
                self._sincos[a] = self._call(self.recorded.sincos, values[a], 2)
            values[at] = self._sincos[a][kind == "cos"]
        else:  # "call": a helper of the generated module, elementwise
            values[at] = self._call(b, values[a], 1)[0]

    def _read(self, k: int, entry: tuple):
        """Entry ``entry`` of argument ``k`` broadcast to the output's type; a batched argument carries the batch
        on its last axis, the output's last axis. The parameter vector given as ``constants`` is a constant."""
        if self.constants is not None and k == len(self.args):
            constant = mlir.ir_constant(np.asarray(self.constants[entry[0]], self.aval.dtype))
            return hlo.broadcast_in_dim(self.type, constant, mlir.dense_int_array([]))
        x, shape = self.args[k], self.ctx.avals_in[k].shape
        batched = len(shape) == len(entry) + 1
        start = [*entry, 0] if batched else list(entry)
        limit = [i + 1 for i in entry] + ([shape[-1]] if batched else [])
        part = hlo.slice(x, mlir.dense_int_array(start), mlir.dense_int_array(limit),
                         mlir.dense_int_array([1] * len(start)))
        flat = ir.RankedTensorType.get(shape[-1:] if batched else (), mlir.dtype_to_ir_type(np.dtype(self.aval.dtype)))
        axes = [len(self.aval.shape) - 1] if batched else []
        return hlo.broadcast_in_dim(self.type, hlo.reshape(flat, part), mlir.dense_int_array(axes))

    def _call(self, fn: Callable, x, results: int) -> list:
        """``fn(x)`` (``results`` arrays of the output's type) lowered from its trace, inline. Traced once and
        called as one function of the module instead (``jax.jit``), the helpers lowered in 0.02 instead of 0.12 s
        for the G1 with hands' C, but XLA then contracted multiply-adds differently: float32 results differed from
        the traced program's in the last bit."""
        rule = mlir.lower_fun(fn if results > 1 else lambda v: (fn(v),), multiple_results=True)
        out = rule(self.ctx.replace(primitive=None, avals_in=[self.aval], avals_out=[self.aval] * results), x)
        return [v[0] if isinstance(v, (list, tuple)) else v for v in out]


def _integer_power(x, n: int):
    """``x ** n`` by squaring, as ``jax.lax.integer_pow`` lowers it."""
    acc = None
    while n > 0:
        if n & 1:
            acc = x if acc is None else hlo.multiply(acc, x)
        n >>= 1
        if n:
            x = hlo.multiply(x, x)
    return acc


_values_p.def_impl(_impl)
_values_p.def_abstract_eval(_abstract)
mlir.register_lowering(_values_p, _lower)
batching.primitive_batchers[_values_p] = _batch
ad.primitive_jvps[_values_p] = _jvp
