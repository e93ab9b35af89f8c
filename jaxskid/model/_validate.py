"""Validation of a robot model, in one place.

:meth:`Robot.create <jaxskid.Robot.create>` runs :func:`check_model` on what it is given, before fixed joints
are merged, so that an error names the caller's own index: ``joints[2].inertia``, ``frames[0].offset[3]``,
``defaults.m1``. Readers of description files parse scalars with :func:`to_expr` (the one parser of
numbers and expressions), check only the syntax and the forms that never reach the model (a quaternion, a
3x3 inertia, a ``mass`` key) with the functions below, and map the model's ``where`` back to their keys.

The rules and their tolerances:

* a scalar is a finite real number, or an arithmetic expression of numbers, parameter names and the
  elementary functions every code generator prints (:mod:`jaxskid.model._scalars`; no attribute access),
  of magnitude at most :data:`LARGEST`;
* a revolute screw ``(omega, v)`` has a unit ``omega`` and ``omega . v = 0`` (no pitch); a prismatic one
  has ``omega = 0`` and a unit ``v``, within :data:`TOL`;
* a pose is ``[[R, p], [0, 1]]`` with ``R^T R = 1`` within :data:`TOL` and ``det R = +1``;
* a mass-inertia matrix is symmetric, of the form ``[[I_o, m c~], [-m c~, m 1]]`` (within
  :data:`SYMMETRY_TOL`, relative), with ``m = 0`` or ``m >=`` :data:`SMALLEST` and a positive semi-definite
  rotational inertia about the centre of mass (eigenvalues above ``-EIGEN_TOL`` times the inertia's scale);
* a drive belongs to a moving joint, and its armature, viscous and Coulomb friction are not negative;
* parents come before their children and form no cycle; names are unique.

Checks that need numbers use the parameters' default values; with a parameter that has none, the check
is skipped.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from .._errors import ModelError
from ._scalars import ALLOWED, float_value, folded, unsupported

TOL = 1e-6
"""Unit axes and quaternions, orthonormal rotations, ``omega . v`` of a revolute screw."""
SYMMETRY_TOL = 1e-12
"""Relative: mirrored entries and the block structure of a numeric mass-inertia matrix."""
EIGEN_TOL = 1e-9
"""Relative to the inertia's scale: how negative an eigenvalue of a rotational inertia may be (round-off)."""
LARGEST = 1e30
"""Larger numbers are mistakes in any unit system, and overflow the numeric checks."""
SMALLEST = 1e-30
"""Smaller nonzero masses are mistakes in any unit system; their products underflow (in float32 first)."""

_ARITHMETIC = re.compile(r"[A-Za-z0-9_+\-*/^().,\s]*")
_DECIMAL = re.compile(r"(\d+\.\d*|\.\d+)([eE][+-]?\d+)?")
# Names that must parse as symbols rather than SymPy's built-ins (S, N, E, I, Q, O, beta, gamma...).
_SYMPIFY_LOCALS = {n: sp.Symbol(n, real=True) for n in ("S", "N", "E", "I", "Q", "O", "beta", "gamma", "zeta", "lambda_")}
_SYMPIFY_LOCALS["pi"] = sp.pi


def symbol(name: str) -> sp.Symbol:
    """The SymPy symbol jaxskid uses for the parameter ``name`` (real-valued)."""
    return sp.Symbol(name, real=True)


def describe_value(value) -> str:
    """What a value from a file or an argument is, for a message: ``the number 1.5``, ``a list of 2 items``."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, list):
        return f"a list of {len(value)} item{'s' if len(value) != 1 else ''}"
    if isinstance(value, Mapping):
        return f"a mapping with keys {', '.join(map(str, value)) or '(none)'}"
    return f"a {type(value).__name__}"


# ---------------------------------------------------------------------------------------------- scalars
def to_expr(value, *, where: str = "") -> sp.Expr:
    """A SymPy expression from a number, a string or an expression; symbols become real symbols.

    Strings may hold arithmetic on numbers, names and function calls only (no attribute access, no
    dunder names), so parsing never runs arbitrary code; their decimal literals become double-precision
    floats. Floats with an integer value become exact integers, so that structural zeros and ones stay
    exact in the derivation. Raises :class:`ModelError` at ``where`` for anything that is not a finite
    real scalar (see the module docstring).
    """
    if isinstance(value, bool):
        raise ModelError(f"expected a number or an expression, got {describe_value(value)}", where=where)
    expr = _parse(value, where) if isinstance(value, str) else _sympify(value, where)
    if isinstance(expr, sp.MatrixBase) or not isinstance(expr, sp.Expr):
        raise ModelError(f"expected a scalar number or expression, got {value!r}", where=where)
    expr = _realify(expr)
    _check_scalar(expr, value, where)
    return folded(expr)


def _sympify(value, where):
    try:
        return sp.sympify(value)
    except Exception:  # noqa: BLE001 - sympify fails in many ways on what it cannot read
        raise ModelError(f"expected a number or a symbolic expression, got {value!r}", where=where) from None


def _parse(text: str, where: str):
    if not text.strip() or not _ARITHMETIC.fullmatch(text) or "__" in text or "." in _DECIMAL.sub("", text):
        raise ModelError(f"expected an arithmetic expression of numbers and parameter names, got {text!r}",
                         where=where)
    try:  # unevaluated first: SymPy computes 10**10**10 exactly while it parses (module _scalars)
        raw = sp.sympify(text, locals=_SYMPIFY_LOCALS, evaluate=False)
        _check_parts(raw, text, where)
        if isinstance(raw, sp.Basic) and float_value(raw) == math.inf:
            raise ModelError(f"expected a finite real value, got {text!r} (beyond the range of a double)", where=where)
        expr = sp.sympify(text, locals=_SYMPIFY_LOCALS)
    except ModelError:
        raise
    except Exception as exc:  # noqa: BLE001 - sympify fails in many ways on malformed text
        raise ModelError(f"cannot parse {text!r} as an expression ({type(exc).__name__})", where=where) from None
    if isinstance(expr, sp.Basic):
        floats = {f: sp.Float(float(f)) for f in expr.atoms(sp.Float) if f._prec != 53}
        expr = expr.xreplace(floats) if floats else expr
    return expr


def _realify(expr):
    subs: dict = {s: symbol(s.name) for s in expr.free_symbols if not s.is_real}
    for f in expr.atoms(sp.Float):
        x = float(f)
        if math.isfinite(x) and x == int(x) and abs(x) < 2**53:
            subs[f] = sp.Integer(int(x))
    return expr.xreplace(subs) if subs else expr


def _check_parts(expr, value, where: str) -> None:
    bad = unsupported(expr) if isinstance(expr, sp.Basic) else None
    if bad is not None and bad.startswith("imaginary"):
        raise ModelError(f"expected a real value, got {value!r}", where=where)
    if bad is not None:
        kind = "" if bad.startswith("unknown") else "unsupported "
        raise ModelError(f"{kind}{bad} in {value!r}; expressions may use {ALLOWED}", where=where)


def _check_scalar(expr: sp.Expr, value, where: str) -> None:
    if expr.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
        raise ModelError(f"expected a finite value, got {value!r}", where=where)
    _check_parts(expr, value, where)
    if any(s.name.lower() in ("inf", "infinity", "nan") for s in expr.free_symbols):
        raise ModelError(f"expected a finite value, got {value!r}", where=where)
    if expr.free_symbols:
        return
    if expr.is_extended_real is False:
        raise ModelError(f"expected a real value, got {value!r}", where=where)
    x = float_value(expr)
    if x is None or math.isfinite(x):  # None: a part float_value does not evaluate
        try:
            x = float(expr)
        except (TypeError, ValueError, OverflowError):
            x = math.inf
    if not math.isfinite(x):
        raise ModelError(f"expected a finite real value, got {value!r}", where=where)
    if abs(x) > LARGEST:
        raise ModelError(f"expected a magnitude of at most {LARGEST:g} (check the units), got {value!r}", where=where)


def numeric(expr, values: Mapping) -> float | None:
    """The value of ``expr`` with ``values`` (symbol -> number) put in, or None if a symbol has none; ``inf`` or
    ``nan`` where it overflows or is not a real number."""
    e = sp.sympify(expr)
    x = float_value(e, values)
    if x is not None and not math.isfinite(x):
        return x  # inf where a part overflows (SymPy would compute its digits), nan where it is not real
    if e.free_symbols:
        e = sp.sympify(e.xreplace(values))
        if e.free_symbols:
            return None
    try:
        return float(e)
    except (TypeError, ValueError, OverflowError):
        return None


# ---------------------------------------------------------------------------------------------- rules
def check_unit(vector: Sequence, values: Mapping, where: str, what: str) -> None:
    """A unit vector (when its entries have values): ``expected a unit <what>, got norm ...``."""
    xs = [numeric(e, values) for e in vector]
    if None not in xs:
        norm = math.sqrt(sum(x * x for x in xs))
        if abs(norm - 1.0) > TOL:
            raise ModelError(f"expected a unit {what}, got norm {norm:.6g}", where=where)


def check_mass(mass: float | None, where: str, entry: str = "") -> None:
    """A non-negative mass (None: unknown, not checked); ``entry`` names where it sits in a matrix."""
    if mass is not None and mass < 0:
        raise ModelError(f"expected a non-negative mass{entry}, got {mass:.6g}", where=where)
    if mass is not None and 0 < mass < SMALLEST:
        raise ModelError(f"expected a mass{entry} of 0 or at least {SMALLEST:g} (check the units), got {mass:.6g}",
                         where=where)


def check_positive_semidefinite(i3: np.ndarray, scale: float, where: str, what: str, hint: str = "") -> None:
    """A 3x3 rotational inertia with no eigenvalue below ``-EIGEN_TOL * scale`` (``hint`` ends the message)."""
    ev = np.linalg.eigvalsh(i3)
    if ev.min() < -EIGEN_TOL * scale:
        raise ModelError(f"expected a {what}, got eigenvalues {np.round(ev, 9).tolist()}{hint}", where=where)


def differ(a, b) -> bool:
    """Whether two entries differ: exactly when symbolic, beyond :data:`SYMMETRY_TOL` when numbers."""
    a, b = sp.sympify(a), sp.sympify(b)
    if a.is_Number and b.is_Number:
        x, y = float(a), float(b)
        return abs(x - y) > SYMMETRY_TOL * max(1.0, abs(x), abs(y))
    return not sp.expand(a - b).is_zero


def check_symmetric(m: sp.Matrix, where: str, what: str) -> None:
    for r in range(m.rows):
        for c in range(r + 1, m.cols):
            if differ(m[r, c], m[c, r]):
                raise ModelError(f"expected a symmetric {what}; entries [{r}][{c}] and [{c}][{r}] differ", where=where)


def check_rotation(r: sp.Matrix, values: Mapping, where: str) -> None:
    """An orthonormal 3x3 matrix with determinant +1 (when its entries have values)."""
    xs = [numeric(e, values) for e in r]
    if None in xs:
        return
    a = np.array(xs, dtype=float).reshape(3, 3)
    if not np.allclose(a.T @ a, np.eye(3), atol=TOL, rtol=0) or np.linalg.det(a) < 0:
        raise ModelError(f"expected a rotation matrix (orthonormal, determinant +1), got {a.round(6).tolist()}",
                         where=where)


def check_pose(c: sp.Matrix, values: Mapping, where: str) -> None:
    """``[[R, p], [0, 0, 0, 1]]`` with ``R`` a rotation; the last row is reported at ``where[3]``."""
    if [c[3, k] for k in range(4)] != [0, 0, 0, 1]:
        raise ModelError(f"expected the last row of a pose to be [0, 0, 0, 1], got {list(c[3, :])}",
                         where=f"{where}[3]")
    check_rotation(c[:3, :3], values, where)


def check_screw(kind: str, screw: Sequence, values: Mapping, where: str) -> None:
    """Unit screw coordinates ``(omega, v)`` of a revolute (no pitch) or prismatic joint."""
    w, v = screw[:3], screw[3:]
    if kind == "prismatic":
        if any(numeric(e, values) is None or abs(numeric(e, values)) > TOL for e in w):
            raise ModelError("expected zero angular part (omega) for a prismatic joint", where=where)
        check_unit(v, values, where, "translation axis (omega = 0: a prismatic joint)")
        return
    check_unit(w, values, where, "rotation axis omega")
    xs = [numeric(e, values) for e in screw]
    if None not in xs and abs(np.dot(xs[:3], xs[3:])) > TOL:
        raise ModelError(f"expected a revolute screw (omega . v = 0) or a prismatic one (omega = 0), got "
                         f"omega . v = {np.dot(xs[:3], xs[3:]):.6g} (a helical joint)", where=where)


def check_mass_inertia(m6: sp.Matrix, values: Mapping, where: str) -> None:
    """A 6x6 mass-inertia matrix ``[[I_o, m c~], [-m c~, m 1]]`` about the body frame's origin."""
    check_symmetric(m6, where, "6x6 matrix")
    for r in range(3):
        for c in range(3):
            if differ(m6[3 + r, 3 + c], m6[5, 5] if r == c else 0):
                raise ModelError(f"expected the lower-right 3x3 block to be mass * identity; entry [{3 + r}][{3 + c}] "
                                 "is not", where=where)
        for c in range(r, 3):
            if differ(m6[r, 3 + c], -m6[c, 3 + r]):
                raise ModelError(f"expected the upper-right 3x3 block to be skew-symmetric (m c~); entry [{r}][{3 + c}] "
                                 "is not", where=where)
    check_mass(numeric(m6[5, 5], values), where, " (entry [5][5])")
    xs = [numeric(e, values) for e in m6]
    if None in xs:
        return
    with np.errstate(all="ignore"):
        a = np.array(xs, dtype=float).reshape(6, 6)
        if not np.all(np.isfinite(a)):
            k = int(np.flatnonzero(~np.isfinite(a))[0])
            raise ModelError(f"expected finite real values at the parameters' defaults, got {m6[k]} = {a.flat[k]}",
                             where=where)
        if np.abs(a).max() > LARGEST:
            raise ModelError("expected finite mass-inertia values of a physical size", where=where)
        m = a[5, 5]
        if m == 0:
            check_positive_semidefinite(a[:3, :3], float(np.abs(a).max()), where,
                                        "positive semi-definite inertia for a massless body")
            return
        c = np.array([a[2, 4], a[0, 5], a[1, 3]]) / m  # the m c~ block, (omega, v) order
        cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
        # about the centre of mass, relative to I_o, which holds the m c^2 terms and their round-off
        check_positive_semidefinite(a[:3, :3] + m * cx @ cx, float(np.abs(a[:3, :3]).max()), where,
                                    "positive definite rotational inertia about the centre of mass")


def check_parents(parents: Sequence, *, first: int = 0, where: Callable[[int], str] = lambda i: f"joints[{i}].parent",
                  where_all: str | None = None) -> None:
    """Parent indices of a tree: body ``i + first`` hangs from body ``parents[i]``; ``first - 1`` is the world.

    Every index is in range, the parents form no cycle (reported at ``where_all``, else at the first body
    on it), and every parent comes before its children.
    """
    n, world = len(parents), first - 1
    for i, p in enumerate(parents):
        if not isinstance(p, int) or isinstance(p, bool) or not world <= p <= n - 1 + first:
            raise ModelError(f"expected a body index in {world}..{n - 1 + first} ({world} is the world), "
                             f"got {describe_value(p)}", where=where(i))
    for i in range(n):  # a chain of parents that comes back to a body is a cycle
        chain, body = [], i + first
        while body != world and body not in chain:
            chain.append(body)
            body = parents[body - first]
        if body != world:
            loop = " -> ".join(f"body {b}" for b in [*chain[chain.index(body):], body])
            raise ModelError(f"the parent indices form a cycle: {loop}", where=where_all or where(i))
    for i, p in enumerate(parents):
        if p > i - 1 + first:
            raise ModelError(f"body {i + first}'s parent is body {p}, which comes after it; list every body after "
                             f"its parent ({world} is the world)", where=where(i))


# ---------------------------------------------------------------------------------------------- the model
def check_model(joints: Sequence, frames: Sequence, gravity: Sequence, end_effectors: Sequence[str],
                defaults: Mapping[str, float], base: str) -> None:
    """Every invariant of a model, on normalised joints and frames (fixed joints not yet merged)."""
    _check_names(joints, frames, end_effectors, base)
    values = {symbol(k): v for k, v in defaults.items()}
    _check_real(gravity, values, "gravity")
    for i, j in enumerate(joints):
        where = f"joints[{i}]"
        _check_real(j.origin, values, f"{where}.origin")  # the inertia: check_mass_inertia
        _check_real(j.screw, values, f"{where}.screw")
        check_pose(j.origin, values, f"{where}.origin")  # first: a spatial description's screws depend on it
        if j.type != "fixed":
            check_screw(j.type, j.screw, values, f"{where}.screw")
        check_mass_inertia(j.inertia, values, f"{where}.inertia")
        if j.drive is not None:
            check_drive(j.type, j.drive, values, f"{where}.drive")
    for k, f in enumerate(frames):
        if not -1 <= f.body < len(joints):
            raise ModelError(f"expected a body index in -1..{len(joints) - 1}, got {f.body}", where=f"frames[{k}].body")
        check_pose(f.offset, values, f"frames[{k}].offset")


def _check_real(entries, values: Mapping, where: str) -> None:
    """Every entry whose parameters have defaults is a finite real number there (``sqrt(-m)`` with ``m = 1`` is
    not: the equations would compute nan)."""
    for e in entries:
        x = numeric(e, values)
        if x is not None and not math.isfinite(x):
            raise ModelError(f"expected finite real values at the parameters' defaults, got {e} = {x}", where=where)


def check_drive(kind: str, drive, values: Mapping, where: str) -> None:
    """A drive (:class:`~jaxskid.model._drive.Drive`) on a moving joint, with armature and friction ``>= 0``."""
    if kind == "fixed":
        raise ModelError("a fixed joint has no drive; remove the drive or make the joint move", where=where)
    for what in ("armature", "viscous", "coulomb"):
        x = numeric(getattr(drive, what), values)
        if x is not None and x < 0:
            raise ModelError(f"expected a non-negative {what} value, got {x:g}", where=f"{where}.{what}")


def _check_names(joints, frames, end_effectors, base) -> None:
    seen: dict[str, int] = {}
    for i, j in enumerate(joints):
        if j.name in seen:
            raise ModelError(f"duplicate joint name {j.name!r} (also joints[{seen[j.name]}])", where=f"joints[{i}].name")
        seen[j.name] = i
    links: set[str] = {base}
    for i, j in enumerate(joints):
        if j.link in links:
            raise ModelError(f"duplicate link name {j.link!r}", where=f"joints[{i}].link")
        links.add(j.link)
    for k, f in enumerate(frames):
        if f.name in links:
            raise ModelError(f"duplicate frame name {f.name!r}", where=f"frames[{k}].name")
        links.add(f.name)
    for e in end_effectors:
        if e not in links:
            raise ModelError(f"unknown end-effector frame {e!r}", where="end_effectors")


def check_defaults(defaults: Mapping) -> dict[str, float]:
    """Default parameter values as finite floats, reported at ``defaults.<name>``."""
    out = {}
    for k, v in defaults.items():
        try:
            x = math.nan if isinstance(v, bool) else float(sp.sympify(v))
        except Exception:  # noqa: BLE001 - whatever sympify or float cannot read is not a number
            x = math.nan
        if not math.isfinite(x):
            raise ModelError(f"expected a finite number, got {v!r}", where=f"defaults.{k}")
        out[str(k)] = x
    return out


def matrix(value, shape, where) -> sp.ImmutableMatrix:
    """The one reader of the model's matrices: a matrix of ``shape`` whose entries are read by :func:`to_expr`
    (strings too: never ``sympify``)."""
    rows = value.tolist() if isinstance(value, sp.MatrixBase) else value
    try:
        rows = [list(r) for r in rows]
    except TypeError:
        raise ModelError(f"expected a {shape[0]}x{shape[1]} matrix, got {value!r}", where=where) from None
    if len(rows) != shape[0] or any(len(r) != shape[1] for r in rows):
        got = f"{len(rows)}x{len(rows[0]) if rows else 0}"
        raise ModelError(f"expected a {shape[0]}x{shape[1]} matrix, got shape {got}", where=where)
    return sp.ImmutableMatrix(shape[0], shape[1], [to_expr(x, where=f"{where}[{r}][{c}]")
                                                   for r, row in enumerate(rows) for c, x in enumerate(row)])
