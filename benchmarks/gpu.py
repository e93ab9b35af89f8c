"""The G1's quantities in the generated CUDA kernels and in the JAX form, the floating-base G1 against
adam-robotics, and z1 rollouts with their gradients, on whatever JAX's default device is (prepared for one run
on a GPU machine: ``bash benchmarks/gpu_run.sh`` there, with the wheels, URDF copies and cache of ``.gpu/``,
a folder git ignores, carried along).

    python benchmarks/gpu.py --prepare                  # URDF copies into --urdf-dir (from example-robot-data)
    JAXSKID_CACHE_DIR=.gpu/cache python benchmarks/gpu.py --derive-only
    python -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_17_x86_64 -d .gpu/whl adam-robotics==0.5.0 urdfdom-py array-api-compat \
        prettytable wcwidth yourdfpy trimesh six   # what the GPU machine lacks
    python benchmarks/gpu.py --rows rows.jsonl [--runs 7,8] --markdown PATH   # recorded rows, measuring nothing
    JAXSKID_CACHE_DIR=.gpu/cache python benchmarks/gpu.py [--budget 420] [--batch 16384] [--out rows.jsonl]
                                                          [--markdown PATH] [--sections quantities,...]
                                                          [--forms cuda,jax] [--urdf-dir .gpu/urdf]

Derive on a CPU machine first (``--derive-only`` with the ``JAXSKID_CACHE_DIR`` the GPU run will use, under
each setting of ``JAXSKID_CUDA`` and ``JAXSKID_NATIVE`` whose module may differ): the run then spends its time
on XLA's compile and the calls. XLA's persistent cache is off, so every first call is XLA's compile and the
run. Each result is printed as one JSON line as soon as it is measured, and appended to ``--out``; a section
starts no case once its share of the ``--budget`` seconds is spent (``--shares``; what it leaves goes to
the next), and a case still running when the budget is spent is abandoned (``error``), so the run ends in
time with its table. ``JAXSKID_CUDA`` is set before each ``jaxskid.lower``: ``form`` ``"cuda"`` (``1``, the
generated CUDA kernels where the backend is a GPU) or ``"jax"`` (``0``, the plain JAX form); ``runs`` is what
``dyn.report()`` says of the quantity, and each ``lower`` row has the whole report.

Sections:

- ``quantities``: the fixed-base G1 (29 DOF) and the G1 with hands (43), every inertial parameter symbolic,
  the six quantities of ``benchmarks/scaling.py`` in the first form of ``--forms``: the first call at
  ``--batch`` (XLA's compile and the run; for a CUDA kernel, NVRTC's compile too), the median time per state
  on float64 and on float32 states, of one call waited for and with :data:`IN_FLIGHT` calls in flight; ``jax`` (after the others): the same in the second form. The JAX form
  of the Coriolis matrices and of the 43-DOF regressor compiles for minutes on a GPU: those cases run last of
  all, each only with :data:`SLOW_NEEDS` seconds left;
- ``agreement``: the z1's six quantities and four of the G1's as they run (CUDA kernels) against the JAX form
  of the same module computed on the CPU device;
- ``variants``: the G1's M and C with the CUDA kernels built other ways (ptxas level, split or not, threads
  per block), each against the default;
- ``adam``: the floating-base G1 (nv 35): M and tau at qdd = 0 (the bias) against adam-robotics' ``mass_matrix``
  and ``bias_force`` (its JAX backend, body-fixed velocities; adam's base twist is (v, omega), ours (omega, v):
  the first six rows and columns are permuted to compare), float64 and float32, first calls, per-state
  medians and the largest difference from adam's float64 result;
- ``rollout``: the z1 arm (7 DOF with its gripper), 500 RK4 steps of 1 ms under open-loop torques, loss the
  mean squared error to a goal state; batches 1, 1024 and ``--batch``: the loss and its gradient with respect
  to every parameter (``jax.jit(jax.grad(loss))``), their ratio, first calls, the time per state and step,
  and the values (to compare the ways), each way of :data:`ROLLOUTS` that ``--rollouts`` names.

The URDF copies carry no meshes, and every joint has an ``<origin>`` (adam needs one; the G1 has a joint
without): both libraries load the same file.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import importlib.metadata
import json
import os
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxskid  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)
from gpu_rollouts import timed  # noqa: E402  (beside this script too)

URDFS = {  # the copies in --urdf-dir, from example-robot-data's robots/
    "g1_29dof_rev_1_0.urdf": "g1_description/urdf/g1_29dof_rev_1_0.urdf",
    "g1_29dof_with_hand_rev_1_0.urdf": "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf",
    "z1.urdf": "z1_description/urdf/z1.urdf",
}
QUANTITIES = ("inverse_dynamics", "mass_matrix", "coriolis_matrix", "regressor", "forward_dynamics",
              "mass_matrix_dot")
STATES = {"inverse_dynamics": 3, "mass_matrix": 1, "coriolis_matrix": 2, "regressor": 3, "forward_dynamics": 3,
          "mass_matrix_dot": 2}  # the state arrays each quantity takes (tau for forward dynamics)
LOWERINGS = {  # name: (URDF copy, floating base, quantities); every inertial parameter symbolic
    "g1": ("g1_29dof_rev_1_0.urdf", False, QUANTITIES),
    "g1_hands": ("g1_29dof_with_hand_rev_1_0.urdf", False, QUANTITIES),
    "g1_floating": ("g1_29dof_rev_1_0.urdf", True, ("mass_matrix", "inverse_dynamics")),
    "z1": ("z1.urdf", False, ("forward_dynamics",)),
    "z1_all": ("z1.urdf", False, QUANTITIES),
}
SECTIONS = {"quantities": ("g1_hands", "g1"), "agreement": ("z1_all", "g1"), "adam": ("g1_floating",),
            "rollout": ("z1",), "variants": ("g1",), "jax": ("g1", "g1_hands")}
SHARES = "0.36,0.46,0.58,0.80,0.90,0.98"
"""The default ``--shares``: the fraction of the budget after which each section (in the order of
:data:`SECTIONS`) starts no more cases, so that the later ones get time."""
SLOW = {("g1", "coriolis_matrix"), ("g1_hands", "coriolis_matrix"), ("g1_hands", "regressor")}
"""The cases whose JAX form XLA compiles for minutes on a GPU: run after every section."""
AGREEMENT = {"z1_all": QUANTITIES, "g1": ("mass_matrix", "forward_dynamics", "regressor", "mass_matrix_dot")}
"""The quantities whose kernels ``agreement`` compares with the JAX form computed on the CPU."""
AGREEMENT_LIMIT = 60.0
"""Seconds an ``agreement`` case may take: the reference is XLA's CPU compile of a quantity's JAX form, and in
one run on an H200 the G1's forward dynamics did not finish in 140 s, which left no time to the later sections."""
FORMER = {"JAXSKID_CUDA_TRIG": "library", "JAXSKID_CUDA_LAYOUT": "rows", "JAXSKID_CUDA_ORDER": "program",
          "JAXSKID_CUDA_CONSTANT": "0"}
"""The settings that build the kernels as jaxskid built them before the defaults of each."""
VARIANTS = {"library trig": {"JAXSKID_CUDA_TRIG": "library"}, "by state": {"JAXSKID_CUDA_LAYOUT": "rows"},
            "program order": {"JAXSKID_CUDA_ORDER": "program"},
            "parameters from their input": {"JAXSKID_CUDA_CONSTANT": "0"}, "all four former": FORMER,
            "not split": {"JAXSKID_CUDA_LONG": "1000000"}}
"""The kernel builds ``variants`` measures against the default (:mod:`jaxskid.lowering._cuda`'s settings)."""
VARIANT_QUANTITIES = ("mass_matrix", "coriolis_matrix", "inverse_dynamics")
"""The G1's quantities ``variants`` builds each way."""
SLOW_NEEDS = 120.0
"""Seconds left that a slow case needs to start."""
RESERVE = 10.0
"""Seconds kept for the summary at the end: a case still running then is abandoned."""
STEPS, DT = 500, 1e-3
START = time.perf_counter()


@dataclasses.dataclass
class Log:
    """The rows so far, printed as JSON lines as they come and appended to ``out``; the time left."""

    budget: float
    shares: dict[str, float]
    out: Path | None = None
    rows: list[dict] = dataclasses.field(default_factory=list)

    def __call__(self, **row) -> dict:
        line = json.dumps(row)
        print(line, flush=True)
        if self.out is not None:
            with self.out.open("a") as f:
                f.write(line + "\n")
        self.rows.append(row)
        return row

    def left(self) -> float:
        return self.budget - (time.perf_counter() - START)

    def fits(self, section: str) -> bool:
        """Whether ``section`` may start another case: its share of the budget (``--shares``) is not spent, and
        more than :data:`RESERVE` seconds are left."""
        return self.left() - (1 - self.shares[section]) * self.budget > 0 and self.left() > RESERVE


ABANDONED: list[threading.Thread] = []


def within(seconds: float, fn):
    """``fn()``, run in a daemon thread so that a compile past the budget can be left behind.

    Raises:
        TimeoutError: ``fn`` has not returned after ``seconds`` (it goes on running, in :data:`ABANDONED`).
    """
    box = {}

    def run():
        try:
            box["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(max(seconds, 0.0))
    if thread.is_alive():
        ABANDONED.append(thread)
        raise TimeoutError(f"still running after {seconds:.0f} s, abandoned")
    if "error" in box:
        raise box["error"]
    return box["value"]


def case(log: Log, fits: bool, fn, limit: float | None = None, **ids) -> dict:
    """One row: ``ids`` and the fields ``fn()`` returns; ``ids`` with ``skipped`` where it does not ``fit``, or
    with ``error`` (a failure is a result here, and the run goes on; so is running past the budget, or past
    ``limit`` seconds)."""
    if not fits:
        return log(**ids, skipped="budget")
    try:
        return log(**ids, **within(min(log.left() - RESERVE, limit or float("inf")), fn))
    except Exception as exc:  # noqa: BLE001
        return log(**ids, error=f"{type(exc).__name__}: {str(exc)[:300]}")


# ---------------------------------------------------------------------------------------------- inputs
def erd_robots() -> Path:
    return Path(importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"))


def with_origins(text: bytes) -> bytes:
    """The URDF ``text`` with ``<origin xyz="0 0 0" rpy="0 0 0"/>`` added to every joint that has none (the
    identity, which URDF readers assume; adam-robotics fails without one)."""
    from lxml import etree

    root = etree.fromstring(text)
    for joint in root.findall("joint"):
        if joint.find("origin") is None:
            joint.insert(0, etree.Element("origin", xyz="0 0 0", rpy="0 0 0"))
    return etree.tostring(root, xml_declaration=True, encoding="utf-8")


def prepare(urdf_dir: Path) -> None:
    """The URDF copies of :data:`URDFS` in ``urdf_dir``, without meshes."""
    urdf_dir.mkdir(parents=True, exist_ok=True)
    for name, source in URDFS.items():
        (urdf_dir / name).write_bytes(with_origins((erd_robots() / source).read_bytes()))
        print(f"wrote {urdf_dir / name}")


def lower(urdf_dir: Path, name: str, form: str) -> jaxskid.Dynamics:
    """The lowering ``name`` of :data:`LOWERINGS` in ``form`` (``JAXSKID_CUDA`` set before lowering)."""
    os.environ["JAXSKID_CUDA"] = "1" if form == "cuda" else "0"
    file, floating, quantities = LOWERINGS[name]
    robot = jaxskid.load(urdf_dir / file, **({"floating_base": True} if floating else {}))
    return jaxskid.lower(robot, quantities)


def lowered(log: Log, urdf_dir: Path, name: str, form: str, section: str) -> jaxskid.Dynamics | None:
    """:func:`lower` in a row: its time (``lower_s``, a second or two where the module was cached), the number
    of parameters (10 per moving body: all symbolic), ``dyn.report()`` and its time (``report_s``: it builds
    the kernels' libraries not built yet); None where it failed or ``section``'s time is over."""
    out = {}

    def run():
        start = time.perf_counter()
        out["dyn"] = lower(urdf_dir, name, form)
        lower_s, start = time.perf_counter() - start, time.perf_counter()
        report = out["dyn"].report()
        return {"lower_s": lower_s, "n_params": len(out["dyn"].parameters), "report_s": time.perf_counter() - start,
                "report": report}

    row = case(log, log.fits(section), run, section="lower", robot=name, form=form)
    return out.get("dyn") if "lower_s" in row else None


def unlowered(log: Log, section: str, **ids) -> None:
    """The row of a case whose functions are missing: its section's time was over, or a row above says why."""
    log(section=section, **ids, skipped="the functions failed, above" if log.fits(section) else "budget")


def derive(urdf_dir: Path, sections) -> None:
    """Every lowering the run needs into ``JAXSKID_CACHE_DIR``, under each setting whose generated module may
    differ: ``JAXSKID_CUDA`` 1 and 0, and ``JAXSKID_NATIVE`` 1 and 0 (whether the module carries the C that
    kernels are printed from). No C is compiled (``CC`` names no compiler): the CPU's libraries are not what the
    GPU runs."""
    os.environ["CC"] = "jaxskid-no-compiler"
    for name in dict.fromkeys(n for s in sections for n in SECTIONS[s]):
        for cuda, native in (("1", "1"), ("0", "0"), ("1", "0"), ("0", "1")):
            os.environ["JAXSKID_NATIVE"] = native
            start = time.perf_counter()
            lower(urdf_dir, name, "cuda" if cuda == "1" else "jax")
            print(json.dumps({"derive": name, "JAXSKID_CUDA": cuda, "JAXSKID_NATIVE": native,
                              "seconds": time.perf_counter() - start}), flush=True)


def states(count: int, batch: int, n: int, seed: int = 0) -> list[jax.Array]:
    """``count`` arrays ``(batch, n)``, uniform in [-1, 1], float64."""
    rng = np.random.default_rng(seed)
    return [jnp.asarray(rng.uniform(-1, 1, size=(batch, n))) for _ in range(count)]


IN_FLIGHT = 10
"""Calls issued before waiting, for the time per call with the calls in flight (:func:`in_flight`)."""


def in_flight(fn, args, calls: int = IN_FLIGHT, repeats: int = 3) -> float:
    """Seconds per call of ``fn(*args)`` with ``calls`` calls issued before waiting for them all (the median of
    ``repeats``): the device's time per call where the host's dispatch and its wait for the result overlap it,
    as in a loop of calls. A single call waited for (:func:`timed`) also counts the wait itself."""
    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready([fn(*args) for _ in range(calls)])
        times.append((time.perf_counter() - start) / calls)
    return float(np.median(times))


def per_state(fn, args, batch: int) -> dict:
    """``fn(*args)`` on float64 and on float32 states: first calls (seconds), median ns per state of one call
    waited for, and per state with :data:`IN_FLIGHT` calls in flight."""
    first, median = timed(fn, *args)
    args32 = [a.astype(jnp.float32) for a in args]
    first32, median32 = timed(fn, *args32)
    return {"first_s": first, "per_state_ns": 1e9 * median / batch,
            "first_s_f32": first32, "per_state_ns_f32": 1e9 * median32 / batch,
            "flight_ns": 1e9 * in_flight(fn, args) / batch, "flight_ns_f32": 1e9 * in_flight(fn, args32) / batch}


# ---------------------------------------------------------------------------------------------- sections
def quantities(log: Log, urdf_dir: Path, batch: int, forms, section: str = "quantities") -> list:
    """The section ``quantities`` (``"jax"``: the same in the JAX form) but the cases of :data:`SLOW` in the JAX
    form: returned, ``(ids, measure)``, to run after every section (:func:`slow`)."""
    deferred = []
    for form in forms:
        for name in SECTIONS[section]:
            dyn = lowered(log, urdf_dir, name, form, section)
            if dyn is None:
                for quantity in QUANTITIES:
                    unlowered(log, section, robot=name, quantity=quantity, form=form)
                continue
            report, args = dyn.report(), states(3, batch, dyn.n_dof)
            for quantity in QUANTITIES:
                ids = {"section": "quantities", "robot": name, "n_dof": dyn.n_dof, "quantity": quantity,
                       "form": form, "runs": report.get(quantity), "batch": batch}
                fn = getattr(dyn, quantity)
                measure = (lambda fn=fn, a=args[:STATES[quantity]]: per_state(fn, a, batch))
                if (name, quantity) in SLOW and "JAX form" in str(report.get(quantity)):
                    deferred.append((ids, measure))
                else:
                    case(log, log.fits(section), measure, **ids)
    return deferred


def agreement(log: Log, urdf_dir: Path) -> None:
    """The section ``agreement``: each quantity of :data:`AGREEMENT` as it runs (the CUDA kernel on a GPU) against
    the JAX form of the same generated module computed on the CPU, 64 states: the largest difference relative to
    the largest entry."""
    cpu = jax.devices("cpu")[0]
    for name, names in AGREEMENT.items():
        dyn = lowered(log, urdf_dir, name, "cuda", "agreement")
        report = dyn.report() if dyn is not None else {}
        for quantity in names:
            ids = {"section": "agreement", "robot": name, "quantity": quantity, "runs": report.get(quantity)}
            if dyn is None:
                unlowered(log, **ids)
                continue

            def measure(quantity=quantity):
                args = states(STATES[quantity], 64, dyn.n_dof, seed=5)
                got = np.asarray(getattr(dyn, quantity)(*args))
                program = jax.vmap(dyn.generated(quantity), in_axes=(*[0] * len(args), None))
                with jax.default_device(cpu):
                    want = np.asarray(jax.jit(program)(*jax.device_put([*args, dyn.param_vector()], cpu)))
                return {"rel_diff": float(np.max(np.abs(got - want)) / max(np.max(np.abs(want)), 1e-300))}

            case(log, log.fits("agreement"), measure, AGREEMENT_LIMIT, **ids)


def variants(log: Log, urdf_dir: Path, batch: int) -> None:
    """The section ``variants``: the G1's :data:`VARIANT_QUANTITIES` in CUDA kernels built the default way and each
    way of :data:`VARIANTS` (its environment set while lowering and at the first call, which compiles the kernel):
    first call and time per state, float64."""
    for variant, env in {"default": {}, **VARIANTS}.items():
        saved = {k: os.environ.get(k) for k in env}
        os.environ.update(env)
        try:
            dyn = lowered(log, urdf_dir, "g1", "cuda", "variants")
            for quantity in VARIANT_QUANTITIES:
                ids = {"robot": "g1", "quantity": quantity, "variant": variant}
                if dyn is None:
                    unlowered(log, "variants", **ids)
                    continue
                ids["section"] = "variants"
                args = states(STATES[quantity], batch, dyn.n_dof)
                case(log, log.fits("variants"),
                     lambda fn=getattr(dyn, quantity), a=args: {
                         **dict(zip(("first_s", "per_state_ns"), _first_and_ns(fn, a, batch))),
                         "flight_ns": 1e9 * in_flight(fn, a) / batch}, **ids)
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v


def _first_and_ns(fn, args, batch: int) -> tuple[float, float]:
    first, median = timed(fn, *args)
    return first, 1e9 * median / batch


def slow(log: Log, deferred) -> None:
    """The deferred cases of :func:`quantities`, each with at least :data:`SLOW_NEEDS` seconds left."""
    for ids, measure in deferred:
        case(log, log.left() >= SLOW_NEEDS, measure, **ids)


def adam_functions(urdf_dir: Path, joints, dtype) -> dict:
    """adam-robotics' batched ``mass_matrix`` and ``bias_force`` of the G1 copy, body-fixed velocities.

    adam 0.5 passes a sharding as ``device=`` to ``jnp.asarray``, which jax >= 0.10 refuses: its array spec
    is taken with ``device=None`` (a wrapper of a wrapper does the same)."""
    import adam.jax.computations as computations
    from adam import Representations

    spec = computations.spec_from_reference
    computations.spec_from_reference = lambda ref: dataclasses.replace(spec(ref), device=None)
    kd = computations.KinDynComputations(str(urdf_dir / LOWERINGS["g1_floating"][0]), list(joints), dtype=dtype,
                                         gravity=jnp.asarray([0, 0, -9.81, 0, 0, 0], dtype))
    kd.set_frame_velocity_representation(Representations.BODY_FIXED_REPRESENTATION)
    return {"mass_matrix": jax.jit(jax.vmap(kd.mass_matrix)), "bias": jax.jit(jax.vmap(kd.bias_force))}


def adam_section(log: Log, urdf_dir: Path, batch: int, forms) -> None:
    """The section ``adam``: adam-robotics first (its float64 results are the reference), then each form."""
    robot = jaxskid.load(urdf_dir / LOWERINGS["g1_floating"][0], floating_base=True)
    q, v = floating_states(batch, robot.n_dof)
    ours = {"mass_matrix": (q,), "bias": (q, v, jnp.zeros_like(v))}
    theirs = adam_inputs(q, v)
    order = np.r_[3:6, 0:3, 6:robot.nv]  # adam's base twist (v, omega) from ours (omega, v)
    reference = {}
    for library, form in (("adam", None), *(("jaxskid", f) for f in forms)):
        fns, runs = functions(log, urdf_dir, robot.joint_names, library, form)
        for quantity in ("mass_matrix", "bias"):
            ids = {"section": "adam", "robot": "g1_floating", "nv": robot.nv, "quantity": quantity,
                   "library": library, "form": form, "batch": batch,
                   "runs": runs.get("inverse_dynamics" if quantity == "bias" else quantity)}
            if fns is None:
                unlowered(log, **ids)
                continue
            args, permute = (theirs[quantity], None) if library == "adam" else (ours[quantity], order)
            case(log, log.fits("adam"), lambda fn=fns[quantity], args=args, permute=permute, quantity=quantity:
                 versus(fn, args, batch, reference, quantity, permute), **ids)


def functions(log: Log, urdf_dir: Path, joints, library: str, form: str | None) -> tuple[dict | None, dict]:
    """``({"mass_matrix": fn, "bias": fn}, report)`` of adam or of jaxskid in ``form``; ``(None, {})`` where it
    failed (a row says why) or did not fit."""
    if library == "jaxskid":
        dyn = lowered(log, urdf_dir, "g1_floating", form, "adam")
        return ({"mass_matrix": dyn.mass_matrix, "bias": dyn.inverse_dynamics}, dyn.report()) if dyn else (None, {})
    return _adam_functions(log, urdf_dir, joints), {}


def _adam_functions(log: Log, urdf_dir: Path, joints) -> dict | None:
    """adam's functions of float64 and of float32 inputs (a model of each dtype), or None where it failed."""
    try:
        by_dtype = {np.dtype(d): adam_functions(urdf_dir, joints, d) for d in (jnp.float64, jnp.float32)}
    except Exception as exc:  # noqa: BLE001 - no adam here: its rows say why
        log(section="adam", library="adam", error=f"{type(exc).__name__}: {str(exc)[:300]}")
        return None
    return {name: (lambda *a, name=name: by_dtype[a[0].dtype][name](*a)) for name in ("mass_matrix", "bias")}


def floating_states(batch: int, n: int, seed: int = 0) -> tuple[jax.Array, jax.Array]:
    """``q (batch, 7 + n)``: base position, unit quaternion (x, y, z, w), joints in [-1, 1]; ``v (batch, 6 + n)``:
    (omega, v_b) in the base frame, then the joint velocities (:mod:`jaxskid.runtime._free_flyer`)."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(batch, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = np.concatenate([rng.uniform(-1, 1, (batch, 3)), quat, rng.uniform(-1, 1, (batch, n))], axis=1)
    return jnp.asarray(q), jnp.asarray(rng.normal(size=(batch, 6 + n)))


def adam_inputs(q: jax.Array, v: jax.Array) -> dict:
    """adam's arguments of the states ``q, v``: the base pose as a 4 x 4 transform (base to world), the joint
    positions, the base twist (v_b, omega) in the base frame and the joint velocities."""
    from scipy.spatial.transform import Rotation

    q, v = np.asarray(q), np.asarray(v)
    pose = np.tile(np.eye(4), (len(q), 1, 1))
    pose[:, :3, :3] = Rotation.from_quat(q[:, 3:7]).as_matrix()  # scalar last, as ours
    pose[:, :3, 3] = q[:, :3]
    pose, s = jnp.asarray(pose), jnp.asarray(q[:, 7:])
    twist = jnp.asarray(np.concatenate([v[:, 3:6], v[:, :3]], axis=1))
    return {"mass_matrix": (pose, s), "bias": (pose, s, twist, jnp.asarray(v[:, 6:]))}


def versus(fn, args, batch: int, reference: dict, key: str, order) -> dict:
    """:func:`per_state`, and the largest difference of the float64 and float32 results from adam's float64,
    ``reference[key]``: adam's own call (``order`` None) sets it; ours are reordered to adam's velocities by
    ``order``."""
    row = per_state(fn, args, batch)
    for suffix, dtype in (("", jnp.float64), ("_f32", jnp.float32)):
        value = np.asarray(fn(*[a.astype(dtype) for a in args]), dtype=np.float64)
        if order is None and not suffix:
            reference[key] = value
            continue
        if order is not None:
            value = value[:, order][:, :, order] if value.ndim == 3 else value[:, order]
        if key in reference:
            row[f"max_abs_diff{suffix}"] = float(np.max(np.abs(value - reference[key])))
    return row


ROLLOUTS = {"one kernel": {}, "one kernel (float32)": {}, "one kernel (32 threads)": {"JAXSKID_CUDA_THREADS": "32"},
            "one kernel (128 threads)": {"JAXSKID_CUDA_THREADS": "128"},
            "one kernel (program order; parameters from their input)": {"JAXSKID_CUDA_ORDER": "program",
                                                                        "JAXSKID_CUDA_CONSTANT": "0"},
            "kernels per step": None}
"""How the ``rollout`` section's rollouts run, all in the form ``--forms`` gives first: the rollout one CUDA kernel
and its gradient another (:mod:`jaxskid.runtime._cuda_rollout`), with the settings given (and float32 states where
the name says so), or (None) a loop of steps, with :meth:`jaxskid.Dynamics.cuda_rollout` turned off on its
lowering. ``--rollouts`` chooses among them."""


def rollout(log: Log, urdf_dir: Path, batch: int, form: str, kinds) -> None:
    """The section ``rollout``: z1, :data:`STEPS` RK4 steps of :data:`DT`, batches 1, 1024 and ``batch``, each
    way ``kinds`` names of :data:`ROLLOUTS`."""
    for kind in kinds:
        settings = ROLLOUTS[kind]
        dyn = lowered(log, urdf_dir, "z1", form, "rollout")
        if dyn is not None and settings is None:
            dyn.cuda_rollout = lambda steps: None
        saved = {k: os.environ.get(k) for k in settings or {}}
        os.environ.update(settings or {})
        try:
            rollouts(log, dyn, batch, form, kind)
        finally:
            for k, v in saved.items():
                os.environ.pop(k) if v is None else os.environ.update({k: v})


def rollouts(log: Log, dyn, batch: int, form: str, kind: str) -> None:
    batches = sorted({1, min(1024, batch), batch})
    if dyn is None:
        for b in batches:
            unlowered(log, "rollout", robot="z1", steps=STEPS, batch=b, form=form, rollout=kind)
        return
    n = dyn.n_dof
    t = DT * np.arange(STEPS)[:, None]
    u = jnp.asarray(2.0 * np.sin(2 * np.pi * (1 + np.arange(n)) * t / (STEPS * DT)))
    goal = jnp.concatenate([jnp.full(n, 0.3), jnp.zeros(n)])
    runs = dyn.report().get("forward_dynamics")
    if kind.startswith("one kernel"):
        runs = "rollout kernels" if dyn.cuda_rollout(STEPS) is not None else f"no rollout kernel; {runs}"
    for b in batches:
        dtype = jnp.float32 if "float32" in kind else jnp.float64
        ids = {"section": "rollout", "robot": "z1", "steps": STEPS, "batch": b, "form": form, "rollout": kind,
               "dtype": jnp.dtype(dtype).name, "runs": runs}
        x0 = jnp.zeros(2 * n).at[:n].set(0.1)
        if b > 1:
            x0 = x0 + jnp.concatenate([0.05 * states(1, b, n, seed=b)[0], jnp.zeros((b, n))], axis=1)
        case(log, log.fits("rollout"),
             lambda x0=x0, b=b: rollout_case(dyn, x0.astype(dtype), u.astype(dtype), goal.astype(dtype), b), **ids)


def rollout_case(dyn, x0, u, goal, batch: int) -> dict:
    """The loss ``mean((x - goal)^2)`` over a rollout from ``x0`` under the torques ``u``, and its gradient with
    respect to every parameter, both jitted: medians, first calls, ratio, time per state and step."""
    def loss(p):
        return jnp.mean((jaxskid.rollout(dyn, x0, u, DT, STEPS, params=p).x - goal) ** 2)

    p0 = dyn.param_vector(dtype=x0.dtype)
    loss_fn, grad_fn = jax.jit(loss), jax.jit(jax.grad(loss))
    loss_first, loss_time = timed(loss_fn, p0)
    grad_first, grad_time = timed(grad_fn, p0)
    weights = jnp.asarray(np.random.default_rng(7).normal(size=len(p0)))
    # the values, for comparing the ways of ROLLOUTS in one run
    checks = {"loss_value": float(loss_fn(p0)), "grad_dot_w": float(weights @ grad_fn(p0))}
    return {"loss_ms": 1e3 * loss_time, "grad_ms": 1e3 * grad_time, "ratio": grad_time / loss_time, **checks,
            "loss_first_s": loss_first, "grad_first_s": grad_first, "n_params": len(p0),
            "loss_ns_per_state_step": 1e9 * loss_time / (batch * STEPS),
            "grad_ns_per_state_step": 1e9 * grad_time / (batch * STEPS)}


# ---------------------------------------------------------------------------------------------- summary
def _runs(x) -> str:
    return x.split(" (")[0] if isinstance(x, str) else "-"


def S(seconds: float) -> str:
    return doc_tables.duration(seconds)


def NS(nanoseconds: float) -> str:
    return doc_tables.duration(1e-9 * nanoseconds)


def MS(milliseconds: float) -> str:
    return doc_tables.duration(1e-3 * milliseconds)


TABLES = {  # section: (column, key, format); the columns with a format but _runs are measured
    "lower": [("lowering", "robot", None), ("form", "form", None),
              ("lower (load + import of the cached module)", "lower_s", S), ("parameters", "n_params", str),
              ("report (builds the kernels)", "report_s", S)],
    "agreement": [("robot", "robot", None), ("quantity", "quantity", None), ("runs", "runs", _runs),
                  ("largest difference from the JAX form on CPU, relative", "rel_diff", "{:.1e}".format)],
    "quantities": [("robot", "robot", None), ("DOF", "n_dof", None), ("quantity", "quantity", None),
                   ("form", "form", None), ("runs", "runs", _runs), ("first call", "first_s", S),
                   ("per state", "per_state_ns", NS), ("float32 first call", "first_s_f32", S),
                   ("float32 per state", "per_state_ns_f32", NS), ("per state, calls in flight", "flight_ns", NS),
                   ("the same, float32", "flight_ns_f32", NS)],
    "adam": [("quantity", "quantity", None), ("library", "library", None), ("form", "form", None),
             ("runs", "runs", _runs), ("first call", "first_s", S), ("per state", "per_state_ns", NS),
             ("float32 first call", "first_s_f32", S), ("float32 per state", "per_state_ns_f32", NS),
             ("per state, calls in flight", "flight_ns", NS), ("the same, float32", "flight_ns_f32", NS),
             ("max abs diff from adam's float64", "max_abs_diff", "{:.1e}".format),
             ("the same, float32", "max_abs_diff_f32", "{:.1e}".format)],
    "variants": [("quantity", "quantity", None), ("kernel build", "variant", None), ("first call", "first_s", S),
                 ("per state", "per_state_ns", NS), ("per state, calls in flight", "flight_ns", NS)],
    "rollout": [("batch", "batch", None), ("form", "form", None), ("rollout", "rollout", None),
                ("dtype", "dtype", None), ("runs", "runs", _runs), ("loss", "loss_ms", MS),
                ("gradient", "grad_ms", MS), ("ratio", "ratio", "{:.1f}x".format),
                ("first call loss", "loss_first_s", S), ("first call gradient", "grad_first_s", S),
                ("loss per state-step", "loss_ns_per_state_step", NS),
                ("gradient per state-step", "grad_ns_per_state_step", NS)],
}


def summary(rows: list[dict]) -> list[str]:
    """A Markdown table of each section's rows; a skipped or failed case says so in its first measured cell.
    Rows of several runs (``--rows``) carry their run's number, in a first column."""
    lines = []
    for section, columns in TABLES.items():
        if any("run" in r for r in rows):
            columns = [("run", "run", None), *columns]
        first = next(k for k, (_, _, f) in enumerate(columns) if f not in (None, _runs))
        cells = []
        for row in (r for r in rows if r.get("section") == section):
            line = ["-" if row.get(key) is None else (f or str)(row[key]) for _, key, f in columns]
            note = row.get("error") or (row.get("skipped") and f"skipped ({row['skipped']})")
            if note:
                line[first:] = [note.replace("|", "/")[:120], *["-"] * (len(columns) - first - 1)]
            cells.append(line)
        if cells:
            lines += [f"**{section}**", "", *doc_tables.table([c for c, _, _ in columns], cells), ""]
    return lines


def write_tables(markdown: Path | None, heading: str, rows: list[dict], batch: int, more: str = "") -> None:
    """The tables of :func:`summary` under ``heading`` (the device, JAX's version, the date), printed and written
    to ``markdown``."""
    lines = doc_tables.Lines()
    for line in [heading, "", *summary(rows)]:
        lines(line)
    doc_tables.write(markdown, lines, f"Batch {batch}, medians of 5 calls; first call: XLA's compile and the run "
                     "(its persistent cache off; a CUDA kernel's NVRTC compile too), the generated modules cached; "
                     "every inertial parameter symbolic; form: JAXSKID_CUDA=1 (cuda) or 0 (jax) when lowered. " + more)


# ---------------------------------------------------------------------------------------------- main
def arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--budget", type=float, default=420.0, help="seconds for the whole run")
    parser.add_argument("--out", type=Path, default=None, help="append each row (a JSON line) to this file")
    parser.add_argument("--batch", type=int, default=16384)
    parser.add_argument("--sections", default=",".join(SECTIONS))
    parser.add_argument("--shares", default=SHARES, help="fraction of the budget after which quantities, adam and "
                        "rollout each start no more cases (what a section leaves goes to the next)")
    parser.add_argument("--forms", default="cuda,jax", help="in this order; the rollout runs the first")
    parser.add_argument("--rollouts", default=",".join(ROLLOUTS), help="the ways the rollout section runs")
    parser.add_argument("--urdf-dir", type=Path, default=ROOT / ".gpu" / "urdf")
    parser.add_argument("--prepare", action="store_true", help="only write the URDF copies into --urdf-dir")
    parser.add_argument("--derive-only", action="store_true", help="only fill JAXSKID_CACHE_DIR")
    parser.add_argument("--rows", type=Path, default=None, help="measure nothing: write --markdown from the rows "
                        "of earlier runs (JSON lines, each with the number of its run)")
    parser.add_argument("--runs", default=None, help="with --rows: only these runs (numbers, comma-separated)")
    doc_tables.add_option(parser)
    args = parser.parse_args()
    args.sections, args.forms, args.rollouts = args.sections.split(","), args.forms.split(","), args.rollouts.split(",")
    if not set(args.rollouts) <= set(ROLLOUTS):
        parser.error(f"--rollouts: choose from {', '.join(ROLLOUTS)}")
    if not set(args.sections) <= set(SECTIONS) or not set(args.forms) <= {"cuda", "jax"}:
        parser.error(f"--sections: choose from {', '.join(SECTIONS)}; --forms: from cuda, jax")
    try:
        args.shares = dict(zip(SECTIONS, map(float, args.shares.split(",")), strict=True))
    except ValueError:
        parser.error(f"--shares: expected {len(SECTIONS)} numbers, got {args.shares!r}")
    return args


def main() -> None:
    args = arguments()
    if args.prepare:
        prepare(args.urdf_dir)
        return
    if args.derive_only:
        derive(args.urdf_dir, args.sections)
        return
    if args.rows is not None:
        rows = [json.loads(line) for line in args.rows.read_text().splitlines() if line.strip()]
        if args.runs:
            rows = [r for r in rows if str(r.get("run")) in args.runs.split(",")]
        starts = [r for r in rows if r.get("section") == "start"]
        rows = [r for r in rows if r.get("section") != "lower" and "skipped" not in r]  # what was measured
        heading = "; ".join(f"run {r.get('run', k + 1)}: {r['device']}, jax {r['jax']}, {r['date']}"
                            for k, r in enumerate(starts))
        write_tables(args.markdown, heading, rows, starts[0]["batch"], f"The rows of {args.rows.name}.")
        return
    jaxskid.compilation_cache(None)  # every first call compiles: none finds a program an earlier form compiled
    log = Log(args.budget, args.shares, args.out)
    device = jax.devices()[0]
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    log(section="start", device=device.device_kind, backend=jax.default_backend(), jax=jax.__version__, date=stamp,
        batch=args.batch, budget=args.budget, shares=args.shares, cache=str(jaxskid.cache_dir()),
        env={k: os.environ.get(k) for k in ("JAXSKID_CUDA", "JAXSKID_NATIVE")})
    deferred = quantities(log, args.urdf_dir, args.batch, args.forms[:1]) if "quantities" in args.sections else []
    if "agreement" in args.sections:  # after the first calls of "quantities": its kernels are then compiled
        agreement(log, args.urdf_dir)
    if "adam" in args.sections:
        adam_section(log, args.urdf_dir, args.batch, args.forms)
    if "rollout" in args.sections:
        rollout(log, args.urdf_dir, args.batch, args.forms[0], args.rollouts)
    if "variants" in args.sections:
        variants(log, args.urdf_dir, args.batch)
    if "jax" in args.sections:
        deferred += quantities(log, args.urdf_dir, args.batch, args.forms[1:], "jax")
    slow(log, deferred)
    log(section="end", seconds=time.perf_counter() - START, abandoned=len(ABANDONED))
    write_tables(args.markdown, f"{device.device_kind}, jax {jax.__version__}, {stamp}", log.rows, args.batch)
    if ABANDONED:  # a compile left running in a daemon thread: leave without waiting for it
        sys.stdout.flush()
        os._exit(0)


if __name__ == "__main__":
    main()
