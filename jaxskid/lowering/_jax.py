"""Lowering: print :class:`~jaxskid._equations.Equations` as a JAX module, cache it on disk, load it.

This is the only stage that knows both SymPy and JAX. The generated module has one pure function per
quantity, ``name(*state, p) -> array``, for a single state; batching is ``jax.vmap``'s job.

Output form. How the result array is assembled decides how fast XLA on CPU runs the function in a batch.
``python benchmarks/output_forms.py`` measures the forms on the Panda (float64, batch 65536, per state):

- ``jnp.stack`` / ``jnp.array([...])`` of the entries: XLA computes each distinct entry in a kernel of
  its own that redoes the shared work (mass matrix 710 ns);
- one chain ``jnp.where(index == k, value_k, out)`` over the flattened entries: the shared work is
  hoisted out of the loop over entries, but every entry runs the whole chain of compares and selects
  against an index held in memory, n^2 selects for n entries (260 ns);
- nested chains, one per axis, on ``lax.broadcasted_iota`` of that axis: the innermost index is a loop
  constant after unrolling, so those selects fold away, and the outer chains select whole rows (160 ns;
  66 ns with the fusible sine and cosine of :mod:`jaxskid.lowering._helpers_source`);
- the same, with every input entry first broadcast to the output's shape (what is generated): every
  operation is then elementwise on one shape, so XLA's estimate of how often a shared value would be
  recomputed stays low and the whole function is one kernel (mass matrix 57 ns; Coriolis matrix 570
  against 780 ns at batch 16384, one kernel instead of 153). The shared work still runs once per state:
  it depends only on the state, and LLVM hoists it out of the loops over the entries.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import tempfile
from collections.abc import Sequence
from pathlib import Path

import sympy as sp
from sympy.printing.numpy import JaxPrinter
from sympy.printing.precedence import PRECEDENCE

from ..equations._derive import Equations, Options, derive, resolve
from ._helpers_source import SOURCE as HELPERS_SOURCE
from ..model._robot import Robot
from ._printing import NumberTweaks

log = logging.getLogger("jaxskid")

GENERATOR_VERSION = "4"
_CHECK_PREFIX = "# jaxskid-checksum: "


class _Printer(NumberTweaks, JaxPrinter):
    """JAX printer with the shared number rules (:class:`jaxskid._printing.NumberTweaks`): plain Python
    float literals are weakly typed, so constants take the inputs' dtype."""

    _sqrt_name = "jax.numpy.sqrt"

    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False})

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.args
        if exp.is_Integer and -8 <= int(exp) < 0 or exp == -sp.Rational(1, 2):  # 1/x by Newton (_helpers_source)
            return f"_recip({self._print(sp.Pow(base, -exp, evaluate=False))})"
        return super()._print_Pow(expr, rational)

    def _print_Mul(self, expr):
        # sympy prints a/b for negative powers inside a product; keep them as factors so that
        # _print_Pow turns them into _recip
        factors = [self._print_Pow(f) if f.is_Pow and f.exp.is_Rational and f.exp < 0 else None for f in expr.args]
        if not any(factors):
            return super()._print_Mul(expr)
        rest = sp.Mul(*[f for f, printed in zip(expr.args, factors) if printed is None], evaluate=False)
        parts = [p for p in factors if p] + ([self.parenthesize(rest, PRECEDENCE["Mul"])] if rest != 1 else [])
        return "*".join(parts)

    def _print_sin(self, expr):
        return f"_sin({self._print(expr.args[0])})"

    def _print_cos(self, expr):
        return f"_cos({self._print(expr.args[0])})"


def _index_expr(arg: str, shape: tuple[int, ...], k: int) -> str:
    if len(shape) == 1:
        return f"{arg}[{k}]"
    idx = []
    for d in reversed(shape):
        idx.append(k % d)
        k //= d
    return f"{arg}[{', '.join(str(i) for i in reversed(idx))}]"


def _assemble(shape: tuple[int, ...], outputs: list, rename: dict, printer: _Printer, dtype: str) -> list[str]:
    """Lines that build the output array (see the module docstring) and return it."""
    if not shape:
        value = "0.0" if outputs[0] == 0 else printer.doprint(outputs[0].xreplace(rename))
        return [f"return jnp.zeros((), {dtype}) + {value}"]
    shape = tuple(shape)
    lines = [f"_z = jnp.zeros({shape!r}, {dtype})"]
    lines += [f"_i{a} = jax.lax.broadcasted_iota(jnp.int32, {shape!r}, {a})" for a in range(len(shape))]
    stride = [1] * len(shape)
    for a in reversed(range(len(shape) - 1)):
        stride[a] = stride[a + 1] * shape[a + 1]
    count = [0]

    def build(axis: int, offset: int) -> str:
        """Expression for the block of entries from ``offset`` that share the indices before ``axis``."""
        acc = "_z"
        for i in range(shape[axis]):
            k = offset + i * stride[axis]
            if axis == len(shape) - 1:
                e = outputs[k]
                if e == 0:
                    continue
                value = printer.doprint(e.xreplace(rename))
            else:
                value = build(axis + 1, k)
                if value == "_z":
                    continue
                if len(value) > 60:  # name a nested block once rather than repeat it inline
                    count[0] += 1
                    lines.append(f"_b{count[0]} = {value}")
                    value = f"_b{count[0]}"
            acc = f"jnp.where(_i{axis} == {i}, {value}, {acc})"
        return acc

    lines.append(f"return {build(0, 0)}")
    return lines


def function_source(eqs: Equations, name: str, printer: _Printer | None = None) -> str:
    """Source of one quantity: ``_name(*args, p, spread)``, the program (``spread`` broadcasts each input
    entry to the output's shape, or is the identity), and ``name(*args, p)``, the ``jax.custom_jvp``
    that runs it broadcast and differentiates it unbroadcast (see the module docstring and
    :mod:`jaxskid.lowering._helpers_source`)."""
    printer = printer or _Printer()
    qty = eqs.quantities[name]
    prog = eqs.program([name])
    rename = {s: sp.Symbol(f"_p{k}", real=True) for k, s in enumerate(eqs.param_symbols)}
    used: set = set()
    for _, e in prog:
        used |= e.free_symbols
    for e in qty.outputs:
        used |= sp.sympify(e).free_symbols
    args = [*qty.args, "p"]
    shape = tuple(qty.shape)
    lines = [f"def _{name}({', '.join(args)}, spread):"]
    for a in qty.args:
        arg = eqs.arguments[a]
        for k, s in enumerate(arg.symbols):
            if s in used:
                lines.append(f"    {s.name} = spread({_index_expr(a, arg.shape, k)})")
    for k, s in enumerate(eqs.param_symbols):
        if s in used:
            lines.append(f"    _p{k} = spread(p[{k}])")
    for s, e in prog:
        lines.append(f"    {s.name} = {printer.doprint(e.xreplace(rename))}")
    lines.extend("    " + line for line in _assemble(qty.shape, [sp.sympify(e) for e in qty.outputs], rename,
                                                  printer, f"jnp.result_type({qty.args[0]}, p)"))
    lines += [
        "",
        "",
        "@jax.custom_jvp",
        f"def {name}({', '.join(args)}):",
        f'    """{qty.equation}: {qty.doc}"""',
        f"    return _{name}({', '.join(args)}, {'_spread(' + repr(shape) + ')' if shape else '_same'})",
        "",
        "",
        f"{name}.defjvp(_plain_jvp(_{name}))",
    ]
    return "\n".join(lines) + "\n"


def module_source(eqs: Equations, names: Sequence[str], key: str) -> str:
    """A complete generated module for the named quantities, with metadata and a checksum."""
    robot = eqs.robot
    meta = {
        "robot": robot.name,
        "key": key,
        "joint_names": list(robot.joint_names),
        "frame_names": list(robot.frame_names),
        "end_effectors": list(robot.end_effectors),
        "parameters": list(eqs.parameters),
        "defaults": robot.default_params(),
        "quantities": {
            n: {"args": list(eqs.quantities[n].args), "shape": list(eqs.quantities[n].shape),
                "equation": eqs.quantities[n].equation, "doc": eqs.quantities[n].doc}
            for n in names
        },
    }
    header = [
        f"# Generated by jaxskid (generator {GENERATOR_VERSION}) for robot {robot.name!r}.",
        f"# Quantities: {', '.join(names)}.",
        "# Each function takes the state arrays named in its signature, shape (n,), and p, the parameter",
        "# vector in the order of METADATA['parameters']; it returns one array. Batch with jax.vmap.",
        "import jax",
        "import jax.numpy as jnp",
        HELPERS_SOURCE,
        f"METADATA = {json.dumps(meta, sort_keys=True)}",
        "",
    ]
    printer = _Printer()
    body = "\n\n".join(function_source(eqs, n, printer) for n in names)
    text = "\n".join(header) + "\n" + body
    return text + _CHECK_PREFIX + hashlib.sha256(text.encode()).hexdigest() + "\n"


def cache_dir() -> Path:
    """Where generated modules are cached: ``$JAXSKID_CACHE_DIR``, else ``~/.cache/jaxskid``."""
    env = os.environ.get("JAXSKID_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "jaxskid"


def request_key(robot: Robot, names: Sequence[str], options: Options | None = None) -> str:
    h = hashlib.sha256()
    h.update(GENERATOR_VERSION.encode())
    h.update(robot.fingerprint().encode())
    h.update(repr(tuple(names)).encode())
    h.update(repr(options or Options()).encode())
    h.update(repr(sorted(robot.default_params().items())).encode())  # the module's METADATA holds the defaults
    return h.hexdigest()


def _load_source(text: str, origin: str) -> dict:
    body, sep, tail = text.rpartition(_CHECK_PREFIX)
    if not sep or tail.strip() != hashlib.sha256(body.encode()).hexdigest():
        raise ValueError("checksum mismatch")
    namespace: dict = {"__name__": f"jaxskid_generated_{Path(origin).stem.replace('-', '_')}"}
    exec(compile(text, origin, "exec"), namespace)  # noqa: S102 - our own generated, checksummed code
    return namespace


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)  # atomic: concurrent writers of the same entry each leave a whole file
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def generate_module(
    robot: Robot,
    quantities: Sequence[str] | str | None = None,
    *,
    cache: bool = True,
    directory: Path | str | None = None,
    options: Options | None = None,
    progress: bool = False,
) -> tuple[dict, str, Path | None]:
    """Derive (or fetch from the cache) and load the JAX module of the requested quantities.

    Returns ``(namespace, source, path)``. A cached entry that is truncated, corrupted or stale is
    regenerated.
    """
    names = resolve(robot, quantities)
    key = request_key(robot, names, options)
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", robot.name)[:40] or "robot"
    path = Path(directory or cache_dir()) / f"{stem}-{key[:20]}.py" if cache else None
    if path is not None and path.exists():
        try:
            text = path.read_text()
            ns = _load_source(text, str(path))
            if ns["METADATA"]["key"] == key:
                log.debug("jaxskid: loaded %s from the cache", path)
                return ns, text, path
        except Exception as exc:  # corrupted entry: fall through and regenerate
            log.warning("jaxskid: cache entry %s is unreadable (%s); regenerating", path, exc)
    eqs = derive(robot, names, options=options, progress=progress)
    text = module_source(eqs, names, key)
    ns = _load_source(text, str(path) if path else "<jaxskid>")
    if path is not None:
        try:
            _write_atomic(path, text)
        except OSError as exc:
            log.warning("jaxskid: could not write the cache entry %s (%s)", path, exc)
    return ns, text, path
