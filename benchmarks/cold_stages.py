"""Where a cold first call of one quantity goes: loading the robot, deriving, lowering (code generation and,
on CPU, the native build it starts), tracing and lowering the program, XLA's compilation, and the run.

    python benchmarks/cold_stages.py [--robot g1] [--quantity coriolis_matrix] [--batch 4096]

Each stage's wall time in a fresh process with an empty cache (a temporary ``JAXSKID_CACHE_DIR``), float64.
Robots are example-robot-data's, as in ``benchmarks/scaling.py``; ``--no-store`` lowers forward dynamics
without keeping its export (``jaxskid/runtime/_whole.py``), to compare.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--quantity", default="coriolis_matrix")
    parser.add_argument("--batch", type=int, default=4096)
    parser.add_argument("--no-store", action="store_true")
    args = parser.parse_args()
    os.environ["JAXSKID_CACHE_DIR"] = tempfile.mkdtemp(prefix="jaxskid-cold-")
    start = time.perf_counter()
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    from scaling import ERD, ROBOTS

    import jaxskid

    path, lock = ROBOTS[args.robot][:2]
    marks = [("import", time.perf_counter())]
    robot = jaxskid.load(ERD / path, lock=lock)
    marks.append(("load", time.perf_counter()))
    eqs = jaxskid.derive(robot, [args.quantity])
    marks.append(("derive", time.perf_counter()))
    dyn = jaxskid.lower(eqs)
    marks.append(("lower", time.perf_counter()))
    if args.no_store:
        dyn.path = None
    rng = np.random.default_rng(0)
    states = {a: jnp.asarray(rng.uniform(-1, 1, (args.batch, *dyn.argument_shape(a))))
              for a in dyn.signature(args.quantity)[0]}
    fn = jax.jit(getattr(dyn, args.quantity))
    lowered = fn.lower(*states.values())
    marks.append(("trace + lower", time.perf_counter()))
    compiled = lowered.compile()
    marks.append(("XLA", time.perf_counter()))
    jax.block_until_ready(compiled(*states.values()))
    marks.append(("run", time.perf_counter()))
    last, parts = start, []
    for name, t in marks:
        parts.append(f"{name} {t - last:.1f} s")
        last = t
    print(f"{args.robot} {args.quantity}: " + ", ".join(parts) + f"; from load {marks[-1][1] - marks[0][1]:.1f} s")


if __name__ == "__main__":
    main()
