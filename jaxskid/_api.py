"""The entry points, across the stages: :func:`load` a description, :func:`lower` it to JAX functions,
:func:`compile_native` it to C called from Python."""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from ._gc import gc_paused
from ._errors import ModelError, RequestError, unknown_names
from .codegen import Layout
from .codegen._c import emit_c, native_block, native_sources
from .codegen._common import quantity_metadata
from ._generated import GeneratedModule
from .codegen._jax import GENERATOR_VERSION, jax_names, module_source
from .equations import QUANTITIES, Equations, Options, derive, resolve
from .lowering._cache import cache_dir as default_cache_dir
from .lowering._cache import entry_path, read_entry, request_key, store_entry
from .lowering._xla_cache import default_compilation_cache
from .lowering._ffi_build import NativeLibrary, ffi_library_soon
from .lowering._extension import Method
from .lowering._native import build, default_backend
from .description._end_effectors import with_end_effectors
from .description._yaml_skidy import check_dialect
from .model._inertia_check import check_inertias
from .model._robot import Robot
from .model._validate import describe_value
from .model._standard import body_standard_map
from .runtime._checks import checks_mode
from .runtime._deferred import Deferred
from .runtime._dynamics import Dynamics
from .runtime._cuda import enabled as cuda_enabled
from .runtime._ffi import enabled as native_enabled
from .runtime._native import NativeDynamics


_URDF_SWITCHES = ("symbolic_inertia", "mimic", "floating_base", "balance_inertia")
_URDF_OPTIONS = (*_URDF_SWITCHES, "gravity")


def _check_options(source: str, ext: str, lock, drives, options: Mapping) -> None:
    """:func:`load`'s keywords, before the file is read: ``lock`` a mapping of joint names, the switches
    ``True`` or ``False`` (not a truthy string), the further keywords those of the URDF reader."""
    if lock is not None and not (isinstance(lock, Mapping) and all(isinstance(k, str) for k in lock)):
        raise ModelError(f"expected a mapping joint name -> position, got {describe_value(lock)}", where="lock",
                         source=source)
    unknown = [k for k in options if k not in _URDF_OPTIONS]
    if unknown and ext == ".urdf":
        named, listed = unknown_names(unknown, _URDF_OPTIONS)
        raise ModelError(f"unknown option {named}; a URDF file takes {listed}", source=source)
    for name, value in (("drives", drives), *((k, v) for k, v in options.items() if k in _URDF_SWITCHES)):
        if not isinstance(value, bool):
            raise ModelError(f"expected true or false, got {describe_value(value)}", where=name, source=source)


@gc_paused
def load(path: str | os.PathLike, *, lock: Mapping[str, float] | None = None, drives: bool = False,
         dialect: str = "jaxskid", end_effectors=None, **options) -> Robot:
    """Read a robot from ``.urdf``, ``.yaml``/``.yml`` or ``.json`` (chosen by the file extension).

    ``lock`` fixes the named joints at the given positions. ``drives`` gives every moving joint ``J`` a
    drive (:class:`jaxskid.Drive`) with the parameters ``J_Ia`` (armature), ``J_fv`` (viscous friction),
    ``J_fc`` (Coulomb friction) and ``J_fo`` (torque offset), default 0 (for URDF, ``J_fv`` and ``J_fc``
    default to the joint's ``<dynamics damping friction>``; a YAML ``drives`` entry keeps its values).
    ``dialect="skidy"`` reads a YAML/JSON file as Skidy does (:mod:`jaxskid.description._yaml_skidy`: a serial
    chain unless both ``parent`` and ``support`` are given, ``frame: com`` carried over to later bodies,
    assignments of assignments, unknown keys and a prismatic joint's ``vec`` ignored with a warning); a URDF
    reads the same in both dialects. ``end_effectors``: for any file, ``{name: (link, pose)}`` places
    end-effectors ``pose`` away from the named links (:mod:`jaxskid.description._end_effectors`), and they
    replace the file's own; for a URDF also a list of link names (default: the leaf links).
    Further keyword options go to the URDF reader (``symbolic_inertia``, ``gravity``, ``mimic``: couple the
    ``<mimic>`` joints, whose positions then follow the independent joints; ``floating_base``: make the root
    link a free-flyer base body, :attr:`Robot.floating_base`, which a YAML file says with its own
    ``floating_base: true`` key; ``balance_inertia``: make each inertia that no rigid body has isotropic with
    the same trace, as MuJoCo's ``balanceinertia``, with a warning). A description without ``mass_inertia``
    gives a robot for kinematics (:attr:`Robot.without_inertia`).
    """
    p = Path(path)
    ext = p.suffix.lower()
    check_dialect(dialect)
    _check_options(str(p), ext, lock, drives, options)
    placed = isinstance(end_effectors, Mapping)
    if ext == ".urdf":
        from .description._urdf import read_urdf

        robot = read_urdf(p, lock=lock, drives=drives, end_effectors=() if placed else end_effectors, **options)
        where = lambda i: f"link {robot.joints[i].link!r} <inertial>"  # noqa: E731
    elif ext in (".yaml", ".yml", ".json"):
        from .description._yaml_schema import read_description

        if options:
            raise ModelError(f"unknown option(s) {', '.join(options)} for a {ext} file", source=str(p))
        if end_effectors is not None and not placed:
            raise ModelError("expected end_effectors as {name: (link, pose)} for a description file (its own ee "
                             "gives the end-effectors)", where="end_effectors", source=str(p))
        robot = read_description(p, lock=lock, drives=drives, dialect=dialect)
        where = lambda i: f"mass_inertia of body {robot.joints[i].link!r}"  # noqa: E731
    else:
        raise ModelError(f"unknown file type {ext or '(none)'!r}; expected .urdf, .yaml, .yml or .json", source=str(p))
    check_inertias(robot, str(p), where)
    return with_end_effectors(robot, end_effectors, source=str(p)) if placed else robot


@gc_paused
def lower(
    model: Robot | Equations,
    quantities: Sequence[str] | str | None = None,
    *,
    symbolic: Iterable[str] | None = None,
    cache: bool = True,
    cache_dir: str | os.PathLike | None = None,
    options: Options | None = None,
    progress: bool = False,
    checks: bool | str = True,
) -> Dynamics:
    """Derive, lower and wrap the requested quantities of ``model`` (only those).

    The generated module is cached on disk, keyed by everything that determines it (the robot, the
    quantities, the options, the default parameters and the generator's version): a second call with the
    same request derives nothing.

    Args:
        model: a :class:`Robot`, or :class:`Equations` already derived (they are printed as they are; the
            cache is shared with the robot's request).
        quantities: names from :data:`jaxskid.QUANTITIES`; ``None`` for :data:`jaxskid.DEFAULT_QUANTITIES`
            (for ``Equations``: every quantity they hold), ``"all"`` for every quantity. For a robot, the
            quantities a requested one is differentiated with come too: ``forward_dynamics`` brings
            ``mass_matrix``, ``inverse_dynamics`` and ``inverse_dynamics_vjp``, which give its exact
            derivatives (:mod:`jaxskid.runtime._implicit`) for gradients through rollouts. Where no native
            kernel is built (``JAXSKID_NATIVE=0``, a GPU without CUDA kernels, a TPU), the pullbacks
            (``<name>_vjp``) that were not asked for are derived when a gradient first needs them
            (:mod:`jaxskid.runtime._deferred`).
        symbolic: the parameters that stay inputs of the generated functions; every other parameter is
            replaced by its default value (the ``assignments``). ``None`` keeps all parameters symbolic.
            Only for a robot: substitute before deriving for ``Equations``.
        cache: reuse and write generated modules in ``cache_dir`` (default :func:`jaxskid.cache_dir`).
        cache_dir: where the generated module and its native library are kept. XLA's compiled programs go to
            the process-wide cache of :func:`jaxskid.compilation_cache` (``jaxskid.cache_dir() / "xla"``,
            unless you chose another), whatever ``cache_dir`` is.
        options: how expressions are formed (:class:`jaxskid.Options`: CSE, simplification, trig); for
            ``Equations``, the options they were derived with.
        progress: show a progress bar while deriving.
        checks: whether calls from Python check their inputs before running: NaN or inf in a state or a
            parameter (named, with the first bad index), parameter values that are not numbers, and
            masses and inertias no rigid body has (:mod:`jaxskid.runtime._checks`); a few microseconds a
            call, nothing inside a caller's ``jit``, ``grad`` or ``vmap``. ``"debug"``: inside them too, the
            states of every quantity, ``forward_dynamics`` and ``rollout`` call are checked by a test staged into
            the traced program, which fails with a ``jax.errors.JaxRuntimeError`` carrying the ``InputError``'s
            message (argument and first bad index); a debugging aid that costs a host call per evaluation.
            ``dyn.checks`` can be changed later (to ``"debug"`` only on a ``Dynamics`` lowered with it).
    """
    checks = checks_mode(checks)
    robot, asked, names, options = _request(model, quantities, symbolic, options)
    # where no kernel can run (JAXSKID_NATIVE=0 on CPU, JAXSKID_CUDA=0 on a GPU, a TPU), no C is printed
    c_kernels = native_enabled()
    native_c = c_kernels or cuda_enabled()
    # and the pullbacks nobody asked for are made when a gradient first needs them (jaxskid.runtime._deferred)
    deferred = () if native_c or isinstance(model, Equations) else \
        tuple(k for k in names if QUANTITIES[k].pullback_of is not None and k not in asked)
    names = tuple(k for k in names if k not in deferred)
    key = module_key(robot, names, options, native_c)
    if cache:
        default_compilation_cache()
    path = entry_path(cache_dir, robot.name, key) if cache else None
    found = read_entry(path, key) if path is not None else None
    if found is None:
        eqs = model if isinstance(model, Equations) else derive(robot, names, options=options, progress=progress)
        native = []
        for library in native_sources(eqs, names, jax_names, first=asked) if native_c else ():
            native.append(library)  # its kernels are the JAX module's programs, printed in C
            if cache and c_kernels:
                # the C compiler works on each library while the next and the JAX module are printed; the
                # one of the quantities that only serve the requested ones' derivatives at a low priority
                later = not set(library.quantities) & set(asked)
                ffi_library_soon(library, Path(cache_dir or default_cache_dir()) / "native", later)
        module = module_source(Layout(eqs, names, jax_names)) + native_block(native)
        found = store_entry(path, module, key)
    native_root = Path(cache_dir or default_cache_dir()) / "native" if cache else None
    return Dynamics(found, catalogue=tuple(QUANTITIES), native=tuple(NativeLibrary(s, native_root) for s in found.native),
                    inertia=functools.partial(body_standard_map, robot), checks=checks,
                    deferred=_deferred(robot, deferred, found, options, cache, cache_dir) if deferred else None)


def _request(model: Robot | Equations, quantities, symbolic, options: Options | None) -> tuple:
    """``(robot, asked, names, options)`` of a :func:`lower` call: the robot (its symbolic parameters kept), the
    quantities asked for, those and the ones they are differentiated with, and the options."""
    if isinstance(model, Equations):
        if symbolic is not None:
            raise RequestError("lower: symbolic= needs a Robot; for Equations, derive from robot.substitute(...)")
        if options is not None and options != model.options:
            raise RequestError(f"lower: options {options} differ from the equations' {model.options}")
        names = _derived(model, quantities)
        return model.robot, names, names, model.options
    robot = model if symbolic is None else model.keep_symbolic(symbolic)
    asked = resolve(robot, quantities)
    return robot, asked, resolve(robot, [*asked, *(k for n in asked for k in QUANTITIES[n].derivatives)]), \
        options or Options()


def _deferred(robot: Robot, names: Sequence[str], beside: GeneratedModule, options: Options, cache: bool,
              cache_dir) -> Deferred:
    """The quantities ``names`` of ``robot`` as a module of their own, derived, printed and cached when one of
    them is first used (:mod:`jaxskid.runtime._deferred`), taking ``p`` as the module ``beside`` it does."""
    key = module_key(robot, names, options, False)
    path = entry_path(cache_dir, robot.name, key) if cache else None

    def load():
        found = read_entry(path, key) if path is not None else None
        if found is None:
            eqs = derive(robot, names, options=options)
            found = store_entry(path, module_source(Layout(eqs, names, jax_names)), key)
        return found

    announced = {k: quantity_metadata(q.args, q.shape(robot), q.equation, q.doc)
                 for k, q in ((k, QUANTITIES[k]) for k in names)}
    return Deferred(announced, beside.metadata["parameters"], load)


def module_key(robot: Robot, names: Sequence[str], options: Options | None = None, native: bool = True) -> str:
    """The cache key of the JAX module of ``names``: everything that determines it (the generator's version,
    the robot, the quantities, the options and the defaults, which the module's METADATA holds, and whether
    it carries the C of its native kernels)."""
    options = options or Options()
    return request_key([GENERATOR_VERSION, robot.fingerprint(), repr(tuple(names)), repr(options),
                        repr(sorted(robot.default_params().items())), *(() if native else ("without native C",))])


def compile_native(
    model: Robot | Equations,
    quantities: Sequence[str] | str | None = None,
    *,
    backend: str | None = None,
    cache_dir: str | os.PathLike | None = None,
) -> NativeDynamics:
    """Compile the requested quantities of ``model`` to native code for fast single calls: derive, print
    the ``"c"`` target of :mod:`jaxskid.codegen`, build it (:mod:`jaxskid.lowering._native`) and wrap it
    in a :class:`NativeDynamics`.

    Args:
        model: a :class:`Robot` (its quantities are derived here) or already derived :class:`Equations`.
        quantities: names from :data:`jaxskid.QUANTITIES`; ``None`` for the defaults (for ``Equations``:
            every quantity they hold).
        backend: ``"capi"`` (an extension module of the quantities: the fastest), ``"cffi"`` or ``"ctypes"``;
            ``None`` picks capi where Python's headers are installed, else cffi, else ctypes.
        cache_dir: where built libraries are kept (default ``jaxskid.cache_dir() / "native"``).

    Raises:
        BuildError: no C compiler, or the build failed (the message ends with the compiler's output).
    """
    if isinstance(model, Equations):
        eqs, names = model, _derived(model, quantities)
    else:
        names = resolve(model, quantities)
        eqs = derive(model, names)
    layout = Layout(eqs, names)
    files = emit_c(layout)
    header, source = files[f"{layout.stem}.h"], files[f"{layout.stem}.c"]
    symbols = {n: f"{layout.stem}_{n}" for n in names}
    arity = {symbols[k.name]: len(k.args) + 2 for k in layout.programs}  # the state arguments, p and out
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir() / "native"
    backend = backend or default_backend()
    metadata = layout.metadata()
    methods = ()
    if backend == "capi":
        methods = tuple(_method(k, symbols[k.name], layout, metadata["quantities"][k.name]) for k in layout.programs)
    library = build(layout.stem, header, source, arity, backend, root, methods)
    return NativeDynamics(metadata, {n: library.functions[c] for n, c in symbols.items()}, ffi=library.ffi,
                          path=library.path, source=source, catalogue=tuple(QUANTITIES), backend=backend,
                          module=library.handle)


def _method(kernel, c_name: str, layout: Layout, meta: Mapping) -> Method:
    """The extension method of one quantity for the ``"capi"`` backend of :func:`compile_native`."""
    shape = tuple(meta["shape"])
    doc = f"{kernel.name}({', '.join(kernel.args)}, params=None) -> {shape}\n\n{meta['equation']}: {meta['doc']}"
    return Method(kernel.name, c_name, tuple((a, tuple(layout.arg_shape(a))) for a in kernel.args),
                  len(layout.parameters), shape, doc)


def _derived(eqs: Equations, quantities: Sequence[str] | str | None) -> tuple[str, ...]:
    """The requested quantities of already derived equations (``None``: all they hold), in canonical order."""
    names = tuple(eqs.quantities) if quantities is None else resolve(eqs.robot, quantities)
    missing = [n for n in names if n not in eqs.quantities]
    if missing:
        raise RequestError(f"{', '.join(missing)} not derived; derived: {', '.join(eqs.quantities)}")
    return names
