"""The first call in a new process: cold, and with jaxskid's persistent compilation cache.

    python benchmarks/first_call.py [--robots z1,panda] [--steps 500] [--batch 0] [--markdown PATH]

jaxskid keeps generated modules and, through JAX's persistent compilation cache, XLA's compiled programs in
``jaxskid.cache_dir()`` (here a fresh temporary directory). For each robot (example-robot-data's Unitree z1
and Franka Panda with its fingers locked), three processes run one after the other on that directory:

1. ``derive``: ``jaxskid.lower`` with nothing cached (derivation and code generation);
2. ``cold``: the first call of an RK4 rollout of ``--steps`` steps at 1 ms and of the gradient of a loss
   of it with respect to all inertial parameters (``jaxskid.jit(jax.grad(loss))``), with the module
   cached but no compiled program: tracing and XLA's compilation;
3. ``warm``: the same in a new process, which reads the compiled programs from the cache.

Each figure is the wall time of one call (trace + compile or load + run) in its own process; the ratio
cold / warm is what the persistent cache saves a new process. Pinocchio has no compilation step; for
scale, the script prints the time of the same rollout with Pinocchio's ``aba`` called from Python.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import doc_tables  # benchmarks/doc_tables.py, beside this script

ROBOTS = {
    "z1": ("z1_description/urdf/z1.urdf", None),
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
}


def _erd() -> Path:
    import pinocchio as pin

    return Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"


def _stage(stage: str, robot: str, steps: int, batch: int) -> dict:
    """One stage of the module docstring, in this process."""
    start = time.perf_counter()
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import jaxskid

    path, lock = ROBOTS[robot]
    out = {"import": time.perf_counter() - start}
    start = time.perf_counter()
    dyn = jaxskid.lower(jaxskid.load(_erd() / path, lock=lock), quantities=["forward_dynamics"])
    out["lower"] = time.perf_counter() - start
    if stage == "derive":
        return out
    n, p0 = dyn.n_dof, dyn.param_vector()
    t = 1e-3 * np.arange(steps)[:, None]
    u = jnp.asarray(2.0 * np.sin(2 * np.pi * (1 + np.arange(n)) * t / (steps * 1e-3)))
    x0 = jnp.zeros((batch, 2 * n) if batch else (2 * n,)).at[..., :n].set(0.1)

    def loss(p):
        return jnp.mean(jaxskid.rollout(dyn, x0, u, 1e-3, steps, params=p).x ** 2)

    start = time.perf_counter()
    jax.block_until_ready(jaxskid.rollout(dyn, x0, u, 1e-3, steps, params=p0).x)
    out["rollout"] = time.perf_counter() - start
    start = time.perf_counter()
    jax.block_until_ready(jaxskid.jit(jax.grad(loss))(p0))
    out["gradient"] = time.perf_counter() - start
    return out


def _run(stage: str, robot: str, steps: int, batch: int, cache: str) -> dict:
    env = dict(os.environ, JAXSKID_CACHE_DIR=cache)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    done = subprocess.run([sys.executable, __file__, "--stage", stage, robot, str(steps), str(batch)],
                          env=env, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(done.stderr[-3000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def _pinocchio_rollout(robot: str, steps: int) -> float:
    """Seconds for the same RK4 rollout with Pinocchio's aba, one state, from Python."""
    import numpy as np
    import pinocchio as pin

    path, lock = ROBOTS[robot]
    model = pin.buildModelFromUrdf(str(_erd() / path))
    if lock:
        ids = [model.getJointId(name) for name in lock]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    data = model.createData()
    n = model.nv
    q, v = np.full(n, 0.1), np.zeros(n)
    t = 1e-3 * np.arange(steps)[:, None]
    u = 2.0 * np.sin(2 * np.pi * (1 + np.arange(n)) * t / (steps * 1e-3))
    dt = 1e-3
    start = time.perf_counter()
    for k in range(steps):
        def f(q, v):
            return v, pin.aba(model, data, q, v, u[k])
        k1 = f(q, v)
        k2 = f(q + dt / 2 * k1[0], v + dt / 2 * k1[1])
        k3 = f(q + dt / 2 * k2[0], v + dt / 2 * k2[1])
        k4 = f(q + dt * k3[0], v + dt * k3[1])
        q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", default="z1,panda")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--batch", type=int, default=0, help="rollouts per call (0: one, unbatched)")
    parser.add_argument("--stage", nargs=4, help=argparse.SUPPRESS)
    doc_tables.add_option(parser)
    args = parser.parse_args()
    if args.stage:
        stage, robot, steps, batch = args.stage
        print(json.dumps(_stage(stage, robot, int(steps), int(batch))))
        return
    notes = (f"{args.steps} RK4 steps, batch {args.batch or 1}; wall seconds of one call, each stage in a new "
             "process; warm: the compiled programs read from the persistent cache.")
    print(notes)
    out = doc_tables.Lines()
    out("| robot | derive + lower (nothing cached) | rollout: cold, warm, ratio | gradient: cold, warm, ratio "
          "| Pinocchio aba rollout from Python |")
    out("|---|---|---|---|---|")
    for robot in args.robots.split(","):
        with tempfile.TemporaryDirectory() as cache:
            derive = _run("derive", robot, args.steps, args.batch, cache)
            cold = _run("cold", robot, args.steps, args.batch, cache)
            warm = _run("warm", robot, args.steps, args.batch, cache)
        pin_time = _pinocchio_rollout(robot, args.steps)
        out(f"| {robot} | {derive['lower']:.1f} s "
              f"| {cold['rollout']:.2f} s, {warm['rollout']:.2f} s, {cold['rollout'] / warm['rollout']:.1f}x "
              f"| {cold['gradient']:.2f} s, {warm['gradient']:.2f} s, {cold['gradient'] / warm['gradient']:.1f}x "
            f"| {pin_time:.3f} s |")
    doc_tables.write(args.markdown, out, notes)


if __name__ == "__main__":
    main()
