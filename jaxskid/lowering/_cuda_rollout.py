"""A fixed-base robot's RK4 rollout under held torques as one CUDA kernel, and its gradient as two more: one
rollout per thread, every step inside the kernel.

On a GPU a rollout written as a loop of XLA operations launches kernels at every step (a few for each of the
four stages): a batch of one rollout waits on launches, and a large batch reads and writes its states between
them. Here each thread integrates its rollout from ``x0`` under the torque rows ``u`` with the programs of
forward dynamics, and writes every state (``forward``). The ``adjoint`` recomputes each step's four stages from
its saved state, from the last step, and runs the same RK4 backward step as the CPU's one-call step
(``c/rk4_backward.h`` on ``c/fd_backward.h``: the mass matrix factored, then the pullback of inverse dynamics),
accumulating the cotangents of ``x0``, the torques and the step, and writing each stage's lambda. The
``parameters`` kernel takes those lambdas and sums the pullback's parameter part over blocks of steps, a thread
each: that sum needs no recursion, and kept out of the adjoint it leaves the adjoint half the stack.

:func:`rollout_source` writes the source, the quantity kernels' template (``c/cuda_kernel.cu``) around
``c/cuda_rollout.cu``; it compiles with NVRTC like theirs (:func:`jaxskid.lowering._cuda.compile_kernel`) and as
C on the host for the tests. The number of steps is part of the source.
"""

from __future__ import annotations

from collections.abc import Mapping

from .._generated import ROLLOUT_PARAMETERS, ROLLOUT_PARTS, ROLLOUT_STRIDE, VectorKernel, constant_input, rollout_layout
from ._cuda import _IO, constant_parameters, constants, ordered, split_sizes, threads, trig_source
from ._ffi import Piece, _chunked
from ._ffi_rk4 import RK4_STEP
from ._templates import fill, template

ROLLOUT_PTXAS = "3"
"""ptxas's optimisation level for rollout kernels: on an H200 the z1's 500 steps ran faster at ``-O3`` than at
``-O1`` at every batch, forward and backward (``benchmarks/gpu.py``'s ``rollout`` section), and built as fast."""

PROGRAMS = {"fd": ("forward_dynamics", ("q", "qd", "tau", "p")), "mass": ("mass_matrix", ("q", "p")),
            "vjp": ("inverse_dynamics_vjp", ("q", "qd", "qdd", "cotangent", "p"))}
"""The device functions of a rollout kernel: ``{function: (quantity, its arguments in order)}``, over the
quantities of :data:`jaxskid._generated.ROLLOUT_PROGRAMS`."""


def programs_usable(vectors: Mapping[str, VectorKernel | None]) -> bool:
    """Whether ``vectors`` (the vector programs by quantity, from a lowering's native libraries) hold what a
    rollout kernel needs, with the arguments it passes."""
    return all(vectors.get(q) is not None and vectors[q].args == args for q, args in PROGRAMS.values())


def rollout_source(vectors: Mapping[str, VectorKernel | None], stem: str, n: int, n_params: int, steps: int,
                   io: str = "float64", part: str = "forward", shared: bool = True) -> str:
    """The CUDA source of the kernel ``part`` (:func:`jaxskid._generated.rollout_layout`) of ``steps`` RK4 steps
    of a robot of ``n`` velocities and ``n_params`` parameters, inputs and results of dtype ``io``, exporting
    ``jaxskid_kernel(jaxskid_job)`` as the quantity kernels do. ``shared``: every rollout of a call has the same
    parameters, which the programs read from constant memory where they fit
    (:func:`jaxskid._generated.constant_input`)."""
    if not programs_usable(vectors):
        raise ValueError("a rollout kernel needs the vector programs of " + ", ".join(q for q, _ in PROGRAMS.values()))
    text, (long, chunk) = [], split_sizes()
    constant = constant_input(ROLLOUT_PARAMETERS[part], n_params, shared) >= 0
    for function, (quantity, _) in PROGRAMS.items():
        program, restrict = ordered(constant_parameters(vectors[quantity]) if constant else vectors[quantity])
        pieces = _chunked(function, program, "D", set(), io="D", long=long, chunk_size=chunk, huge=None,
                          restrict=restrict)
        text += [p.text() if isinstance(p, Piece) else p for p in pieces]
    n_vjp = sum(s.kind == "output" for s in vectors["inverse_dynamics_vjp"].statements)
    functions = fill(template("cuda_rollout.cu"), STEM=stem, STEPS=steps, N=n, NP=n_params, NV=n_vjp,
                     STRIDE=ROLLOUT_STRIDE, PROGRAMS="".join(text), FD_BACKWARD=template("fd_backward.h"),
                     RK4_STEP=RK4_STEP)
    sizes, _, n_out, _ = rollout_layout(part, n, n_params, steps)
    call = ", ".join(f"(const io_t *)j->in[{i}] + off[{i}]" for i in range(len(sizes)))
    head = (f"#define JAXSKID_IO {_IO[io]}\n#define JAXSKID_IO_DOUBLE {int(io == 'float64')}\n"
            f"#define JAXSKID_ROLLOUT_PART {ROLLOUT_PARTS.index(part)}\n")
    return head + fill(template("cuda_kernel.cu"), JOB=template("cuda_job.h"), TRIG=trig_source("fused"), STEM=stem,
                       NAME=f"rollout ({part})", CONSTANTS=constants(n_params if constant else None),
                       FUNCTIONS=functions, N_IN=len(sizes), CALL=call, OUT=f"(io_t *)j->out + s * {n_out}LL",
                       THREADS=threads())
