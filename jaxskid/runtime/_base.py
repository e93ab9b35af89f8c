"""What every set of evaluated quantities of one robot shares: its metadata, its parameters, its errors.

:class:`jaxskid.Dynamics` (JAX functions) and :class:`jaxskid.NativeDynamics` (compiled C) both hold the
quantities of one robot, each as a function of its state arrays and ``params``. The parameters follow one
rule (:class:`jaxskid.model.ParameterLayout`): ``None`` for the defaults, a mapping name -> value in which
missing names take their defaults and unknown names are errors, or a vector in the order of
:attr:`QuantitySet.parameters`, whose leading axes are a batch.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence

import jax
import jax.numpy as jnp

from . import _free_flyer as _ff
import numpy as np

from .._errors import InputError, RequestError
from ._checks import InertiaCheck, checks_mode
from ..model._parameters import ParameterLayout
from ._parameters import HostParameters, param_array


def metadata_fields(meta: Mapping) -> dict:
    """The keyword arguments of :class:`QuantitySet` from a ``METADATA`` dict
    (:meth:`jaxskid.codegen.Layout.metadata`)."""
    return dict(
        robot_name=meta["robot"], joint_names=meta["joint_names"], frame_names=meta["frame_names"],
        end_effectors=meta["end_effectors"], layout=ParameterLayout(tuple(meta["parameters"]), meta["defaults"]),
        signatures={k: (m["args"], m["shape"]) for k, m in meta["quantities"].items()},
        driven=meta.get("driven", ()), floating_base=meta.get("floating_base", False),
        standard_names=meta.get("standard_names", ()), coriolis=meta.get("coriolis", "christoffel"),
        constraint_rows=meta.get("constraint_rows", 0),
    )


class QuantitySet:
    """The quantities of one robot, with its metadata and parameters.

    Subclasses make the quantity functions and set ``_made`` (how the quantities were made, e.g.
    ``"lowered"``) and ``_remedy`` (the call that makes a missing one, with ``{name!r}`` for its name):
    asking for a quantity of the catalogue that was not made raises :class:`RequestError` with them.

    Args:
        robot_name: the robot's name.
        joint_names: ``(n_dof,)`` joint names, in the order of ``q``.
        frame_names: the frames ``forward_kinematics`` returns.
        end_effectors: the end-effector frames, in the order of the wrench rows.
        layout: the parameter names (the order of the vector) and their defaults.
        signatures: quantity name -> (argument names, output shape), for the quantities made.
        catalogue: the names of every quantity jaxskid knows (:data:`jaxskid.QUANTITIES`), for the error
            that names a quantity that exists but was not made.
        driven: the joints that have a drive (:class:`jaxskid.Drive`): ``tau = M qdd + C qd + Q_grav`` plus
            their armature, friction and offset.
        floating_base: whether the robot's root is a free-flyer: ``q`` is then ``(p, quat, q_j)`` (``nq = 7 + n``)
            and velocities ``(omega, v, qd_j)`` (``nv = 6 + n``); see :mod:`jaxskid.runtime._free_flyer`.
        inertia: ``() -> (standard, bodies, involved)``, the map from a parameter vector to the bodies'
            standard parameters (:func:`jaxskid.model._standard.body_standard_map`), called on the first check
            of parameter values; None: masses and inertias are not checked at call time.
        standard_names: the names of the regressor's columns (:func:`jaxskid.standard_parameter_names`).
        coriolis: the factorisation of ``coriolis_matrix`` (:class:`jaxskid.Options`): ``"christoffel"`` or
            ``"skidy"``.
        constraint_rows: the number of rows of the robot's constraints, the size of ``cotangent_rows``.
        checks: whether top-level calls check their inputs (:mod:`jaxskid.runtime._checks`): NaN or inf in
            a state or a parameter, parameter values that are not numbers, masses and inertias no rigid body
            has. Inside a caller's ``jit``, ``grad`` or ``vmap`` nothing is checked, unless ``"debug"``
            (:func:`jaxskid.runtime._checks.check_inputs`).
    """

    _made = "made"
    _remedy = "{name!r}"

    def __init__(
        self,
        *,
        robot_name: str,
        joint_names: Sequence[str],
        frame_names: Sequence[str],
        end_effectors: Sequence[str],
        layout: ParameterLayout,
        signatures: Mapping[str, tuple[Sequence[str], Sequence[int]]],
        catalogue: Collection[str] = (),
        driven: Sequence[str] = (),
        floating_base: bool = False,
        inertia: Callable[[], tuple] | None = None,
        checks: bool | str = True,
        standard_names: Sequence[str] = (),
        coriolis: str = "christoffel",
        constraint_rows: int = 0,
    ):
        self.robot_name: str = robot_name
        self.driven: tuple[str, ...] = tuple(driven)
        self.joint_names: tuple[str, ...] = tuple(joint_names)
        self.frame_names: tuple[str, ...] = tuple(frame_names)
        self.end_effectors: tuple[str, ...] = tuple(end_effectors)
        self.layout: ParameterLayout = layout
        self.parameters: tuple[str, ...] = layout.names
        self.defaults: dict[str, float] = {k: layout.defaults[k] for k in layout.names if k in layout.defaults}
        self.n_dof: int = len(self.joint_names)
        self.floating_base: bool = bool(floating_base)
        self.nq: int = self.n_dof + (7 if floating_base else 0)
        """The size of ``q``."""
        self.nv: int = self.n_dof + (6 if floating_base else 0)
        """The size of ``qd``, ``qdd`` and ``tau``."""
        self._signatures = {k: (tuple(a), tuple(s)) for k, (a, s) in signatures.items()}
        self._catalogue = frozenset(catalogue)
        self._host = HostParameters(layout)
        self.standard_names: tuple[str, ...] = tuple(standard_names)
        """The standard parameters' names, the regressor's columns (``{link}_m``, ..., then the drives'); empty
        for a module generated before they were recorded."""
        self.constraint_rows: int = int(constraint_rows)
        """The number of rows of the robot's constraints (0: none)."""
        self.coriolis: str = coriolis
        """The factorisation of ``coriolis_matrix``: ``"christoffel"`` (``dM/dt - 2C`` skew) or ``"skidy"``."""
        self.checks: bool | str = checks_mode(checks)
        """Whether top-level calls check their inputs (see the ``checks`` argument)."""
        self._inertia_source = inertia
        self._inertia: InertiaCheck | None = None
        self._last_checked = None  # the last parameter vector that passed (a dict packs to the same one)

    @property
    def quantities(self) -> tuple[str, ...]:
        """The names of the quantities made, in the catalogue's order."""
        return tuple(self._signatures)

    def signature(self, name: str) -> tuple[tuple[str, ...], tuple[int, ...]]:
        """(argument names, output shape) of a quantity; :class:`RequestError` for one not made here."""
        try:
            return self._signatures[name]
        except KeyError:
            raise self._missing(name) from None

    def integrate(self, q, v, dt=1.0) -> jax.Array:
        """The configuration reached from ``q`` ``(..., nq)`` at the constant velocity ``v`` ``(..., nv)`` after
        ``dt``: ``g exp(dt V)`` for a floating base (Pinocchio's ``integrate``), ``q + dt v`` for joints."""
        return _ff.integrate(jnp.asarray(q), jnp.asarray(v), dt, self.floating_base)

    def difference(self, q0, q1) -> jax.Array:
        """The velocity ``v`` ``(..., nv)`` with ``integrate(q0, v, 1) = q1``: ``log(g0^-1 g1)`` for a floating
        base (Pinocchio's ``difference``, with the twist as (omega, v)), ``q1 - q0`` for joints."""
        return _ff.difference(jnp.asarray(q0), jnp.asarray(q1), self.floating_base)

    def argument_shape(self, arg: str) -> tuple[int, ...]:
        """The shape of one state of the argument ``arg``: ``(n_ee, 6)`` for the wrenches and ``cotangent_ee``,
        ``(n_ee, 4, 4)`` for ``cotangent_pose``, ``(nq,)`` for ``q``, ``(nv,)`` for the velocity-space ones (``qd``,
        ``qdd``, ..., ``tau``, ``cotangent``), ``(nv, nv)`` for ``cotangent_matrix``, ``(m, nv)``
        for ``cotangent_constraint`` and ``(m,)`` for ``cotangent_rows`` (m: :attr:`constraint_rows`)."""
        if arg.startswith("wrench") or arg == "cotangent_ee":
            return (len(self.end_effectors), 6)
        if arg == "cotangent_pose":
            return (len(self.end_effectors), 4, 4)
        if arg == "cotangent_matrix":
            return (self.nv, self.nv)
        if arg == "cotangent_constraint":
            return (self.constraint_rows, self.nv)
        if arg == "cotangent_rows":
            return (self.constraint_rows,)
        return (self.nq,) if arg == "q" else (self.nv,)

    def default_params(self) -> dict[str, float]:
        """Parameter name -> default value, for the parameters that have one."""
        return dict(self.defaults)

    def param_vector(self, params=None, dtype=None) -> jax.Array:
        """The parameters as a JAX array ``(..., n_params)`` in the order of :attr:`parameters`.

        ``params``: ``None`` (the defaults), a mapping name -> value (missing names take their defaults;
        an unknown name raises :class:`RequestError` naming the closest valid ones; values may carry batch
        axes), or an array ``(..., n_params)``. ``dtype``: the result's (default: float64 with x64 enabled).
        """
        return param_array(self.layout, self.packed_params(params), dtype)

    def default_constants(self) -> tuple[float, ...]:
        """The default parameter vector as a tuple of floats: what the gathered form compiles as constants for
        a call without parameters (:func:`jaxskid.runtime._emitted.values`)."""
        return tuple(np.asarray(self.packed_params(None), dtype=float).tolist())

    def packed_params(self, params, where: str = "params"):
        """``params`` ready to pass to a jitted function, converted there by :func:`param_array`.

        Concrete values are packed on the host by the parameters' one rule (:class:`HostParameters`) and
        checked (see ``checks``): a float64 NumPy array ``(..., n_params)`` (``None`` gives the read-only
        default vector), a mapping's as a JAX array kept on the device (:meth:`HostParameters.on_device`).
        JAX arrays, tracers and mappings that hold them are returned unchanged.
        """
        host = self._host.pack(params, where)
        if host is None:
            return params
        if self.checks and host is not self._host.defaults and host is not self._last_checked:
            self._check_params(host, where)
            self._last_checked = host
        return self._host.on_device(host) if isinstance(params, Mapping) else host

    def _check_params(self, p: np.ndarray, where: str) -> None:
        """:class:`InputError` for a NaN or inf parameter (named) or a physically impossible body."""
        finite = np.isfinite(p)
        if not finite.all():
            k = int(np.argmax(~finite.reshape(-1, p.shape[-1]).all(axis=0)))
            bad = p[..., k].ravel()[~finite[..., k].ravel()][0]
            raise InputError(f"{where}: {self.parameters[k]} is {bad}: expected finite parameter values")
        if self._inertia is None and self._inertia_source is not None:
            standard, bodies, involved = self._inertia_source()
            self._inertia = InertiaCheck(self.parameters, standard, bodies, involved, self._host.defaults)
            self._inertia_source = None
        if self._inertia is not None:
            self._inertia.check(p, where)

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        if name in self._catalogue:
            raise self._missing(name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _missing(self, name: str) -> RequestError:
        """The error for a quantity that was not made: how to make it, or that no quantity has that name."""
        made = self._made
        if name in self._catalogue or not self._catalogue:
            return RequestError(
                f"{name!r} was not {made} for this robot; {made}: {', '.join(self.quantities)}. "
                f"Ask for it with {self._remedy.format(name=name)}"
            )
        return RequestError(f"no quantity is named {name!r}; {made} here: {', '.join(self.quantities)}")
