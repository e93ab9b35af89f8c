"""The runtime object: jit-compiled, vmap-able, differentiable functions of the lowered quantities.

``Dynamics`` knows only JAX and the metadata of a generated module; it never touches SymPy. Every
function takes the state arrays of its quantity (shape ``(n,)``, or ``(..., n)`` for a batch, which is
mapped with ``jax.vmap``), then ``params``: ``None`` for the defaults, a dict name -> value (a pytree, so
``jax.grad`` with respect to it works), or a vector in the order of :attr:`Dynamics.parameters`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RequestError, ShapeError


def compiler_options() -> dict:
    """XLA options for the generated functions.

    On CPU, XLA's newer fusion emitters compile the long straight-line programs of jaxskid slowly and
    into slow code (the second time derivative of tau on the Panda: 1.45 ms against 270 ns per state;
    the Coriolis matrix: 747 us against 15 us), so the classic emitters are used there.
    """
    return {"xla_cpu_use_fusion_emitters": False} if jax.default_backend() == "cpu" else {}


def _plain(body: Callable, same: Callable, *args):
    return body(*args, same)


def _traced(tree) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(tree))


def _outermost(top: Callable, nested: Callable, **jit_kwargs) -> Callable:
    """Call ``top`` jitted with :func:`compiler_options` from Python, ``nested`` plainly jitted inside a
    caller's trace (JAX accepts compiler options only on a top-level jit)."""
    nested_jit = jax.jit(nested, **jit_kwargs)
    top_jit: list = []  # compiled on first use: compiler_options() asks for the backend

    def call(*args, **kwargs):
        if _traced((args, kwargs)):
            return nested_jit(*args, **kwargs)
        if not top_jit:
            top_jit.append(jax.jit(top, compiler_options=compiler_options(), **jit_kwargs))
        return top_jit[0](*args, **kwargs)

    return call


def jit(fn: Callable | None = None, **jit_kwargs) -> Callable:
    """``jax.jit`` with :func:`compiler_options` where they may be given: at the outermost call.

    Wrap your own functions of jaxskid's quantities with it (as jaxskid wraps its rollouts and fits): with
    XLA's default CPU emitters, the long straight-line programs compile into code up to 1000x slower.
    JAX accepts compiler options only on a top-level jit, so inside a caller's trace this is a plain
    ``jax.jit`` (and the caller's options apply). Keyword arguments go to ``jax.jit``; usable as a
    decorator, with or without them.
    """
    if fn is None:
        return functools.partial(jit, **jit_kwargs)
    return functools.wraps(fn)(_outermost(fn, fn, **jit_kwargs))


class Dynamics:
    """Lowered quantities of one robot. Build it with :func:`jaxskid.lower`.

    The quantity functions are attributes named after the quantities (``mass_matrix``,
    ``inverse_dynamics``, ...); see ``quantities`` for what this object has.
    """

    def __init__(self, namespace: dict, source: str, path=None):
        meta = namespace["METADATA"]
        self.source = source
        self.path = path
        self.robot_name: str = meta["robot"]
        self.joint_names: tuple[str, ...] = tuple(meta["joint_names"])
        self.frame_names: tuple[str, ...] = tuple(meta["frame_names"])
        self.end_effectors: tuple[str, ...] = tuple(meta["end_effectors"])
        self.parameters: tuple[str, ...] = tuple(meta["parameters"])
        self.defaults: dict[str, float] = dict(meta["defaults"])
        self.n_dof = len(self.joint_names)
        self._meta = meta["quantities"]
        self._raw: dict[str, Callable] = {name: namespace[name] for name in self._meta}
        same = namespace["_same"]
        self._plain: dict[str, Callable] = {
            name: functools.partial(_plain, namespace["_" + name], same) for name in self._meta
        }
        self._jitted: dict[str, Callable] = {}

    # ------------------------------------------------------------------ introspection
    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(self._meta)

    def signature(self, name: str) -> tuple[tuple[str, ...], tuple[int, ...]]:
        """(argument names, output shape) of a quantity."""
        m = self._meta[name]
        return tuple(m["args"]), tuple(m["shape"])

    def raw(self, name: str, batched: bool = True) -> Callable:
        """The generated function for one state, ``f(*state, p)`` with ``p`` a parameter vector.

        ``batched=True`` gives the form to map with ``jax.vmap`` (its inputs are broadcast to the output's
        shape so that XLA makes one kernel of a batch; see :mod:`jaxskid.codegen._jax`); ``batched=False`` the
        same program on unbroadcast values, for a single state (XLA makes nothing better of the broadcast
        there, and on the closed-form forward dynamics its simplifier loops over it).
        """
        return self._raw[name] if batched else self._plain[name]

    def default_params(self) -> dict[str, float]:
        return dict(self.defaults)

    def param_vector(self, params=None, dtype=None) -> jax.Array:
        """Parameters as a vector in the order of :attr:`parameters` (defaults fill in for None)."""
        if params is None:
            missing = [k for k in self.parameters if k not in self.defaults]
            if missing:
                raise RequestError(f"parameter(s) {', '.join(missing)} have no default value; pass params")
            vec = jnp.asarray(np.array([self.defaults[k] for k in self.parameters], dtype=np.float64))
        elif isinstance(params, Mapping):
            missing = [k for k in self.parameters if k not in params]
            if missing:
                raise RequestError(
                    f"params is missing {', '.join(missing)} (expected the names in Dynamics.parameters)"
                )
            if not self.parameters:
                vec = jnp.zeros((0,))
            else:
                vec = jnp.stack([jnp.asarray(params[k]) for k in self.parameters])
        else:
            vec = jnp.asarray(params)
            if vec.shape != (len(self.parameters),):
                raise ShapeError(f"params: expected a dict or a vector of shape ({len(self.parameters)},), got {vec.shape}")
        return vec if dtype is None else vec.astype(dtype)

    # ------------------------------------------------------------------ the functions
    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        if name in self._meta:
            fn = self._jitted.get(name)
            if fn is None:
                fn = self._jitted[name] = self._make(name)
            return fn
        from ..equations._derive import QUANTITIES

        if name in QUANTITIES:
            raise RequestError(
                f"{name!r} was not lowered for this robot; lowered: {', '.join(self.quantities)}. "
                f"Ask for it with jaxskid.lower(robot, quantities=[..., {name!r}])"
            )
        raise AttributeError(f"'Dynamics' object has no attribute {name!r}")

    def _make(self, name: str) -> Callable:
        args, shape = self.signature(name)
        raw, plain = self._raw[name], self._plain[name]
        n = self.n_dof
        arg_shapes = {a: ((len(self.end_effectors), 6) if a.startswith("wrench") else (n,)) for a in args}

        def call(*state, params=None, pair=False):
            arrays = [jnp.asarray(x) for x in state]
            batch = None
            for a, x in zip(args, arrays):
                want = arg_shapes[a]
                if x.shape[x.ndim - len(want):] != want or x.ndim < len(want):
                    raise ShapeError(
                        f"{name}: {a}: expected shape {want} (or (..., {', '.join(map(str, want))}) for a batch), got {x.shape}"
                    )
                lead = x.shape[: x.ndim - len(want)]
                if batch is None:
                    batch = lead
                elif lead != batch:
                    raise ShapeError(f"{name}: batch shapes differ: {batch} and {lead} for {a}")
            dtype = jnp.result_type(*arrays) if arrays else None
            if dtype is not None and not jnp.issubdtype(dtype, jnp.floating):
                dtype = jnp.result_type(float)
                arrays = [x.astype(dtype) for x in arrays]
            p = self.param_vector(params, dtype)
            if not batch and pair:
                # One state alone: XLA turns the broadcast inputs back into scalars and splits the function
                # into a kernel per shared value (20 for the Panda's mass matrix: 117 us a call on 2
                # cores). Mapped over the state and a second, all-zero one, it stays one kernel (8 us).
                # Only at the outermost call: inside a caller's trace an enclosing vmap may batch it.
                pairs = [jnp.stack([x, jnp.zeros_like(x)]) for x in arrays]
                return jax.vmap(raw, in_axes=(*([0] * len(pairs)), None))(*pairs, p)[0]
            if not batch:
                return plain(*arrays, p)
            flat = [x.reshape((-1, *arg_shapes[a])) for a, x in zip(args, arrays)]
            out = jax.vmap(raw, in_axes=(*([0] * len(flat)), None))(*flat, p)
            return out.reshape((*batch, *shape))

        if name == "forward_kinematics":
            frames = self.frame_names

            def call_fk(*state, params=None, pair=False):
                poses = call(*state, params=params, pair=pair)
                return {f: poses[..., k, :, :] for k, f in enumerate(frames)}

            body = call_fk
        else:
            body = call
        compiled = _outermost(functools.partial(body, pair=True), body)
        takes_wrench = name == "inverse_dynamics"

        def fn(*state, params=None, wrench=None):
            if takes_wrench and len(state) == len(args) + 2:
                *state, params, wrench = state
            if len(state) == len(args) + 1 and params is None:
                *state, params = state
            if len(state) != len(args):
                raise ShapeError(f"{name} takes ({', '.join(args)}, params), got {len(state)} state argument(s)")
            out = compiled(*state, params=params)
            if wrench is not None:
                if not takes_wrench:
                    raise ShapeError(f"{name} takes no wrench")
                out = out + self.external_torques(state[0], wrench, params)
            return out

        fn.__name__ = name
        fn.__doc__ = (
            f"{name}({', '.join(args)}, params=None{', wrench=None' if takes_wrench else ''}) -> {tuple(shape)}"
            f"\n\n{self._meta[name]['equation']}: {self._meta[name]['doc']}"
        )
        return fn

    def forward_dynamics(self, q, qd, tau, params=None, wrench=None):
        """``qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q) - Q_ext)``.

        Uses the lowered quantity ``forward_dynamics`` (closed form) when there is one, else
        ``mass_matrix`` and ``inverse_dynamics`` (or ``coriolis_torques`` and ``gravity_torques``) with a
        Cholesky-type solve; see :func:`jaxskid.forward_dynamics`.
        """
        from ..apps._simulate import forward_dynamics

        return forward_dynamics(self, q, qd, tau, params, wrench)

    def __repr__(self) -> str:
        return f"Dynamics({self.robot_name!r}, n_dof={self.n_dof}, quantities={list(self.quantities)})"
