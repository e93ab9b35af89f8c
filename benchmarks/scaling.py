"""How the cost of each quantity grows with the robot, against Pinocchio in the same run.

    python benchmarks/scaling.py [--robots ur5,panda,solo12,g1,g1_hands] [--batch 4096] [--repeats 7]
                                 [--quantities ...] [--plot benchmarks/out/scaling.png] [--no-floating]
                                 [--trig auto|fused] [--cold-apart] [--markdown PATH]

Robots (fixed base, from example-robot-data): UR5 (6 DOF), Panda (7, fingers locked), solo12 (12), the
Unitree G1 (29) and the G1 with hands (43), every inertial parameter symbolic. For each robot and quantity:

- ``cold``: derive + lower + compile + first call of that quantity alone, with an empty cache (generated
  module, native library and XLA's compilation cache all in a fresh folder); with ``--cold-apart``, in a new
  process on every core of the machine, whatever this one may use (XLA's code generation and a long program's
  parts, ``jaxskid/runtime/_parts.py``, use several), so that ``taskset -c 1`` keeps the times per state
  on one core;
- ``jaxskid``: the median time per state of the public function on a batch (``dyn.mass_matrix(q)``,
  ``q`` of shape ``(batch, n)``, float64);
- ``out=``: the same for a matrix-valued quantity written into an earlier result's memory
  (``dyn.mass_matrix(q, out=m)``, donated), as Pinocchio writes into its ``data`` at every call: a large
  batch's result then fills no fresh memory, whose first touch costs the kernel's page clearing (the G1's
  regressor, 275 MB at batch 4096: see ``benchmarks/memory_floor.py``);
- ``pinocchio``: the median time per call of Pinocchio's function for the same quantity from Python
  (``rnea``, ``crba``, ``computeCoriolisMatrix``, ``computeJointTorqueRegressor``, ``aba``; for
  ``mass_matrix_dot``, ``computeCoriolisMatrix`` and ``C + C^T``), and the ratio pinocchio / jaxskid
  (> 1: jaxskid is faster per state).

Quantities Pinocchio lacks (``mass_matrix_ddot``, ``coriolis_matrix_dot``, ``coriolis_matrix_ddot``, if
asked for) are reported against jaxskid's own mass matrix at the same size. ``JAXSKID_NATIVE=0`` in the
environment times the pure-JAX form of every quantity (the form used off CPU); ``--float32`` adds the time
per state on float32 states; ``JAXSKID_MALLOC=keep`` makes the allocator keep freed memory, so that large
results do not fault in fresh pages at every call (the footer says when it was set). The plot is time per state against DOF on log-log axes, one line per quantity
for jaxskid (solid) and Pinocchio (dashed).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402
from core import median_time as _median  # noqa: E402  (benchmarks/core.py, beside this script)
import floating_base  # noqa: E402  (beside this script too)
import doc_tables  # noqa: E402  (beside this script too)

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
ROBOTS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", None),
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "solo12": ("solo_description/robots/solo12.urdf", None),
    "g1": ("g1_description/urdf/g1_29dof_rev_1_0.urdf", None),
    "g1_hands": ("g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf", None),
}
QUANTITIES = ("inverse_dynamics", "mass_matrix", "coriolis_matrix", "regressor", "forward_dynamics",
              "mass_matrix_dot")
STATES = {  # the state arrays each quantity takes (tau for forward dynamics)
    "inverse_dynamics": 3, "mass_matrix": 1, "coriolis_matrix": 2, "regressor": 3, "forward_dynamics": 3,
    "mass_matrix_dot": 2, "mass_matrix_ddot": 3, "coriolis_matrix_dot": 3, "coriolis_matrix_ddot": 4,
}


def _pinocchio_model(path: Path, lock):
    model = pin.buildModelFromUrdf(str(path))
    if lock:
        ids = [model.getJointId(name) for name in lock]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    return model


def _pinocchio_calls(model) -> dict:
    data = model.createData()

    def coriolis_sum(q, v, a):
        c = pin.computeCoriolisMatrix(model, data, q, v)
        return c + c.T

    return {
        "inverse_dynamics": lambda q, v, a: pin.rnea(model, data, q, v, a),
        "mass_matrix": lambda q, v, a: pin.crba(model, data, q),
        "coriolis_matrix": lambda q, v, a: pin.computeCoriolisMatrix(model, data, q, v),
        "regressor": lambda q, v, a: pin.computeJointTorqueRegressor(model, data, q, v, a),
        "forward_dynamics": lambda q, v, a: pin.aba(model, data, q, v, a),
        "mass_matrix_dot": coriolis_sum,
    }


def _pinocchio_time(fn, states: np.ndarray, repeats: int) -> float:
    count = min(len(states[0]), 256)

    def loop():
        for k in range(count):
            fn(states[0][k], states[1][k], states[2][k])

    return _median(loop, repeats) / count


def cold_apart(robot_name: str, name: str, batch: int, cache: str) -> float:
    """The cold first call of ``name`` in a new process on every core of the machine (``--cold-apart``), with
    its generated module kept in ``cache`` for this process."""
    def every_core():
        try:
            os.sched_setaffinity(0, range(os.cpu_count() or 1))
        except OSError:  # cores this process may not use
            pass

    command = [sys.executable, __file__, "--cold-child", robot_name, name, str(batch), cache]
    done = subprocess.run(command, capture_output=True, text=True, preexec_fn=every_core, check=False)
    if done.returncode:
        raise RuntimeError(f"the cold first call of {robot_name} {name} failed:\n{done.stderr[-2000:]}")
    return float(done.stdout.split()[-1])


def cold_child(robot_name: str, name: str, batch: int, cache: str) -> None:
    """``--cold-child``: derive, lower, compile and call ``name`` once, and print the seconds that took."""
    path, lock = ROBOTS[robot_name]
    robot = jaxskid.load(ERD / path, lock=lock)
    states = np.random.default_rng(0).uniform(-1, 1, size=(4, batch, robot.n_dof))
    args = [jnp.asarray(s) for s in states][: STATES[name]]
    empty_compilation_cache()
    start = time.perf_counter()
    dyn = jaxskid.lower(robot, [name], cache_dir=cache)
    jax.block_until_ready(getattr(dyn, name)(*args))
    print(f"{time.perf_counter() - start:.3f}")


def measure(robot_name: str, quantities, batch: int, repeats: int, out=print, single: bool = False,
            apart: bool = False) -> list[dict]:
    """The rows of one robot: per quantity, cold time (with ``apart``, :func:`cold_apart`), jaxskid and Pinocchio
    per state."""
    path, lock = ROBOTS[robot_name]
    robot = jaxskid.load(ERD / path, lock=lock)
    n = robot.n_dof
    model = _pinocchio_model(ERD / path, lock)
    assert model.nv == n, (model.nv, n)
    rng = np.random.default_rng(0)
    states = rng.uniform(-1, 1, size=(4, batch, n))
    arrays = [jnp.asarray(s) for s in states]
    pin_calls = _pinocchio_calls(model)
    rows, mass_time = [], None
    for name in quantities:
        args = arrays[: STATES[name]]
        with tempfile.TemporaryDirectory() as cache:
            cold = cold_apart(robot_name, name, batch, cache) if apart else None
            start = time.perf_counter()
            dyn = jaxskid.lower(robot, [name], cache_dir=cache)
            fn = getattr(dyn, name)
            jax.block_until_ready(fn(*args))
            cold = time.perf_counter() - start if cold is None else cold
            dyn.native_target()  # the derivatives' library, built at a low priority meanwhile: done before timing
            ours = _median(lambda: jax.block_until_ready(fn(*args)), repeats) / batch
            matrix = len(dyn.signature(name)[1]) >= 2  # also timed written into an earlier result (out=)
            reused = _reused_time(fn, args, repeats) / batch if matrix else None
            f32 = None
            if single:  # the same function on float32 states (its program traced and compiled again)
                args32 = [a.astype(jnp.float32) for a in args]
                jax.block_until_ready(fn(*args32))
                f32 = _median(lambda: jax.block_until_ready(fn(*args32)), repeats) / batch
        theirs = _pinocchio_time(pin_calls[name], states, repeats) if name in pin_calls else None
        if name == "mass_matrix":
            mass_time = ours
        rows.append({"robot": robot_name, "n_dof": n, "quantity": name, "cold": cold, "jaxskid": ours,
                     "reused": reused, "pinocchio": theirs, "mass_matrix": mass_time, "f32": f32})
        out(_row_line(rows[-1]))
    return rows


def _reused_time(fn, args, repeats: int) -> float:
    """The median time of ``fn(*args, out=previous result)``: each call writes into the last one's memory."""
    last = [jax.block_until_ready(fn(*args))]

    def call():
        last[0] = jax.block_until_ready(fn(*args, out=last[0]))

    return _median(call, repeats)


def _malloc() -> str:
    """How glibc allocates in this run: ``JAXSKID_MALLOC=keep`` keeps freed memory (:mod:`jaxskid._xla_flags`)."""
    return ", JAXSKID_MALLOC=keep" if os.environ.get("JAXSKID_MALLOC") == "keep" else ""


def _row_line(row: dict) -> str:
    theirs, reused = row["pinocchio"], row["reused"]
    if theirs is not None:
        peer = f"{theirs * 1e6:.2f} µs | {theirs / row['jaxskid']:.1f}x"
        into = f"{reused * 1e6:.2f} µs ({theirs / reused:.1f}x)" if reused else "-"
    elif row["mass_matrix"]:
        peer = f"- | {row['jaxskid'] / row['mass_matrix']:.1f}x M's cost"
        into = f"{reused * 1e6:.2f} µs" if reused else "-"
    else:
        peer, into = "- | -", "-"
    single = "" if row["f32"] is None else f" {row['f32'] * 1e6:.2f} µs ({row['jaxskid'] / row['f32']:.2f}x) |"
    return (f"| {row['robot']} | {row['n_dof']} | {row['quantity']} | {row['cold']:.1f} s "
            f"| {row['jaxskid'] * 1e6:.2f} µs | {into} | {peer} |{single}")


def plot(rows: list[dict], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, ax = plt.subplots(figsize=(7, 5))
    names = list(dict.fromkeys(r["quantity"] for r in rows))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, name in enumerate(names):
        mine = sorted((r["n_dof"], r["jaxskid"], r["pinocchio"], r.get("reused")) for r in rows if r["quantity"] == name)
        dofs = [m[0] for m in mine]
        color = colors[k % len(colors)]
        ax.plot(dofs, [1e6 * m[1] for m in mine], "o-", color=color, label=f"{name} (jaxskid)")
        if all(m[3] is not None for m in mine):
            ax.plot(dofs, [1e6 * m[3] for m in mine], "^:", color=color, alpha=0.8)
        if all(m[2] is not None for m in mine):
            ax.plot(dofs, [1e6 * m[2] for m in mine], "s--", color=color, alpha=0.6, label=f"{name} (Pinocchio)")
    if any(r.get("reused") for r in rows):
        ax.plot([], [], "^:", color="0.4", label="jaxskid, out= (written into the last result)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    dofs = sorted({r["n_dof"] for r in rows})
    ax.set_xticks(dofs, [str(d) for d in dofs])
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("degrees of freedom")
    ax.set_ylabel("time per state (µs)")
    native = os.environ.get("JAXSKID_NATIVE", "1") not in ("0", "false", "off", "no")
    ax.set_title(f"jaxskid per state (batch, {'native on CPU' if native else 'pure JAX'}) and Pinocchio per call")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)


def force_fused_trig() -> None:
    """Make the modules generated from now on use the multiply-add sine and cosine on every platform."""
    from jaxskid.codegen import _jax

    choice = "    if jax.default_backend() == \"cpu\":\n        return _sincos(x)\n"
    assert choice in _jax.FUSED_SOURCE, "jaxskid/_fused.py changed: update force_fused_trig"
    _jax.FUSED_SOURCE = _jax.FUSED_SOURCE.replace(choice, "    return _sincos(x)\n")


def empty_compilation_cache() -> None:
    """XLA's compilation cache in a fresh folder, for cold figures: ``jaxskid.lower`` keeps it in
    ``jaxskid.cache_dir()`` whatever the ``cache_dir`` of the generated module, so a second run of a script
    would find the programs of the first."""
    jaxskid.compilation_cache(tempfile.mkdtemp(prefix="jaxskid-xla-"))


def _apart(apart: bool) -> str:
    if not apart:
        return ""
    return f", each in a new process on the machine's {os.cpu_count()} cores (--cold-apart)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--quantities", default=",".join(QUANTITIES))
    parser.add_argument("--batch", type=int, default=4096)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--plot", type=Path, default=Path(__file__).parent / "out" / "scaling.png")
    parser.add_argument("--trig", choices=("auto", "fused"), default="auto",
                        help="fused: the multiply-add sine and cosine on every platform (jaxskid's programs use them "
                             "on CPU and XLA's own elsewhere), to compare the two on a GPU")
    parser.add_argument("--floating", action=argparse.BooleanOptionalAction, default=True,
                        help="then the floating-base rows of benchmarks/floating_base.py: tau and M of solo12 and "
                             "the G1 on a free-flyer, and solo12's constrained forward dynamics on four contacts")
    parser.add_argument("--float32", action="store_true",
                        help="also time each function on float32 states: the column float32 per state, and float64's "
                             "time over float32's (> 1: float32 is faster)")
    parser.add_argument("--cold-apart", action="store_true",
                        help="time each cold first call in a new process on every core of the machine, the times per "
                             "state in this one (under taskset -c 1: on one core, as Pinocchio's loop runs)")
    parser.add_argument("--cold-child", nargs=4, metavar=("ROBOT", "QUANTITY", "BATCH", "CACHE"),
                        help=argparse.SUPPRESS)
    doc_tables.add_option(parser)
    args = parser.parse_args()
    if args.cold_child:
        robot, name, batch, cache = args.cold_child
        return cold_child(robot, name, int(batch), cache)
    empty_compilation_cache()
    quantities = args.quantities.split(",")
    if args.trig == "fused":
        force_fused_trig()
    if any(q not in STATES for q in quantities):
        parser.error(f"--quantities: choose from {', '.join(STATES)}")
    print(f"jax {jax.__version__} on {jax.default_backend()}, Pinocchio {pin.__version__}, float64, batch {args.batch}, "
          f"JAXSKID_NATIVE={os.environ.get('JAXSKID_NATIVE', '1')}, sine and cosine {args.trig}{_malloc()}")
    out = doc_tables.Lines()
    out("| robot | DOF | quantity | cold derive+lower+compile | jaxskid per state | with out= (ratio) "
        "| Pinocchio per call | ratio |" + (" float32 per state (float64 / float32) |" if args.float32 else ""))
    out("|---|---|---|---|---|---|---|---|" + ("---|" if args.float32 else ""))
    rows = []
    for robot in args.robots.split(","):
        rows += measure(robot, quantities, args.batch, args.repeats, out, args.float32, args.cold_apart)
    native = os.environ.get("JAXSKID_NATIVE", "1")
    single = "; the float32 column: the same function on float32 states" if args.float32 else ""
    doc_tables.write(args.markdown, out, f"Batch {args.batch}, float64{single}, every inertial parameter symbolic, medians "
                     f"of {args.repeats}; Pinocchio one call from Python in the same run; cold: derive, lower, "
                     f"compile and first call with every cache empty{_apart(args.cold_apart)}; "
                     f"JAXSKID_NATIVE={native}, sine and cosine {args.trig}{_malloc()}.")
    if args.plot:
        plot(rows, args.plot)
        print(f"plot: {args.plot}")
    if args.floating:
        print()
        floating_base.main(args.batch, args.repeats)


if __name__ == "__main__":
    main()
