"""Gradients of losses over M, C and tau with respect to every inertial parameter and to q, at several sizes.

    python benchmarks/param_gradients.py [--robots panda,solo12,g1,g1_hands] [--batch 64] [--repeats 15]
                                         [--markdown docs/performance/param_gradients.md]

For each robot (fixed base, every inertial parameter symbolic) and each loss, in a process of its own with an
empty cache (generated module, native library and XLA's cache in a fresh folder):

- ``loss``: ``sum M^2``, ``sum C^2``, ``sum tau^2`` or the three together, over a batch of random states;
- ``derive + lower``: reading the URDF, deriving the quantities and their pullbacks, printing the module;
- ``first gradient``: tracing, compiling (the native kernels' C included) and running
  ``jax.jit(jax.grad(loss))`` the first time; ``cached``: the same in a second process that finds the generated
  module and the native libraries of the first (XLA's cache emptied: it traces and compiles again);
- ``loss`` and ``gradient``: median time per call of the jitted loss and of its gradient, and their ratio;
- ``peak memory``: the process's peak resident memory;
- ``pinocchio``: Pinocchio's cost for the same batch of the nearest thing it has: the parameter gradient of
  ``sum tau^2`` as ``Y^T (2 tau)`` with ``computeJointTorqueRegressor`` (``p``), the state gradient with
  ``computeRNEADerivatives`` (``q``), per call from Python, times the batch.

Reverse mode runs the closed-form pullbacks (:mod:`jaxskid.runtime._pullback`). ``JAXSKID_NATIVE=0`` in the
environment measures the JAX form (what runs off CPU).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROBOTS = {  # file under example-robot-data's robots/, joints locked
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "solo12": ("solo_description/robots/solo12.urdf", None),
    "g1": ("g1_description/urdf/g1_29dof_rev_1_0.urdf", None),
    "g1_hands": ("g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf", None),
}
LOSSES = {"M": ("mass_matrix",), "C": ("coriolis_matrix",), "tau": ("inverse_dynamics",),
          "M+C+tau": ("mass_matrix", "coriolis_matrix", "inverse_dynamics")}


def measure(robot_name: str, loss_name: str, wrt: str, batch: int, repeats: int) -> dict:
    """One case, in this process (called in a child process by :func:`main`)."""
    import resource

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    import pinocchio as pin

    import jaxskid
    from core import median_time

    erd = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
    path, lock = ROBOTS[robot_name]
    start = time.perf_counter()
    robot = jaxskid.load(erd / path, lock=lock)
    names = LOSSES[loss_name]
    dyn = jaxskid.lower(robot, list(names))
    lowered = time.perf_counter() - start
    rng = np.random.default_rng(0)
    q, qd, qdd = (jnp.asarray(rng.normal(size=(batch, dyn.n_dof))) for _ in range(3))
    p = dyn.param_vector()
    args = {"mass_matrix": (), "coriolis_matrix": (qd,), "inverse_dynamics": (qd, qdd)}

    def loss(p, q):
        return sum(jnp.sum(getattr(dyn, name)(q, *args[name], params=p) ** 2) for name in names)

    grad = jax.jit(jax.grad(loss, argnums=0 if wrt == "p" else 1))
    start = time.perf_counter()
    jax.block_until_ready(grad(p, q))
    first = time.perf_counter() - start
    value = jax.jit(loss)
    jax.block_until_ready(value(p, q))
    t_loss = median_time(lambda: jax.block_until_ready(value(p, q)), repeats)
    t_grad = median_time(lambda: jax.block_until_ready(grad(p, q)), repeats)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {"lower": lowered, "first": first, "loss": t_loss, "grad": t_grad, "peak": peak, "n": dyn.n_dof,
            "n_params": len(dyn.parameters), "pinocchio": _pinocchio(erd / path, lock, wrt, np.asarray(q),
                                                                     np.asarray(qd), np.asarray(qdd), repeats)}


def _pinocchio(path, lock, wrt, q, qd, qdd, repeats) -> float:
    import pinocchio as pin

    from core import median_time

    model = pin.buildModelFromUrdf(str(path))
    if lock:
        model = pin.buildReducedModel(model, [model.getJointId(j) for j in lock], pin.neutral(model))
    data = model.createData()

    def run():
        for k in range(len(q)):
            tau = pin.rnea(model, data, q[k], qd[k], qdd[k])
            if wrt == "p":
                pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]).T @ (2 * tau)
            else:
                pin.computeRNEADerivatives(model, data, q[k], qd[k], qdd[k])
                data.dtau_dq.T @ (2 * tau)

    return median_time(run, max(3, repeats // 3))


def main() -> None:
    sys.path.insert(0, str(HERE))
    import doc_tables

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="panda,solo12,g1,g1_hands")
    parser.add_argument("--losses", default="M,M+C+tau")
    parser.add_argument("--wrt", default="p,q")
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--case", default=None, help=argparse.SUPPRESS)  # robot:loss:wrt, run in this process
    doc_tables.add_option(parser)
    a = parser.parse_args()
    if a.case:
        robot, loss, wrt = a.case.split(":")
        print(json.dumps(measure(robot, loss, wrt, a.batch, a.repeats)))
        return
    out = doc_tables.Lines()
    header = ["robot", "loss", "wrt", "derive + lower", "first gradient: cold, cached", "loss / call",
              "gradient / call", "ratio", "peak memory", "pinocchio (tau)"]
    out("| " + " | ".join(header) + " |")
    out("|" + "---|" * len(header))
    for robot in a.robots.split(","):
        for loss in a.losses.split(","):
            for wrt in a.wrt.split(","):
                r = _child(robot, loss, wrt, a.batch, a.repeats)
                if r is None:
                    out(f"| {robot} | {loss} | {wrt} | failed | | | | | | |")
                    continue
                out(f"| {robot} ({r['n']}, {r['n_params']} parameters) | sum {loss}^2 | {wrt} | "
                    f"{r['lower']:.1f} s | {r['first']:.1f} s, {r['cached']:.1f} s | "
                    f"{doc_tables.duration(r['loss'])} | {doc_tables.duration(r['grad'])} | "
                    f"{doc_tables.ratio(r['grad'] / r['loss'])} | {r['peak'] / 2**30:.2f} GiB | "
                    f"{doc_tables.duration(r['pinocchio'])} |")
    out()
    out(f"Batch {a.batch}, float64; medians of {a.repeats} calls; `jax.jit(jax.grad(loss))`.")
    if a.markdown:
        doc_tables.write(a.markdown, out)


def _child(robot: str, loss: str, wrt: str, batch: int, repeats: int) -> dict | None:
    """One case in a fresh process with an empty cache, so that ``cold`` and the peak memory are its own."""
    with tempfile.TemporaryDirectory(prefix="jaxskid-param-gradients-") as cache:
        env = {**os.environ, "JAXSKID_CACHE_DIR": cache}  # XLA's cache too: <cache>/xla
        cmd = [sys.executable, str(Path(__file__).resolve()), "--case", f"{robot}:{loss}:{wrt}",
               "--batch", str(batch), "--repeats", str(repeats)]
        runs = []
        for _ in range(2):  # empty, then with the module and the native libraries of the first run
            shutil.rmtree(Path(cache) / "xla", ignore_errors=True)
            done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=HERE)
            if done.returncode != 0:
                print(done.stderr[-2000:], file=sys.stderr)
                return None
            runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    return {**runs[0], "cached": runs[1]["first"]}


if __name__ == "__main__":
    main()
