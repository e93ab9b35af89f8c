"""Derive + lower + compile time, and batched throughput of tau, M, Q_grav and C qd against Pinocchio.

    python benchmarks/core.py [--robot panda] [--repeats 7] [--markdown PATH]
    python benchmarks/core.py --params-cost     # only: parameters as a dict against a vector (G1)

Every figure is a median over repeats, measured in this run, through the public functions
(``dyn.mass_matrix(q)`` with ``q`` of shape ``(batch, n)``; batch 1 is one state of shape ``(n,)``); the
Pinocchio figures are per call from Python on the same states. Ratios > 1 mean jaxskid is faster per state.

``--params-cost`` times ``inverse_dynamics`` of the Unitree G1 (29 DOF, fixed base, 290 parameters) per
call with its parameters given as a dict of plain numbers (``dyn.default_params()``) and as a vector
(``dyn.param_vector()``), on one state and on a batch of 4096; the two calls alternate, each figure is the
median, and the ratio dict / vector is the cost of naming the parameters.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
ROBOTS = {
    "panda": (ERD / "panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "ur5": (ERD / "ur_description/urdf/ur5_robot.urdf", None),
    "solo12": (ERD / "solo_description/robots/solo12.urdf", None),
}
G1 = ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf"
QUANTITIES = ("inverse_dynamics", "mass_matrix", "gravity_torques", "coriolis_torques")
ARGS = {"inverse_dynamics": 3, "mass_matrix": 1, "gravity_torques": 1, "coriolis_torques": 2}


def median_time(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def alternating_medians(calls, repeats: int) -> list[float]:
    """The median time of each call, the calls taken in turn (so that load on the machine hits all alike)."""
    for call in calls:
        call()
    times = [[] for _ in calls]
    for _ in range(repeats):
        for call, out in zip(calls, times):
            t = time.perf_counter()
            call()
            out.append(time.perf_counter() - t)
    return [float(np.median(t)) for t in times]


def add_robot_options(parser, robots: str, batch: int, repeats: int) -> None:
    """``--robots`` (comma-separated names), ``--batch``, ``--repeats`` and ``--markdown PATH`` on a script's
    argument parser, with the script's defaults."""
    parser.add_argument("--robots", default=robots)
    parser.add_argument("--batch", type=int, default=batch)
    parser.add_argument("--repeats", type=int, default=repeats)
    doc_tables.add_option(parser)


def panda(quantities) -> jaxskid.Dynamics:
    """example-robot-data's Panda as a 7-DOF arm (its fingers locked closed), lowered with ``quantities``."""
    path, lock = ROBOTS["panda"]
    return jaxskid.lower(jaxskid.load(path, lock=lock), quantities)


def params_cost(repeats: int, markdown=None) -> None:
    """``inverse_dynamics`` of the G1 per call, parameters as a dict against a vector."""
    robot = jaxskid.load(G1)
    dyn = jaxskid.lower(robot, ["inverse_dynamics"])
    vector, named = dyn.param_vector(), dyn.default_params()
    print(f"G1: {robot.n_dof} DOF, {len(dyn.parameters)} parameters, inverse_dynamics, jax {jax.__version__}, "
          f"float64; median per call, dict and vector calls alternating")
    print(f"{'batch':>6s} {'vector us/call':>15s} {'dict us/call':>13s} {'dict / vector':>14s}")
    rng = np.random.default_rng(0)
    rows = []
    for batch, count in ((1, max(repeats, 201)), (4096, max(repeats, 21))):
        q, qd, qdd = (jnp.asarray(rng.uniform(-1, 1, size=(batch, robot.n_dof))) for _ in range(3))
        if batch == 1:
            q, qd, qdd = q[0], qd[0], qdd[0]
        t_vec, t_dict = alternating_medians(
            [lambda: jax.block_until_ready(dyn.inverse_dynamics(q, qd, qdd, vector)),
             lambda: jax.block_until_ready(dyn.inverse_dynamics(q, qd, qdd, named))], count)
        print(f"{batch:6d} {t_vec * 1e6:15.1f} {t_dict * 1e6:13.1f} {t_dict / t_vec:14.2f}")
        rows.append([batch, f"{t_vec * 1e6:.1f} µs", f"{t_dict * 1e6:.1f} µs", f"{t_dict / t_vec:.2f}"])
    lines = doc_tables.table(["batch", "vector, per call", "dict, per call", "dict / vector"], rows)
    doc_tables.write(markdown, lines, f"The G1 (29 DOF, {len(dyn.parameters)} parameters), `inverse_dynamics`, "
                     "float64; medians per call, the dict and vector calls alternating.")


def pinocchio_calls(model, q, qd, qdd, repeats):
    data = model.createData()
    n = len(q)
    funcs = {
        "inverse_dynamics": lambda k: pin.rnea(model, data, q[k], qd[k], qdd[k]),
        "mass_matrix": lambda k: pin.crba(model, data, q[k]),
        "gravity_torques": lambda k: pin.computeGeneralizedGravity(model, data, q[k]),
        "coriolis_torques": lambda k: pin.nonLinearEffects(model, data, q[k], qd[k]),
    }
    out = {}
    for name, f in funcs.items():
        def loop():
            for k in range(n):
                f(k)
        out[name] = median_time(loop, repeats) / n
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="panda", choices=sorted(ROBOTS))
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--batches", default="1,1024,65536")
    ap.add_argument("--symbolic", choices=("all", "none"), default="all",
                    help="keep every inertial parameter symbolic (all) or substitute the URDF values (none)")
    ap.add_argument("--params-cost", action="store_true",
                    help="only time the G1's inverse_dynamics with its parameters as a dict against a vector")
    doc_tables.add_option(ap)
    args = ap.parse_args(argv)
    if args.params_cost:
        params_cost(args.repeats, args.markdown)
        return
    path, lock = ROBOTS[args.robot]
    batches = [int(b) for b in args.batches.split(",")]

    jaxskid.compilation_cache(tempfile.mkdtemp(prefix="jaxskid-xla-"))  # cold: XLA's cache empty too
    t0 = time.perf_counter()
    robot = jaxskid.load(path, lock=lock)
    t_load = time.perf_counter() - t0
    symbolic = None if args.symbolic == "all" else ()
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        dyn = jaxskid.lower(robot, QUANTITIES, symbolic=symbolic, cache_dir=cache)
        t_derive = time.perf_counter() - t0
        t0 = time.perf_counter()
        dyn2 = jaxskid.lower(robot, QUANTITIES, symbolic=symbolic, cache_dir=cache)
        t_cached = time.perf_counter() - t0
    assert dyn2.source == dyn.source
    n = robot.n_dof
    p = dyn.param_vector()
    rng = np.random.default_rng(0)
    big = max(batches)
    states = rng.uniform(-1, 1, size=(3, big, n))
    t0 = time.perf_counter()
    for name in QUANTITIES:  # the public functions, compiled (on first use) as users get them
        jax.block_until_ready(getattr(dyn, name)(*(jnp.asarray(s[:big]) for s in states[: ARGS[name]]), p))
    t_compile = time.perf_counter() - t0

    print(f"robot {args.robot}: {n} DOF, {len(dyn.parameters)} symbolic parameters, jax {jax.__version__}, "
          f"pinocchio {pin.__version__}, float64")
    print(f"load {t_load:.2f} s | derive + print {t_derive:.2f} s (cached reload {t_cached:.3f} s) | "
          f"compile {len(QUANTITIES)} quantities at batch {big}: {t_compile:.2f} s | "
          f"cold total {t_load + t_derive + t_compile:.2f} s")

    q, qd, qdd = (np.ascontiguousarray(s[:2000]) for s in states)
    peer = pinocchio_calls(pin.buildReducedModel(pin.buildModelFromUrdf(str(path)),
                                                 [pin.buildModelFromUrdf(str(path)).getJointId(j) for j in (lock or {})],
                                                 pin.neutral(pin.buildModelFromUrdf(str(path)))) if lock else
                           pin.buildModelFromUrdf(str(path)), q, qd, qdd, args.repeats)
    print(f"\n{'quantity':18s} {'batch':>6s} {'jaxskid ns/state':>17s} {'pinocchio ns/call':>18s} {'speed-up':>9s}")
    rows = []
    for name in QUANTITIES:
        for b in batches:
            arrays = [jnp.asarray(s[:b]) for s in states[: ARGS[name]]]
            if b == 1:
                arrays = [a[0] for a in arrays]
            f = getattr(dyn, name)
            t = median_time(lambda: jax.block_until_ready(f(*arrays, p)), args.repeats) / b
            print(f"{name:18s} {b:6d} {t * 1e9:17.1f} {peer[name] * 1e9:18.1f} {peer[name] / t:9.2f}")
            rows.append([f"`{name}`", b, "float64", doc_tables.duration(t), doc_tables.duration(peer[name]),
                         doc_tables.ratio(peer[name] / t)])
    b = big
    arrays32 = [jnp.asarray(s[:b], dtype=jnp.float32) for s in states[:3]]
    p32 = p.astype(jnp.float32)
    t = median_time(lambda: jax.block_until_ready(dyn.inverse_dynamics(*arrays32, p32)), args.repeats) / b
    print(f"{'inverse_dynamics':18s} {b:6d} {t * 1e9:17.1f} {peer['inverse_dynamics'] * 1e9:18.1f} "
          f"{peer['inverse_dynamics'] / t:9.2f}   (float32)")
    peer_tau = peer["inverse_dynamics"]
    rows.append(["`inverse_dynamics`", b, "float32", doc_tables.duration(t), doc_tables.duration(peer_tau),
                 doc_tables.ratio(peer_tau / t)])
    lines = doc_tables.table(["quantity", "batch", "dtype", "jaxskid per state", "Pinocchio per call", "ratio"], rows)
    doc_tables.write(args.markdown, lines, f"{args.robot}: {n} DOF, {len(dyn.parameters)} symbolic parameters; "
                     f"load {t_load:.2f} s, derive + print {t_derive:.2f} s (cached reload {t_cached:.3f} s), "
                     f"compile of the {len(QUANTITIES)} quantities at batch {big} {t_compile:.2f} s. "
                     f"Medians of {args.repeats}; "
                     "Pinocchio per call from Python (`rnea`, `crba`, `computeGeneralizedGravity`, "
                     "`nonLinearEffects`) on the same states.")


if __name__ == "__main__":
    main()
