"""The whole second-order set, cold: M, C, Q_grav and tau with their first and second time derivatives.

    python benchmarks/second_order.py [--robots panda,solo12] [--batch 4096]

For each robot (fixed base, example-robot-data, every inertial parameter symbolic), in a fresh cache folder
(generated module, native library and XLA's compilation cache), it times ``jaxskid.lower`` of the twelve
quantities together (derivation and code generation; the C compiler starts in the background) and then the
first batched call of each (``batch`` states, float64: the native library's build finishing, XLA's compile
and the run), and prints the total beside the cold time of M alone. Pinocchio has no time derivatives of M,
C or Q_grav to compare with; ``benchmarks/derivatives.py`` checks their values and times them per state.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxskid  # noqa: E402
from scaling import ERD, ROBOTS, empty_compilation_cache  # noqa: E402  (benchmarks/scaling.py, beside this script)

BASES = ("mass_matrix", "coriolis_matrix", "gravity_torques", "inverse_dynamics")
SET = tuple(b + s for s in ("", "_dot", "_ddot") for b in BASES)


def cold(robot, names, batch: int) -> tuple[float, float]:
    """Seconds of ``lower`` and of the first calls of ``names``, with nothing cached."""
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as cache:
        start = time.perf_counter()
        dyn = jaxskid.lower(robot, list(names), cache_dir=cache)
        lowered = time.perf_counter()
        for name in names:
            args = [jnp.asarray(rng.uniform(-1, 1, (batch, *dyn.argument_shape(a)))) for a in dyn.signature(name)[0]]
            jax.block_until_ready(getattr(dyn, name)(*args))
        return lowered - start, time.perf_counter() - lowered


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", default="panda,solo12")
    parser.add_argument("--batch", type=int, default=4096)
    args = parser.parse_args()
    empty_compilation_cache()
    print("| robot (DOF) | second-order set: lower, first calls, total | M alone, total |")
    print("|---|---|---|")
    for name in args.robots.split(","):
        path, lock = ROBOTS[name]
        robot = jaxskid.load(ERD / path, lock=lock)
        lower, calls = cold(robot, SET, args.batch)
        alone = sum(cold(robot, ("mass_matrix",), args.batch))
        print(f"| {name} ({robot.n_dof}) | {lower:.1f} s, {calls:.1f} s, {lower + calls:.1f} s | {alone:.1f} s |",
              flush=True)


if __name__ == "__main__":
    main()
