"""A batched ``jaxskid.rollout`` against ``jax.vmap`` of single rollouts under ``jaxskid.jit``.

    python benchmarks/rollout_batching.py [--batch 256] [--steps 200] [--repeats 50]

The Panda (7 DOF, fingers locked), lowered with forward_dynamics, mass_matrix and inverse_dynamics; RK4 steps of
1 ms with random torques (an array, one sequence per rollout), float64. Both return the whole trajectory
(``t``, ``x``, ``tau``); ``.x`` only is timed too (there the vmapped program drops ``t`` and ``tau``). Once with the
default parameters (``params=None``) and once with the same values passed as a vector. Medians of interleaved
repeats: wall time, and the process's CPU time (steadier on a loaded machine).
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
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=50)
    args = ap.parse_args(argv)
    dyn = panda(["forward_dynamics", "mass_matrix", "inverse_dynamics"])
    rng = np.random.default_rng(0)
    b, steps, dt = args.batch, args.steps, 1e-3
    x0 = jnp.asarray(np.concatenate([rng.uniform(-1, 1, (b, 7)), np.zeros((b, 7))], axis=1))
    u = jnp.asarray(0.1 * rng.normal(size=(b, steps, 7)))
    vector = dyn.param_vector()

    def single(x, uu, p=None):
        return jaxskid.rollout(dyn, x, uu, dt, steps, params=p)

    mapped = jaxskid.jit(jax.vmap(single))
    mapped_x = jaxskid.jit(jax.vmap(lambda x, uu: single(x, uu).x))
    mapped_p = jaxskid.jit(jax.vmap(single, in_axes=(0, 0, None)))
    calls = {
        "rollout(batch)": lambda: jaxskid.rollout(dyn, x0, u, dt, steps),
        "jit(vmap(rollout))": lambda: mapped(x0, u),
        "rollout(batch).x": lambda: jaxskid.rollout(dyn, x0, u, dt, steps).x,
        "jit(vmap(rollout(...).x))": lambda: mapped_x(x0, u),
        "rollout(batch), params vector": lambda: jaxskid.rollout(dyn, x0, u, dt, steps, params=vector),
        "jit(vmap(rollout)), params vector": lambda: mapped_p(x0, u, vector),
    }
    for name, call in calls.items():
        t = time.perf_counter()
        jax.block_until_ready(call())
        print(f"{name:36s} first call (compile) {time.perf_counter() - t:6.2f} s", flush=True)
    a, c = calls["rollout(batch)"](), calls["jit(vmap(rollout))"]()
    print(f"max |x difference| {float(jnp.abs(a.x - c.x).max()):.1e}; t shapes {a.t.shape} and {c.t.shape}")
    wall, cpu = {k: [] for k in calls}, {k: [] for k in calls}
    for _ in range(args.repeats):
        for name, call in calls.items():
            t, p = time.perf_counter(), time.process_time()
            jax.block_until_ready(call())
            wall[name].append(time.perf_counter() - t)
            cpu[name].append(time.process_time() - p)
    print(f"\njax {jax.__version__}, batch {b}, {steps} RK4 steps, median of {args.repeats} interleaved repeats")
    for name in calls:
        print(f"{name:36s} wall {np.median(wall[name]) * 1e3:7.2f} ms   cpu {np.median(cpu[name]) * 1e3:7.2f} ms")


if __name__ == "__main__":
    main()
