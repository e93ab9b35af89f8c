"""Memory of ``jax.grad`` through a rollout, with and without ``jaxskid.Checkpoint()``.

    python benchmarks/rollout_memory.py [--steps 500,2000,8000] [--repeats 5]

The Panda (7 DOF, fingers locked; forward_dynamics, mass_matrix and inverse_dynamics lowered), one rollout
of RK4 steps of 1 ms with zero torques (an input array), the final state saved (``SaveAt(t1=True)``), the
gradient of ``sum(x(T)^2)`` with respect to ``x0``. Memory: XLA's temporary buffers of the compiled gradient
(``compile().memory_analysis().temp_size_in_bytes``), the peak the program needs besides its inputs and
outputs; time: median of repeated calls.
"""

from __future__ import annotations

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp
import numpy as np

import jaxskid
from core import panda  # benchmarks/core.py, beside this script


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", default="500,2000,8000")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    dyn = panda(["forward_dynamics", "mass_matrix", "inverse_dynamics"])
    x0 = jnp.concatenate([jnp.linspace(0.3, -0.2, 7), jnp.zeros(7)])
    print(f"jax {jax.__version__}; Panda, RK4, 1 ms steps, gradient of sum(x(T)^2) with respect to x0")
    print(f"{'steps':>6} {'checkpoint':>12} {'temp MB':>9} {'compile s':>10} {'gradient ms':>12}")
    for steps in (int(s) for s in args.steps.split(",")):
        u = jnp.zeros((steps, 7))
        for checkpoint in (None, jaxskid.Checkpoint()):
            def loss(x, u, checkpoint=checkpoint, steps=steps):
                final = jaxskid.rollout(dyn, x, u, 1e-3, steps, saveat=jaxskid.SaveAt(t1=True), checkpoint=checkpoint)
                return jnp.sum(final.x ** 2)

            t = time.perf_counter()
            compiled = jax.jit(jax.grad(loss), compiler_options=jaxskid.compiler_options()).lower(x0, u).compile()
            compile_s = time.perf_counter() - t
            temp = compiled.memory_analysis().temp_size_in_bytes
            jax.block_until_ready(compiled(x0, u))
            times = []
            for _ in range(args.repeats):
                t = time.perf_counter()
                jax.block_until_ready(compiled(x0, u))
                times.append(time.perf_counter() - t)
            label = "none" if checkpoint is None else f"block {checkpoint.size(steps)}"
            print(f"{steps:6d} {label:>12} {temp / 1e6:9.3f} {compile_s:10.1f} {np.median(times) * 1e3:12.1f}",
                  flush=True)


if __name__ == "__main__":
    main()
