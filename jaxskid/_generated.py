"""The seam between lowering and the runtime: what a generated JAX module holds, as typed, frozen data.

:mod:`jaxskid.codegen._jax` prints a module, :mod:`jaxskid.lowering._cache` executes it and
:mod:`jaxskid.lowering._module` reads it into a :class:`GeneratedModule`; :class:`jaxskid.Dynamics` is built
from that object and reads no module namespace itself. The native C of the module's matrix-valued quantities
travels beside it as :class:`NativeSource` objects, and reaches the runtime as :class:`NativeBuild` objects
(:class:`jaxskid.lowering._ffi_build.NativeLibrary`), which build their library when first asked.

Nothing here imports JAX or SymPy: the codegen, lowering and runtime stages all use these types.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Protocol


class NativeKernel(NamedTuple):
    """One quantity of a native library: its name, the flat sizes and core ranks of its inputs (the
    parameters last), its output's flat size and rank."""

    name: str
    sizes: tuple[int, ...]
    cores: tuple[int, ...]
    n_out: int
    out_rank: int


class Statement(NamedTuple):
    """One line of a kernel's body over vectors of states: ``kind`` ``"unused"`` (``(void)name;``, an argument
    it does not read), ``"input"`` (``const V name = value;``, an entry of an argument), ``"define"`` (``const
    V name = value;``) or ``"output"`` (``out[name] = value;``); ``value`` is C in which ``@V@`` stands for the
    vector type, and ``reads`` names the variables it reads."""

    kind: str
    name: str
    value: str
    reads: tuple[str, ...]


class VectorKernel(NamedTuple):
    """A quantity's program over vectors of states (:func:`jaxskid.codegen._c.vector_kernel`): its arguments
    (``p`` last; the output ``out`` follows), its statements in order, and the flat indices of the outputs
    that are zero for every state."""

    args: tuple[str, ...]
    statements: tuple[Statement, ...]
    zeros: tuple[int, ...]


@dataclass(frozen=True)
class NativeSource:
    """The generated C of one native library (:func:`jaxskid.codegen._c.native_sources`): ``<stem>.h`` and
    ``<stem>.c``, the quantities it has a kernel for, whether it has the backward step of forward dynamics,
    and the programs of its functions over vectors of states by quantity (None for one that has no vector form:
    it calls a function the vector form lacks)."""

    stem: str
    header: str
    source: str
    backward: bool
    kernels: tuple[NativeKernel, ...]
    vectors: Mapping[str, VectorKernel | None]

    def as_dict(self) -> dict:
        """Plain data, as a generated module writes it (``NATIVE_C``)."""
        return {"stem": self.stem, "header": self.header, "source": self.source, "backward": self.backward,
                "kernels": tuple(tuple(k) for k in self.kernels),
                # one JSON string: a literal of many small tuples takes Python long to compile when the module loads
                "vectors": json.dumps({k: None if v is None else (v.args, v.statements, v.zeros)
                                       for k, v in self.vectors.items()}, separators=(",", ":"))}

    @classmethod
    def from_dict(cls, d: Mapping) -> NativeSource:
        return cls(d["stem"], d["header"], d["source"], bool(d["backward"]),
                   tuple(NativeKernel(k[0], tuple(k[1]), tuple(k[2]), k[3], k[4]) for k in d["kernels"]),
                   {k: None if v is None else VectorKernel(tuple(v[0]), tuple(Statement(a, b, c, tuple(r))
                                                                                for a, b, c, r in v[1]), tuple(v[2]))
                    for k, v in json.loads(d["vectors"]).items()})

    @property
    def quantities(self) -> tuple[str, ...]:
        """The quantities with a kernel in this library."""
        return tuple(k.name for k in self.kernels)

    @property
    def state_parts(self) -> tuple[str, ...]:
        """The pullbacks that also get a kernel of their state part, ``<name>_state`` (without the parameters'
        cotangent): every pullback kernel of a robot with parameters but :data:`WHOLE_PULLBACKS`."""
        return tuple(k.name for k in self.kernels
                     if k.name.endswith("_vjp") and k.name not in WHOLE_PULLBACKS and k.sizes[-1] > 0)

    @property
    def kkt(self) -> bool:
        """Whether it has the backward step of constrained forward dynamics: the backward step of forward
        dynamics and the vector forms of :data:`KKT_QUANTITIES`."""
        return self.backward and all(self.vectors.get(k) is not None for k in KKT_QUANTITIES)


GPU_ONLY = frozenset({"inverse_dynamics", "gravity_torques", "coriolis_torques"})
"""Vector quantities whose kernel serves on a GPU only: on CPU XLA fuses their programs with the caller's (the
CPU's C library leaves them out); on a GPU, XLA took far longer to compile their programs than NVRTC the
kernels."""


WHOLE_PULLBACKS = frozenset({"mass_matrix_vjp", "coriolis_matrix_vjp"})
"""Pullbacks whose native library has no kernel of their state part (``<name>_state``, without the parameters'
cotangent; :mod:`jaxskid.lowering._ffi`): the matrices', long programs (the G1's Coriolis matrix's the longest a
library builds) whose Jacobian with respect to the state alone nothing in jaxskid asks for."""

KKT_QUANTITIES = ("mass_matrix", "inverse_dynamics_vjp", "constraint_jacobian", "constraint_jacobian_vjp",
                  "constraint_drift_vjp", "constraint_residual_vjp")
"""The quantities whose C the native backward step of constrained forward dynamics is built from
(:mod:`jaxskid.lowering._ffi_kkt`): those of the backward step of forward dynamics, the constraint Jacobian and
the pullbacks of the constraint quantities."""


class NativeBuild(Protocol):
    """A native library the runtime may use (:class:`jaxskid.lowering._ffi_build.NativeLibrary`)."""

    sources: NativeSource

    def build(self) -> Path:
        """The path of the built library (built once per machine); raises when it cannot be built."""

    def cuda_image(self, name: str, dtype: str, arch: str, shared: bool = True) -> tuple[bytes, int]:
        """The compiled CUDA kernel of the quantity ``name`` for ``dtype`` (``"float32"``/``"float64"``) inputs
        on ``arch`` (``"sm_90"``), and its threads per block (compiled once per machine); ``shared``: for calls
        whose states share the parameters (:func:`constant_input`)."""

    def cuda_handler(self) -> Path:
        """The path of the library of the XLA FFI handler that launches the CUDA kernels."""

    def cuda_rollout_image(self, vectors: Mapping[str, VectorKernel | None], n: int, n_params: int, steps: int,
                           dtype: str, arch: str, part: str, shared: bool = True) -> tuple[bytes, int]:
        """The compiled CUDA kernel ``part`` (:data:`ROLLOUT_PARTS`) of an RK4 rollout of ``steps`` steps under
        held torques (:mod:`jaxskid.lowering._cuda_rollout`), from the vector programs ``vectors`` of a robot of
        ``n`` velocities and ``n_params`` parameters, and its threads per block; ``shared`` as for
        :meth:`cuda_image`."""


ROLLOUT_PROGRAMS = ("forward_dynamics", "mass_matrix", "inverse_dynamics_vjp")
"""The quantities whose vector programs a rollout kernel is printed from."""

ROLLOUT_PARTS = ("forward", "adjoint", "parameters")
"""A rollout's CUDA kernels (:mod:`jaxskid.lowering._cuda_rollout`): the rollout, the adjoint recursion of its
gradient, and the parameters' part of the gradient, which needs no recursion and runs a thread per
:data:`ROLLOUT_STRIDE` steps of each rollout."""

ROLLOUT_STRIDE = 8
"""Steps per thread of the ``parameters`` kernel."""

ROLLOUT_PARAMETERS = {"forward": 2, "adjoint": 2, "parameters": 3}
"""The input of each rollout kernel that holds the parameters (:func:`rollout_layout`)."""

CONSTANT_MAX = 8192
"""The most parameters a CUDA kernel reads from constant memory (64 KiB of doubles)."""


BY_ENTRY = 64
"""A CUDA quantity kernel of at least this many result entries per state writes them by entry (all states'
entry 0, then entry 1, ...), where neighbouring threads write neighbouring addresses; XLA then transposes the
result into rows. Written by state, a warp's store touches 32 rows, far apart (:func:`by_entry`)."""


def by_entry(n_out: int) -> bool:
    """Whether a CUDA quantity kernel of ``n_out`` result entries per state writes its result by entry
    (:data:`BY_ENTRY`), unless ``JAXSKID_CUDA_LAYOUT`` is ``rows``."""
    if os.environ.get("JAXSKID_CUDA_LAYOUT", "").strip() == "rows":
        return False
    return n_out >= BY_ENTRY


def constant_input(index: int, size: int, shared: bool) -> int:
    """``index``, the input of a CUDA kernel that holds its ``size`` parameters, where the kernel reads them from
    constant memory (the handler copies them there before each call): where every state of the call shares
    them (``shared``) and they fit, unless ``JAXSKID_CUDA_CONSTANT`` is ``0``; otherwise -1."""
    if os.environ.get("JAXSKID_CUDA_CONSTANT", "1").strip() == "0":
        return -1
    return index if shared and 0 < size <= CONSTANT_MAX else -1


def rollout_layout(part: str, n: int, n_params: int, steps: int) -> tuple:
    """``(sizes, cores, n_out, out_rank)`` of a rollout kernel's inputs and result, as the CUDA handler registers a
    kernel (``h`` and the block number ``j`` are arrays of one entry):

    * ``forward``: ``x0 (2n), u (steps, n), p, h -> x (steps + 1, 2n)``;
    * ``adjoint``: ``x (steps + 1, 2n), u, p, h, g (like x) -> [x0bar (2n), ubar (steps n), hbar, lambda
      (steps 4n)]``, ``lambda`` each stage's cotangent of its torque;
    * ``parameters``: ``x, u, lambda (steps, 4n), p, h, j -> pbar (n_params)`` over the steps
      ``[j ROLLOUT_STRIDE, (j + 1) ROLLOUT_STRIDE)``.
    """
    states = 2 * n * (steps + 1)
    if part == "forward":
        return (2 * n, steps * n, n_params, 1), (1, 2, 1, 1), states, 2
    if part == "adjoint":
        return (states, steps * n, n_params, 1, states), (2, 2, 1, 1, 2), 2 * n + steps * n + 1 + 4 * steps * n, 1
    return (states, steps * n, 4 * steps * n, n_params, 1, 1), (2, 2, 2, 1, 1, 0), n_params, 1


def _identity(x):
    return x


def _single(program: Callable, *args):
    return program(*args, _identity)


def _entries(program: Callable, *args):
    return program(*args, _identity, entries=True)


@dataclass(frozen=True)
class GeneratedQuantity:
    """One quantity of a generated module.

    ``function(*state, p)`` is the module's public function (a ``jax.custom_jvp``): the program with every
    input entry broadcast to the output's shape, the form to map with ``jax.vmap``. ``program(*state, p,
    spread, entries=False)`` is the program itself: ``spread`` broadcasts an input entry (or is the
    identity); with ``entries=True`` it returns the structurally nonzero entries unassembled,
    ``{flat index: value}`` (quantities with a shape only).
    """

    name: str
    args: tuple[str, ...]
    """The state arguments, in order (``p`` follows)."""
    shape: tuple[int, ...]
    """One state's result."""
    equation: str
    doc: str
    function: Callable
    program: Callable

    def single(self) -> Callable:
        """``f(*state, p)``: the program on unbroadcast values, for one state."""
        return functools.partial(_single, self.program)

    def entries(self) -> Callable:
        """``f(*state, p) -> {flat index: value}``: the structurally nonzero entries by row-major flat index, in
        the order the program computes them."""
        return functools.partial(_entries, self.program)


@dataclass(frozen=True)
class GeneratedModule:
    """A generated JAX module, executed: its metadata (:meth:`jaxskid.codegen.Layout.metadata`), one
    :class:`GeneratedQuantity` per quantity (in the catalogue's order), the native C beside it, its source
    text and the cache file it came from (None when uncached)."""

    metadata: Mapping
    quantities: Mapping[str, GeneratedQuantity]
    native: tuple[NativeSource, ...]
    source: str
    path: Path | None = None
