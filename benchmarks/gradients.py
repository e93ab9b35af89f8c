"""Gradients through rollouts: what a gradient costs against the loss, to run and to compile.

    python benchmarks/gradients.py [--robots z1,panda] [--steps 500,2000] [--batch 64] [--repeats 5]

For each robot (Unitree z1 and the Franka Panda with its fingers locked, from example-robot-data) and
horizon, a loss is the mean squared state of an RK4 rollout at 1 ms steps under open-loop sinusoidal
torques, as a function of all inertial parameters. The script times, each in a fresh process:

- the loss, its reverse-mode gradient (``jax.grad``, ``autodiff="reverse"``) and its forward-mode gradient
  (``jax.jacfwd``, ``autodiff="forward"``), medians over repeats, and the ratio gradient / loss;
- the first call (trace + compile + run) under ``jaxskid.jit`` and under plain ``jax.jit``, cold (an empty
  persistent compilation cache) and warm (a second process on the same cache); each jit has its own cache
  and processes, so neither finds the other's compiled program;
- the compiled program's memory (arguments, outputs and temporaries, from XLA's memory analysis);
- the same for a batch of rollouts (one parameter set, ``--batch`` initial states).

The generated modules are cached beforehand, so first calls measure compilation, not derivation.
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

ROBOTS = {
    "z1": ("z1_description/urdf/z1.urdf", None),
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
}


def _case(robot: str, steps: int, batch: int, repeats: int, jit_name: str) -> dict:
    """One case, in this process: first calls under ``jit_name``; with jaxskid.jit also run times and memory."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    import pinocchio as pin

    import jaxskid

    erd = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
    path, lock = ROBOTS[robot]
    dyn = jaxskid.lower(jaxskid.load(erd / path, lock=lock), quantities=["forward_dynamics"])
    n, p0 = dyn.n_dof, dyn.param_vector()
    t = 1e-3 * np.arange(steps)[:, None]
    u = jnp.asarray(2.0 * np.sin(2 * np.pi * (1 + np.arange(n)) * t / (steps * 1e-3)))
    x0 = jnp.zeros((batch, 2 * n) if batch else (2 * n,)).at[..., :n].set(0.1)

    def loss(p, autodiff="reverse"):
        x = jaxskid.rollout(dyn, x0, u, 1e-3, steps, params=p, autodiff=autodiff).x
        return jnp.mean(x**2)

    fns = {
        "loss": loss,
        "reverse": jax.grad(loss),
        "forward": jax.jacfwd(lambda p: loss(p, "forward")),
    }
    out = {"robot": robot, "n_dof": n, "n_params": len(p0), "steps": steps, "batch": batch}
    jit = jaxskid.jit if jit_name == "jaxskid" else jax.jit
    for name, fn in fns.items():
        if name == "forward" and jit_name == "jax":
            continue
        f = jit(fn)
        start = time.perf_counter()
        jax.block_until_ready(f(p0))
        out[f"{name}_first_{jit_name}"] = time.perf_counter() - start
        if jit_name == "jax":
            continue
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            jax.block_until_ready(f(p0))
            times.append(time.perf_counter() - start)
        out[f"{name}_time"] = float(np.median(times))
        memory = jax.jit(fn).lower(p0).compile().memory_analysis()
        if memory is not None:
            out[f"{name}_memory"] = int(memory.temp_size_in_bytes + memory.output_size_in_bytes
                                        + memory.argument_size_in_bytes)
    return out


def _in_process(args: list[str], cache: str) -> dict:
    env = dict(os.environ, JAX_COMPILATION_CACHE_DIR=cache, JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
               JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0")
    done = subprocess.run([sys.executable, __file__, "--case", *args], env=env, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(done.stderr[-3000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def _mb(x) -> str:
    return f"{x / 2**20:.1f}" if x is not None else "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", default="z1,panda")
    parser.add_argument("--steps", default="500,2000")
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--case", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        robot, steps, batch, repeats, jit_name = args.case
        print(json.dumps(_case(robot, int(steps), int(batch), int(repeats), jit_name)))
        return
    print("| robot | steps | batch | loss | reverse grad | ratio | forward grad (jacfwd) | ratio "
          "| first call loss / grad, jaxskid.jit: cold, warm | grad first call, jax.jit: cold, warm "
          "| memory loss / grad (MB) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for robot in args.robots.split(","):
        for steps in map(int, args.steps.split(",")):
            for batch in (0, args.batch):
                case = [robot, str(steps), str(batch), str(args.repeats)]
                with tempfile.TemporaryDirectory() as cache:
                    cold, warm = _in_process([*case, "jaxskid"], cache), _in_process([*case, "jaxskid"], cache)
                with tempfile.TemporaryDirectory() as cache:
                    cold_jax, warm_jax = _in_process([*case, "jax"], cache), _in_process([*case, "jax"], cache)
                loss, rev, fwd = cold["loss_time"], cold["reverse_time"], cold["forward_time"]
                print(
                    f"| {robot} ({cold['n_dof']}, {cold['n_params']} params) | {steps} | {batch or 1} "
                    f"| {1e3 * loss:.2f} ms | {1e3 * rev:.2f} ms | {rev / loss:.1f}x | {1e3 * fwd:.1f} ms "
                    f"| {fwd / loss:.0f}x "
                    f"| {cold['loss_first_jaxskid']:.1f} / {cold['reverse_first_jaxskid']:.1f} s, "
                    f"{warm['loss_first_jaxskid']:.1f} / {warm['reverse_first_jaxskid']:.1f} s "
                    f"| {cold_jax['reverse_first_jax']:.1f} s, {warm_jax['reverse_first_jax']:.1f} s "
                    f"| {_mb(cold.get('loss_memory'))} / {_mb(cold.get('reverse_memory'))} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
