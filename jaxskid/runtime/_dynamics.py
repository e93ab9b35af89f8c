"""The runtime object: jit-compiled, vmap-able, differentiable functions of the lowered quantities.

``Dynamics`` knows only JAX and the metadata of a generated module; it never touches SymPy. Every
function takes the state arrays of its quantity (shape ``(n,)``, or ``(..., n)`` for a batch, which is
mapped with ``jax.vmap``), then ``params``: ``None`` for the defaults, a dict name -> value (missing names
take their defaults; a pytree, so ``jax.grad`` with respect to it works), or a vector in the order of
:attr:`Dynamics.parameters`. Leading axes of the parameters are a batch too: they broadcast against the
states' (``dyn.mass_matrix(q_batch, p_batch)``). ``out=``, an earlier result of the same shape and dtype,
gives the result its memory (donated: deleted after the call), so a large batch fills no fresh memory.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Collection, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._gc import paused_gc
from .._errors import unknown_names, RequestError, ShapeError
from .._generated import GPU_ONLY, GeneratedModule, NativeBuild
from ._base import QuantitySet, metadata_fields
from ._cuda import CudaKernel, cuda_kernel, enabled as cuda_enabled
from ._cuda_rollout import rollout_kernels
from ._ffi import enabled as native_enabled, library, log, native_quantity, target
from ._batching import batch_shape, vmapped
from ._constrained import constrained_forward_dynamics, constrained_inverse_dynamics
from ._deferred import Deferred, OnDemand
from ._forward import accelerations, forward_dynamics
from ._gathered import gathered, padded_batch
from ._checks import check_finite, check_inputs, check_not_a_wrench
from ._jit import compiler_options, jit, outermost, top_level  # noqa: F401  (compiler_options, jit: imported from here too)
from ._ldl import materialize
from ._parameters import inexact_inputs
from ._parts import in_parts
from ._pullback import with_pullback
from ._quantity import Quantity
from ._recycle import Recycler, check_donated, check_out, recycled_result


BACKWARD_KERNELS = ("fd_vjp", "rk4_vjp", "rk4fb_vjp", "kkt_vjp")
"""The runtime's own native kernels, besides the quantities' (:meth:`Dynamics.native_target`)."""

_ONCE = 32
"""Vectors up to this length are computed once by :meth:`Dynamics.raw`: ``x @ I`` costs ``len(x)``
multiply-adds per entry, which stays small beside the program that computes the entry."""


def _gathers(shape: tuple) -> bool:
    """Whether a batch of a result of ``shape`` runs in the gathered form (:meth:`Dynamics.mapped`): a matrix, or a
    vector of more than 8 entries, on CPU. Inverse dynamics per state at a batch of 4096, one core: solo12's (12
    entries) 0.08 us so and 0.21 through ``jax.vmap``, the Panda's (7) 0.06 and 0.05 (larger vectors:
    :mod:`jaxskid.runtime._gathered`)."""
    return (len(shape) >= 2 or len(shape) == 1 and shape[0] > 8) and jax.default_backend() == "cpu"


def _traced_once(fn: Callable, name: str | None = None) -> Callable:
    """``jax.jit(fn)``: inside a caller's trace, a call of a jitted function is traced once per argument
    shape and dtype and enters the caller's program as one equation, and JAX caches what it derives from
    it (its linearisation, transpose and batching). Called plainly, a generated function's thousands of
    operations are traced again at every use: the gradient of a rollout traced the forward dynamics, the
    mass matrix and the vector-Jacobian product six times, most of the first call of a process that found
    the compiled program in the persistent cache (``benchmarks/first_call.py``)."""
    jitted = jax.jit(fn)  # keeps a function's name and docstring; a partial is named here
    if name is not None:
        jitted.__name__ = name
    return jitted


class Dynamics(QuantitySet):
    """Lowered quantities of one robot. Build it with :func:`jaxskid.lower`.

    The quantity functions are attributes named after the quantities (``mass_matrix``,
    ``inverse_dynamics``, ...), each with its own signature and docstring (:mod:`jaxskid.runtime._quantity`);
    see ``quantities`` for what this object has.

    Args:
        module: the generated module (:class:`jaxskid._generated.GeneratedModule`): its metadata, functions
            and native C.
        catalogue: the names of every quantity jaxskid knows, so that asking for one that was not
            lowered says so (see :class:`~jaxskid.runtime._base.QuantitySet`).
        native: the module's native libraries (:class:`jaxskid._generated.NativeBuild`), each built when one
            of its kernels is first used; none: every quantity runs in its JAX form.
        inertia, checks: as for :class:`~jaxskid.runtime._base.QuantitySet`.
        deferred: quantities of a second module, made when one of them is first used
            (:class:`~jaxskid.runtime._deferred.Deferred`: the pullbacks, where no native kernel is built); they
            are listed among the quantities from the start.
    """

    _made = "lowered"
    _remedy = "jaxskid.lower(robot, quantities=[..., {name!r}])"

    def __init__(self, module: GeneratedModule, *, catalogue: Collection[str] = (),
                 native: Sequence[NativeBuild] = (), inertia: Callable | None = None, checks: bool = True,
                 deferred: Deferred | None = None):
        meta = module.metadata
        quantities = meta["quantities"]
        later = deferred.quantities if deferred is not None else {}
        order = {k: i for i, k in enumerate(catalogue)}
        names = sorted([*quantities, *(k for k in later if k not in quantities)], key=lambda k: order.get(k, -1))
        listed = {k: quantities[k] if k in quantities else later[k] for k in names}
        super().__init__(**metadata_fields({**meta, "quantities": listed}), catalogue=catalogue, inertia=inertia,
                         checks=checks)
        self.module = module
        self.source = module.source
        self.path = module.path
        self._meta = listed
        self._deferred = deferred
        generated = module.quantities
        # Each generated function is jitted: traced once per shape and dtype, it is one call in the programs
        # that use it, whose transformations JAX caches (see _traced_once); a deferred quantity's when first read
        self._raw: dict[str, Callable] = OnDemand(
            {name: _traced_once(generated[name].function) for name in quantities}, self._fill_deferred, later)
        self._plain: dict[str, Callable] = OnDemand(
            {name: _traced_once(generated[name].single(), name) for name in quantities}, self._fill_deferred, later)
        self._entries: dict[str, Callable] = OnDemand(
            {name: _traced_once(generated[name].entries(), name) for name, m in quantities.items() if m["shape"]},
            self._fill_deferred, later)
        # reverse mode by the closed-form pullbacks, where they were lowered (jaxskid.runtime._pullback)
        self._rules: dict[str, Callable[[Callable], Callable]] = {}
        for name in quantities:
            pull = self._pullback(name)
            if pull is not None:
                n_args, shape = len(quantities[name]["args"]) + 1, tuple(quantities[name]["shape"])
                rule = self._rules[name] = functools.partial(
                    with_pullback, program=self._plain[name], pullback=pull, n_args=n_args, shape=shape,
                    state_pullback=self._pullback(name, state=True))
                self._raw[name] = _traced_once(rule(generated[name].function))
                self._plain[name] = _traced_once(rule(self._plain[name]), name)
        self._jitted: dict[str, Callable] = {}
        self._user_raw: dict[tuple[str, bool], Callable] = {}
        self._gathered: dict[str, Callable] = {}  # mapped()
        # the switches as they were when this Dynamics was made, for its life: C kernels on CPU, CUDA on a GPU
        self._cuda = cuda_enabled()
        self._native_wanted = native_enabled() or self._cuda
        self._cuda_kernels: dict[str, CudaKernel | tuple | None] = {}  # a quantity's, or a rollout's pair
        # the native libraries: each handler's library, built on first use (the kernels of GPU_ONLY on a GPU)
        self._native_build: dict[str, NativeBuild] = {}
        for lib in native:
            self._native_build.update({k: lib for k in lib.sources.quantities if self._cuda or k not in GPU_ONLY})
            if lib.sources.backward:
                self._native_build.update(fd_vjp=lib, rk4_vjp=lib, rk4fb_vjp=lib)
            if not self._cuda:  # a pullback's kernel without the parameters' part (made by the glue, CPU only)
                self._native_build.update({f"{k}_state": lib for k in lib.sources.state_parts})
            if lib.sources.kkt and not self._cuda:  # constrained dynamics' backward step: on CPU only
                self._native_build["kkt_vjp"] = lib
        self._native_path: dict[str, str | None] = {}  # by handler: its library's path, None if unavailable
        # the quantity functions, as attributes (the methods of the same name, forward_dynamics, stay)
        self._quantities: dict[str, Quantity] = {
            name: Quantity(name, tuple(m["args"]), tuple(m["shape"]), m["equation"], m["doc"],
                           tuple(self.argument_shape(a) for a in m["args"]), name == "inverse_dynamics",
                           self.floating_base)
            for name, m in listed.items()
        }
        for name, quantity in self._quantities.items():
            if not hasattr(type(self), name):
                setattr(self, name, quantity.function(functools.partial(self._call, name)))

    def _fill_deferred(self) -> None:
        """The functions of the deferred quantities (:mod:`jaxskid.runtime._deferred`), from their module, made
        now (when one of them is first read: a gradient traced)."""
        module = self._deferred.module()
        for name, m in self._deferred.quantities.items():
            fn = module.quantities[name]
            self._raw.setdefault(name, _traced_once(fn.function))
            self._plain.setdefault(name, _traced_once(fn.single(), name))
            if m["shape"]:
                self._entries.setdefault(name, _traced_once(fn.entries(), name))

    def _pullback(self, name: str, state: bool = False) -> Callable | None:
        """``pull(*state, p, w)``: the cotangents of ``name``'s arguments for a cotangent ``w`` of its result,
        from its lowered pullback (``<name>_vjp``; for inverse dynamics ``inverse_dynamics_vjp`` and the mass
        matrix, ``d(w^T tau)/dqdd = M w``), native where it has a kernel; None where none was lowered.
        ``state``: the same with a zero cotangent for ``p``, for a derivative that does not ask for it (a
        controller's Jacobian with respect to the state), whose native kernel leaves the parameters' part out."""
        have = self._meta
        if name == "inverse_dynamics" and {"inverse_dynamics_vjp", "mass_matrix"} <= set(have):
            vjp, mass = self._pullback_kernel("inverse_dynamics_vjp", state), self._pullback_kernel("mass_matrix")
            nq, nv = self.nq, self.nv

            def pull_tau(q, qd, qdd, p, w):
                g = vjp(q, qd, qdd, w, p)
                return g[:nq], g[nq:nq + nv], mass(q, p) @ w, jnp.zeros_like(p) if state else g[nq + nv:]

            return pull_tau
        if f"{name}_vjp" not in have:
            return None
        vjp = self._pullback_kernel(f"{name}_vjp", state)
        shapes = [self.argument_shape(a) for a in have[name]["args"]]
        sizes = [int(np.prod(s)) for s in shapes]
        ends = np.cumsum(sizes).tolist()

        def pull(*args):
            p, w = args[-2:]
            g = vjp(*args[:-2], w, p)
            return (*(g[e - k:e].reshape(s) for k, e, s in zip(sizes, ends, shapes)),
                    jnp.zeros_like(p) if state else g[ends[-1]:])

        return pull

    def _pullback_kernel(self, name: str, state: bool = False) -> Callable:
        """``name``'s function of one state, its native kernel on CPU where it has one (looked up when first
        called: when a derivative is first traced). ``state``: a pullback whose parameters' entries are not read
        (its native kernel ``<name>_state`` where the library has one, else the whole kernel)."""
        found: list = []

        def call(*args):
            if not found:
                shape, raw = tuple(self._meta[name]["shape"]), self._raw[name]
                native = self.native_target(f"{name}_state") if state and self._native_wanted else None
                if native is not None or (state and not self._native_wanted):
                    shape, full = (shape[0] - len(self.parameters),), raw  # the JAX form: XLA drops the rest

                    def raw(*a):
                        return full(*a)[:shape[0]]
                elif self._native_wanted:  # the whole kernel (the state's entries come first)
                    native = self.native_target(name)
                found.append(raw if native is None else native_quantity(native, shape, raw))
            return found[0](*args)

        return call

    def raw(self, name: str, batched: bool = True) -> Callable:
        """The function of one state, ``f(*state, p)`` with ``p`` a parameter vector, to call inside your own
        ``jax.vmap``, ``lax.scan`` or ``jax.jit``.

        It is the generated program, with a vector output of up to 32 entries computed once
        (:func:`materialize`: XLA on CPU would otherwise fuse it into each of its users and recompute it
        there, as in the stages of a hand-written RK4 step, which then runs and compiles several times
        slower; ``benchmarks/raw_loop.py`` times such a loop). ``forward_dynamics`` is
        :func:`~jaxskid.runtime._forward.accelerations`, the function the rollouts use,
        ``f(q, qd, tau, p, wrench=None)``, with its closed-form derivatives; it exists whenever
        :meth:`forward_dynamics` does.

        ``batched=True`` gives the form to map with ``jax.vmap`` (its inputs are broadcast to the output's
        shape so that XLA makes one kernel of a batch; see :mod:`jaxskid.codegen._jax`); ``batched=False`` the
        same program on unbroadcast values, for a single state (XLA makes nothing better of the broadcast
        there, and on the closed-form forward dynamics its simplifier loops over it).
        """
        fn = self._user_raw.get((name, batched))
        if fn is None:
            if name == "forward_dynamics":
                fn = accelerations(self, batched)
            else:
                fn = self.generated(name, batched)
                shape = self.signature(name)[1]
                if len(shape) == 1 and shape[0] <= _ONCE:
                    generated = fn

                    def fn(*args):
                        return materialize(generated(*args))

                    fn.__name__, fn.__doc__ = name, generated.__doc__
            self._user_raw[(name, batched)] = fn
        return fn

    def native_target(self, name: str = "fd_vjp") -> str | None:
        """For the runtime's own kernels (:meth:`report` says how each quantity runs): the registered XLA FFI
        target of a native kernel (:mod:`jaxskid.runtime._ffi`): ``"fd_vjp"``, the
        backward step of forward dynamics, ``"rk4_vjp"``, the backward pass of a Runge-Kutta step built on it
        (:mod:`jaxskid.runtime._rk4`), ``"kkt_vjp"``, the backward step of constrained forward dynamics
        (:mod:`jaxskid.runtime._constrained`), or the name of a quantity with a native kernel (the matrix-valued
        ones and forward dynamics). Its library is built on first use; None where there is none (not
        lowered, a quantity without a vector form in C, turned off with ``JAXSKID_NATIVE=0``, or no C
        compiler)."""
        build = self._native_build.get(name)
        if build is None:
            return None
        if self._cuda:
            return self._cuda_target(name, build)
        if name not in self._native_path:
            path = library(build, self.robot_name) if self._native_wanted else None
            self._native_path.update({k: path for k, b in self._native_build.items() if b is build})
        return target(self._native_path[name], name)

    def _cuda_target(self, name: str, build: NativeBuild) -> CudaKernel | None:
        """The CUDA kernel of ``name`` (:mod:`jaxskid.runtime._cuda`), or None."""
        if name not in self._cuda_kernels:
            self._cuda_kernels[name] = cuda_kernel(build, name, self.robot_name)
        return self._cuda_kernels[name]

    def cuda_rollout(self, steps: int):
        """The CUDA kernels of a rollout of ``steps`` RK4 steps under held torques and of its gradient
        (:mod:`jaxskid.runtime._cuda_rollout`), or None: CUDA kernels off, a floating base, no pullback of
        inverse dynamics lowered, or no CUDA kernel of forward dynamics (the handler unavailable: logged once)."""
        if self.floating_base or "inverse_dynamics_vjp" not in self.quantities or \
                not self._cuda or self.native_target("forward_dynamics") is None:
            return None
        key = f"rollout {steps}"
        if key not in self._cuda_kernels:
            builds = list({id(b): b for b in self._native_build.values()}.values())
            self._cuda_kernels[key] = rollout_kernels(builds, self.nv, len(self.parameters), steps)
        return self._cuda_kernels[key]

    def report(self) -> dict[str, str]:
        """How each quantity runs on this machine, ``{name: form}``: ``"native kernel"`` (generated C behind an
        XLA FFI handler, :mod:`jaxskid.runtime._ffi`), or ``"JAX form"`` with the reason (a vector quantity,
        which XLA fuses with its caller; native kernels off, or their library unavailable; no vector form in
        C). Builds the native libraries that are not built yet. Forward dynamics and the rollouts' backward
        steps (:data:`BACKWARD_KERNELS`) are listed where they have a kernel."""
        out = {}
        for name in (*self.quantities, *(k for k in BACKWARD_KERNELS if k in self._native_build)):
            out[name] = self._form(name)
        return out

    def _form(self, name: str) -> str:
        if name not in self._native_build:
            return "JAX form (a vector: XLA fuses it with its caller)" if name in self._signatures else "JAX form"
        if not self._native_wanted:
            return "JAX form (native kernels off: JAXSKID_NATIVE=0 or JAXSKID_CUDA=0, or a backend without kernels)"
        if self.native_target(name) is not None:
            return "CUDA kernel" if self._cuda else "native kernel"
        if self._cuda:
            return "JAX form (no CUDA kernel: no vector form in C, or no C compiler or NVRTC; see the log)"
        if self._native_path.get(name) is None:
            return "JAX form (the native library could not be built; see the log)"
        return "JAX form (its generated C has no vector form: it calls a function the kernels lack)"

    def _native_planned(self, name: str) -> bool:
        """Whether :meth:`native_target` is expected to give a kernel for ``name`` (its library is part of this
        lowering and native kernels are on), without building it."""
        return self._native_wanted and name in self._native_build

    def generated(self, name: str, batched: bool = True) -> Callable:
        """The generated function of one state as it is, ``f(*state, p)``: what :meth:`raw` wraps, for
        building other functions of the runtime (see :meth:`raw` for ``batched``)."""
        if name not in self._raw:
            self.signature(name)  # the error that names the quantity and how to lower it
        return self._raw[name] if batched else self._plain[name]

    def entries(self, name: str) -> Callable:
        """The generated function of one state returning its structurally nonzero entries unassembled,
        ``f(*state, p) -> {flat index: scalar}`` (row-major flat indices, in the order the program computes
        them; absent: zero for every state and parameter):
        the sparsity pattern is known when the caller is traced (:mod:`jaxskid.runtime._sparse`)."""
        if name not in self._entries:
            self.signature(name)
            raise RequestError(f"{name} has a scalar value: it has no entries")
        return self._entries[name]

    # ------------------------------------------------------------------ the functions
    def _call(self, name: str, *args, **kwargs):
        """A call of the quantity ``name``, its function made (:meth:`_make`) on the first."""
        fn = self._jitted.get(name)
        if fn is None:
            fn = self._jitted[name] = self._make(name)
        return fn(*args, **kwargs)

    def _evaluate(self, name: str) -> Callable:
        """``call(*state, params, pair)``: the quantity on one state or a batch, with ``params`` already
        packed (:meth:`packed_params`) and converted here, inside the jitted function."""
        args, shape = self.signature(name)
        raw, plain = self._raw[name], self._plain[name]
        native = self.native_target(name)
        if native is None and self._native_planned(name):  # the fast path left: said once per quantity
            log.warning("jaxskid: %s of %s runs in its JAX form on CPU, slower: %s", name, self.robot_name,
                        self._form(name))
        raw_out = plain_out = None
        if native is not None:  # the C kernel on CPU: one per batch, not a program per entry (jaxskid.runtime._ffi)
            raw = raw_out = native_quantity(native, shape, raw)
            plain = plain_out = native_quantity(native, shape, plain)
            if name in self._rules:  # differentiated without tracing the JAX form's value
                raw, plain = self._rules[name](raw_out), self._rules[name](plain_out)
        # an array of the JAX form on CPU: the gathered form, for a batch (jaxskid.runtime._gathered)
        gather = native is None and _gathers(shape)
        if gather:
            raw = self.mapped(name)
        cores = {a: self.argument_shape(a) for a in args}
        n_params = (len(self.parameters),)

        def call(*state, params=None, pair=False, out=None):
            arrays, p, dtype = inexact_inputs(self.layout, state, params)
            batch = batch_shape(name, [(a, x.shape, cores[a]) for a, x in zip(args, arrays)], [("params", p.shape, n_params)])
            if out is not None:
                check_out(name, out, (*batch, *shape), dtype)
                # The native kernel writes into it. The JAX form does not take it: the outermost jit donates
                # it, and XLA gives its memory to the result of the same shape.
                if native is not None and not batch:
                    return plain_out(*arrays, p, out=out)
                if native is not None:
                    return vmapped(lambda *a: raw_out(*a[:-1], out=a[-1]), batch,
                                   [*((x, len(cores[a])) for a, x in zip(args, arrays)), (p, 1), (out, len(shape))])
            if not batch and pair and native is None:
                # One state alone: XLA turns the broadcast inputs back into scalars and splits the function
                # into a kernel per shared value (20 for the Panda's mass matrix, each call far slower).
                # Mapped over the state and a second, all-zero one, it stays one kernel.
                # Only at the outermost call: inside a caller's trace an enclosing vmap may batch it.
                pairs = [jnp.stack([x, jnp.zeros_like(x)]) for x in arrays]
                return jax.vmap(raw, in_axes=(*([0] * len(pairs)), None))(*pairs, p)[0]
            if not batch:
                return plain(*arrays, p)
            pad = functools.partial(padded_batch, dtype=dtype, shape=shape) if gather else None
            fn = self.mapped(name, defaults=True) if gather and params is None else raw  # defaults: constants
            return vmapped(fn, batch, [*((x, len(cores[a])) for a, x in zip(args, arrays)), (p, 1)], pad)

        if name != "forward_kinematics":
            return call
        frames = self.frame_names

        def call_fk(*state, params=None, pair=False, out=None):
            poses = call(*state, params=params, pair=pair, out=out)
            return {f: poses[..., k, :, :] for k, f in enumerate(frames)}

        return call_fk

    def mapped(self, name: str, defaults: bool = False) -> Callable:
        """``generated(name)``, the function of one state to map with ``jax.vmap``; on CPU, for an array, its
        gathered form with the quantity's derivative rules (:mod:`jaxskid.runtime._gathered`). ``defaults``:
        for the default parameters, which the gathered form then compiles as constants (``p`` is not read)."""
        if not _gathers(self.signature(name)[1]):
            return self.generated(name)
        if (name, defaults) not in self._gathered:
            fn = gathered(self.module.quantities[name], self.default_constants() if defaults else None)
            self._gathered[name, defaults] = _traced_once(self._rules[name](fn) if name in self._rules else fn, name)
        return self._gathered[name, defaults]

    def _make(self, name: str) -> Callable:
        args, shape = self.signature(name)
        body = self._evaluate(name)
        # out (None or an earlier result) is donated, and kept though the JAX form does not read it, so that
        # XLA gives its memory to the result
        compiled = outermost(functools.partial(body, pair=True), body, donate_argnames="out", keep_unused=True)
        if self.native_target(name) is None and _gathers(shape):  # a long one: from Python, compiled in parts
            compiled = in_parts(self, name, compiled)
        quantity = self._quantities[name]
        takes_wrench, call = quantity.takes_wrench, quantity.call
        recycler = Recycler() if name != "forward_kinematics" else None  # jaxskid.runtime._recycle
        cores, n_params = [self.argument_shape(a) for a in args], (len(self.parameters),)

        def fn(*state, params=None, wrench=None, out=None, **unexpected):
            if unexpected:
                named, _ = unknown_names(unexpected, ("params", "wrench", "out") if takes_wrench else ("params", "out"))
                raise TypeError(f"{name}: unexpected keyword argument {named}; expected {call}")
            if len(state) == len(args) + 1 and params is None:
                *state, params = state
            if len(state) != len(args):
                raise ShapeError(f"{name}: expected {call}, got {len(state)} positional argument(s)")
            if wrench is not None and not takes_wrench:
                raise ShapeError(f"{name} takes no wrench; expected {call}")
            if takes_wrench and params is not None:
                check_not_a_wrench(name, params, call, len(self.end_effectors), len(self.parameters))
            outside = top_level(state)
            if self.checks and outside:
                check_finite(name, zip(args, state))
            elif self.checks == "debug":  # inside a caller's jit, grad or vmap: a check staged into its program
                check_inputs("debug", name, [*zip(args, state), ("params", params), ("wrench", wrench)],
                             self.parameters)
            if params is not None:  # None stays: the defaults become constants of the compiled program
                params = self.packed_params(params)
            kept = None
            if out is not None:
                check_donated(name, out, (*state, params))
            elif recycler is not None and outside:  # a large result takes an earlier one's memory
                kept = recycled_result(state, cores, (params, n_params), shape)
                out = None if kept is None else recycler.out(*kept)
            with paused_gc():  # the first call traces the program (jaxskid._gc)
                result = compiled(*state, params=params, out=out)
            if kept is not None:
                recycler.keep(result)
            if wrench is not None:
                result = result + self.external_torques(state[0], wrench, params)
            return result

        fn.__name__ = name
        return fn

    def forward_dynamics(self, q, qd, tau, params=None, *, wrench=None):
        """``qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q) - Q_ext)``.

        Uses the lowered quantity ``forward_dynamics`` (closed form) when there is one, else
        ``mass_matrix`` and ``inverse_dynamics`` (or ``coriolis_torques`` and ``gravity_torques``) with a
        Cholesky-type solve; see :func:`jaxskid.forward_dynamics`.
        """
        return forward_dynamics(self, q, qd, tau, params, wrench=wrench)

    def constrained_forward_dynamics(self, q, qd, tau, params=None, *, stabilization=None, regularization=0.0):
        """``(qdd, lambda)`` with ``M qdd + h = tau + A^T lambda`` and ``A qdd = -Adot qd`` (with
        :class:`~jaxskid.Baumgarte` ``stabilization``: ``- 2 alpha A qd - beta^2 phi``), for a robot with
        constraints; see :func:`jaxskid.constrained_forward_dynamics`."""
        return constrained_forward_dynamics(self, q, qd, tau, params, stabilization=stabilization,
                                            regularization=regularization)

    def constrained_inverse_dynamics(self, q, qd, qdd, actuated, params=None):
        """``(tau_a, lambda)`` with ``B tau_a + A^T lambda = tau(q, qd, qdd)`` for the ``actuated`` joints of a
        closed chain; see :func:`jaxskid.constrained_inverse_dynamics`."""
        return constrained_inverse_dynamics(self, q, qd, qdd, actuated, params)

    def __repr__(self) -> str:
        return f"Dynamics({self.robot_name!r}, n_dof={self.n_dof}, quantities={list(self.quantities)})"
