"""Reference evaluation of derived equations: 50-digit mpmath values, fast NumPy values, and a rounding-error
bound, all from the straight-line program of :class:`~jaxskid.Equations` (no JAX).

* :func:`mp_reference` lambdifies the program (``sympy.lambdify(..., modules="mpmath")``, the assignments as
  its common subexpressions) and evaluates it at 50 significant digits. Inputs are float64 numbers, which
  mpmath holds exactly, so the result is the exact value of the expressions at those inputs to ~1e-50.
  It is returned as a double-double ``(hi, lo)`` so that the error of a float64 result can be measured below
  its own round-off (:func:`abs_error`).
* :func:`evaluate` interprets the program with NumPy arrays (real or complex: the complex step gives exact
  derivatives) for a batch of states, without compiling anything: a fresh robot is evaluated in milliseconds.
* :func:`error_bound` is an a-priori bound on the round-off of any evaluation of the same program in
  floating point with unit roundoff ``u`` (Higham, "Accuracy and Stability of Numerical Algorithms", 2nd ed.
  2002, sec. 3.1, Lemma 3.1 and eq. (3.4)): the program has exact inputs and uses only +, x, positive powers
  and sin/cos of inputs, so every computed output is the exact output of the program in which every operation
  is multiplied by its own ``(1 + delta)``, ``|delta| <= u``. Expanding the output into monomials, each one
  carries at most ``D`` such factors, ``D`` the largest number of roundings on a path from an input to the
  output, so ``|computed - exact| <= gamma_D * F_abs``, ``gamma_D = D u / (1 - D u)``, where ``F_abs`` is the
  program evaluated with every input and constant replaced by its absolute value and every subtraction by an
  addition. A k-term sum or product printed left to right rounds k - 1 times on the path of its first term;
  a library sin/cos is counted as ``trig_roundings`` roundings (its error in ulps); constants that are not
  exactly representable in the working precision add one rounding. ``F_abs`` is the condition-related scale
  (it is large where terms cancel); ``D`` grows with the operation count along the recursion.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..equations._derive import Equations


@dataclass(frozen=True)
class Reference:
    """The exact value ``hi + lo`` (double-double) of one quantity, shape ``(batch, *shape)``."""

    hi: np.ndarray
    lo: np.ndarray


def _signature(eqs: Equations, names: Sequence[str]) -> tuple[str, ...]:
    """The state arguments that the named quantities take, in a fixed order."""
    args: list[str] = []
    for n in names:
        for a in eqs.quantities[n].args:
            if a not in args:
                args.append(a)
    return tuple(args)


def _flat_symbols(eqs: Equations, args: Sequence[str]) -> list[sp.Symbol]:
    return [s for a in args for s in eqs.arguments[a].symbols] + list(eqs.param_symbols)


def _flat_values(eqs: Equations, args: Sequence[str], state: Mapping[str, np.ndarray], params, batch: int) -> list:
    cols = []
    for a in args:
        x = np.asarray(state[a], dtype=float).reshape(batch, -1)
        cols.extend(x[:, k] for k in range(x.shape[1]))
    p = np.asarray(params, dtype=float).reshape(-1)
    cols.extend(np.full(batch, v) for v in p)
    return cols


def _batch(eqs: Equations, args: Sequence[str], state: Mapping[str, np.ndarray]) -> int:
    a = args[0]
    return int(np.asarray(state[a]).size // int(np.prod(eqs.arguments[a].shape)))


# ---------------------------------------------------------------------------------------------- mpmath
def mp_function(eqs: Equations, names: Sequence[str]):
    """``f(*inputs) -> list of mpf``: the named quantities' outputs (concatenated, row-major) as a function of
    the flat state symbols of :func:`_signature` followed by the parameters, printed by sympy's mpmath
    printer with the program's assignments as common subexpressions."""
    args = _signature(eqs, names)
    program = eqs.program(names)
    outputs = [sp.sympify(e) for n in names for e in eqs.quantities[n].outputs]
    return sp.lambdify(_flat_symbols(eqs, args), outputs, modules="mpmath", cse=lambda exprs: (program, exprs))


def mp_reference(
    eqs: Equations,
    names: Sequence[str],
    state: Mapping[str, np.ndarray],
    params,
    *,
    dps: int = 50,
    function=None,
) -> dict[str, Reference]:
    """The named quantities at a batch of states, exact to ``dps`` digits, as double-doubles.

    ``state`` maps argument names (``q``, ``qd``, ...) to arrays of shape ``(batch, n)``; ``params`` is the
    parameter vector (``eqs.parameters`` order). ``function`` reuses a :func:`mp_function`.
    """
    import mpmath

    names = tuple(names)
    args = _signature(eqs, names)
    batch = _batch(eqs, args, state)
    f = function or mp_function(eqs, names)
    cols = _flat_values(eqs, args, state, params, batch)
    sizes = [len(eqs.quantities[n].outputs) for n in names]
    hi = np.empty((batch, sum(sizes)))
    lo = np.empty((batch, sum(sizes)))
    with mpmath.workdps(dps):
        for b in range(batch):
            values = f(*(mpmath.mpf(float(c[b])) for c in cols))
            for k, v in enumerate(values):
                v = mpmath.mpf(v)
                h = float(v)
                hi[b, k] = h
                lo[b, k] = float(v - h)
    out, start = {}, 0
    for n, size in zip(names, sizes):
        shape = (batch, *eqs.quantities[n].shape)
        out[n] = Reference(hi[:, start:start + size].reshape(shape), lo[:, start:start + size].reshape(shape))
        start += size
    return out


def abs_error(computed, ref: Reference) -> np.ndarray:
    """``|computed - (hi + lo)|`` entrywise, accurate far below float64 round-off of the result."""
    c = np.asarray(computed, dtype=np.float64)
    return np.abs((c - ref.hi) - ref.lo)


def rel_error(computed, ref: Reference, axes: tuple[int, ...] | None = None) -> np.ndarray:
    """Normwise relative error per state: ``||computed - exact|| / ||exact||`` over the quantity's entries."""
    err = abs_error(computed, ref)
    if axes is None:
        axes = tuple(range(1, err.ndim))
    num = np.sqrt(np.sum(err**2, axis=axes))
    den = np.sqrt(np.sum(ref.hi**2, axis=axes))
    return num / np.maximum(den, np.finfo(float).tiny)


# ---------------------------------------------------------------------------------------------- NumPy
class _Evaluator:
    """Interprets SymPy expressions over arrays; ``abs_mode`` evaluates the absolute-value program and the
    number of roundings along the longest path instead (see :func:`error_bound`)."""

    def __init__(self, values: dict, *, abs_mode=False, trig_roundings=2, inexact_constant=None):
        self.values = values  # Symbol -> array (abs_mode: (array, depth))
        self.abs_mode = abs_mode
        self.trig_roundings = trig_roundings
        self.inexact_constant = inexact_constant  # abs_mode: float -> bool, not representable in the precision

    def __call__(self, e):
        if self.abs_mode:
            return self._abs(e)
        return self._eval(e)

    def _eval(self, e):
        if e.is_Symbol:
            return self.values[e]
        if e.is_Number:
            return float(e)
        if e.is_Add:
            args = e.args
            out = self._eval(args[0])
            for a in args[1:]:
                out = out + self._eval(a)
            return out
        if e.is_Mul:
            args = e.args
            out = self._eval(args[0])
            for a in args[1:]:
                out = out * self._eval(a)
            return out
        if e.is_Pow and e.exp.is_Integer:
            return self._eval(e.base) ** int(e.exp)
        if isinstance(e, sp.sin):
            return np.sin(self._eval(e.args[0]))
        if isinstance(e, sp.cos):
            return np.cos(self._eval(e.args[0]))
        if isinstance(e, sp.sign):  # the drives' Coulomb friction
            return np.sign(self._eval(e.args[0]))
        raise NotImplementedError(f"cannot evaluate {type(e).__name__} in {e}")

    def _abs(self, e):
        """(|e|, number of roundings on the longest path), with inputs exact."""
        if e.is_Symbol:
            return self.values[e]
        if e.is_Number:
            x = float(e)
            exact = e.is_Integer or not self.inexact_constant(x)
            return abs(x), 0 if exact else 1
        if e.is_Add or e.is_Mul:
            parts = [self._abs(a) for a in e.args]
            out = parts[0][0]
            for v, _ in parts[1:]:
                out = out + v if e.is_Add else out * v
            return out, max(d for _, d in parts) + len(parts) - 1
        if e.is_Pow and e.exp.is_Integer and int(e.exp) > 0:
            v, d = self._abs(e.base)
            return v ** int(e.exp), d + int(e.exp) - 1
        if e.is_Pow:  # a quotient amplifies the error of its denominator: not a polynomial program
            raise NotImplementedError(f"the bound holds for programs of +, x and sin/cos; got the power {e}")
        if isinstance(e, (sp.sin, sp.cos)):
            x = self._eval_plain(e.args[0])
            v = np.abs(np.sin(x) if isinstance(e, sp.sin) else np.cos(x))
            return v, self.trig_roundings
        raise NotImplementedError(f"cannot bound {type(e).__name__} in {e}")

    def _eval_plain(self, e):
        if not e.is_Symbol:
            raise NotImplementedError(f"the error bound assumes sin/cos of an input, got {e}")
        return self.plain[e]


def evaluate(
    eqs: Equations,
    names: Sequence[str],
    state: Mapping[str, np.ndarray],
    params,
) -> dict[str, np.ndarray]:
    """The named quantities at a batch of states (``(batch, n)`` arrays, real or complex) with NumPy:
    ``{name: (batch, *shape)}``. Nothing is compiled."""
    names = tuple(names)
    args = _signature(eqs, names)
    batch = _batch(eqs, args, state)
    values: dict = {}
    for a in args:
        x = np.asarray(state[a]).reshape(batch, -1)
        values.update({s: x[:, k] for k, s in enumerate(eqs.arguments[a].symbols)})
    p = np.asarray(params).reshape(-1)
    values.update({s: p[k] for k, s in enumerate(eqs.param_symbols)})
    ev = _Evaluator(values)
    for s, e in eqs.program(names):
        values[s] = ev(e)
    out = {}
    for n in names:
        qty = eqs.quantities[n]
        cols = [np.broadcast_to(ev(sp.sympify(e)), (batch,)) for e in qty.outputs]
        out[n] = np.stack(cols, axis=-1).reshape((batch, *qty.shape))
    return out


def error_bound(
    eqs: Equations,
    names: Sequence[str],
    state: Mapping[str, np.ndarray],
    params,
    *,
    dtype=np.float64,
    trig_roundings: int = 2,
) -> dict[str, np.ndarray]:
    """``gamma_D * F_abs`` per output entry (module docstring): a bound on ``|computed - exact|`` for any
    evaluation of the program in ``dtype`` at these (exactly representable) inputs, ``{name: (batch, *shape)}``.

    ``trig_roundings`` is the error of the sin/cos implementation in units of ``u`` (2: within one ulp).
    """
    names = tuple(names)
    u = float(np.finfo(dtype).eps) / 2
    args = _signature(eqs, names)
    batch = _batch(eqs, args, state)

    def inexact(x: float) -> bool:
        return float(np.asarray(x, dtype=dtype)) != x

    plain: dict = {}
    values: dict = {}
    for a in args:
        x = np.asarray(state[a], dtype=float).reshape(batch, -1)
        for k, s in enumerate(eqs.arguments[a].symbols):
            plain[s] = x[:, k]
            values[s] = (np.abs(x[:, k]), 0)
    p = np.asarray(params, dtype=float).reshape(-1)
    for k, s in enumerate(eqs.param_symbols):
        values[s] = (abs(float(p[k])), 0)
    ev = _Evaluator(values, abs_mode=True, trig_roundings=trig_roundings, inexact_constant=inexact)
    ev.plain = plain
    for s, e in eqs.program(names):
        values[s] = ev(e)
    out = {}
    for n in names:
        qty = eqs.quantities[n]
        cols = []
        for e in qty.outputs:
            v, d = ev(sp.sympify(e))
            gamma = d * u / (1 - d * u)
            cols.append(np.broadcast_to(gamma * np.asarray(v, dtype=float), (batch,)))
        out[n] = np.stack(cols, axis=-1).reshape((batch, *qty.shape))
    return out
