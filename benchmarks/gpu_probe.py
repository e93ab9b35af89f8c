"""A GPU's time per call against the batch, and a target for Nsight Compute: the floating-base G1's M and tau at
zero acceleration (adam-robotics' bias), then a z1 rollout's gradient, with the CUDA kernels of the cached
modules (``benchmarks/gpu.py`` says how to prepare ``.gpu/``).

    JAXSKID_CACHE_DIR=.gpu/cache python benchmarks/gpu_probe.py | tee probe.txt   # the batches
    python benchmarks/gpu_probe.py --rows probe.txt --markdown PATH             # their table, measuring nothing
    JAXSKID_CACHE_DIR=.gpu/cache ncu -k regex:jaxskid_kernel -c 6 --section WarpStateStats \\
        --section SchedulerStats --section LaunchStats --section Occupancy --section InstructionStats \\
        --section MemoryWorkloadAnalysis python benchmarks/gpu_probe.py --profile   # the kernels' counters

With ``--profile`` it calls each kernel once, at 16,384 states, in this order: M, the bias, the rollout's forward,
adjoint and parameters kernels. Without, it then prints the median time of one call of M and of the bias (each
waited for) at batches from 1,024 to 262,144 states, and at 16,384 with sine and cosine from CUDA's library
(``JAXSKID_CUDA_TRIG=library``) against the default multiply-adds.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
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

BATCH = 16384
BATCHES = (1024, 4096, 16384, 65536, 262144)


def floating_states(robot, batch: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(batch, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = np.concatenate([rng.uniform(-1, 1, (batch, 3)), quat, rng.uniform(-1, 1, (batch, robot.n_dof))], axis=1)
    return jnp.asarray(q), jnp.asarray(rng.normal(size=(batch, robot.n_dof + 6)))


def median_call(fn, args, repeats: int = 5) -> tuple[float, float]:
    """``(first call, median of repeats)`` in seconds, each call waited for."""
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first, times = time.perf_counter() - start, []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return first, float(np.median(times))


LINE = re.compile(r"^(?:(?P<trig>[\w ]+ trig), )?batch (?P<batch>\d+) (?P<name>\w+): (?P<ns>[\d.]+) ns per state")


def tables(text: str, markdown: Path | None, source: str) -> None:
    """The table of a probe's output ``text`` (lines as :func:`main` prints them): one call of M and of the bias
    by batch, and the last lines' other build, written to ``markdown``."""
    found = {}
    for line in text.splitlines():
        m = LINE.match(line)
        if m:
            found[(m["trig"] or "default", int(m["batch"]), m["name"])] = float(m["ns"])
    cells = []
    for (trig, batch, name), ns in found.items():
        if name != "M" or trig != "default":
            continue
        bias = found.get((trig, batch, "bias"))
        cells.append([f"{batch:,}", doc_tables.duration(1e-9 * ns * batch), doc_tables.duration(1e-9 * ns),
                      doc_tables.duration(1e-9 * bias * batch), doc_tables.duration(1e-9 * bias)])
    other = [(trig, batch) for trig, batch, name in found if trig != "default" and name == "M"]
    for trig, batch in other:
        cells.append([f"{batch:,}, {trig}", "-", doc_tables.duration(1e-9 * found[(trig, batch, "M")]), "-",
                      doc_tables.duration(1e-9 * found[(trig, batch, "bias")])])
    lines = doc_tables.Lines()
    for line in doc_tables.table(["states", "M, one call", "per state", "bias, one call", "per state"], cells):
        lines(line)
    doc_tables.write(markdown, lines, f"The floating G1, each call waited for; the output of {source} (the kernels "
                     "built as the default was then, which the file's head says; the last row the other build).")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--urdf-dir", type=Path, default=ROOT / ".gpu" / "urdf")
    parser.add_argument("--profile", action="store_true", help="only one call of each kernel (for ncu)")
    parser.add_argument("--rows", type=Path, default=None, help="measure nothing: the table of a probe's output")
    doc_tables.add_option(parser)
    args = parser.parse_args()
    if args.rows is not None:
        tables(args.rows.read_text(), args.markdown, args.rows.name)
        return
    robot = jaxskid.load(args.urdf_dir / "g1_29dof_rev_1_0.urdf", floating_base=True)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    q, v = floating_states(robot, BATCH)
    jax.block_until_ready(dyn.mass_matrix(q))
    jax.block_until_ready(dyn.inverse_dynamics(q, v, jnp.zeros_like(v)))
    z1 = jaxskid.lower(jaxskid.load(args.urdf_dir / "z1.urdf"), ["forward_dynamics"])
    n, steps = z1.n_dof, 500
    u = jnp.asarray(np.sin(np.arange(steps)[:, None] * 0.01 * (1 + np.arange(n))))
    rng = np.random.default_rng(1)
    x0 = jnp.concatenate([0.1 + 0.05 * jnp.asarray(rng.uniform(-1, 1, (BATCH, n))), jnp.zeros((BATCH, n))], axis=1)

    def loss(p):
        return jnp.mean(jaxskid.rollout(z1, x0, u, 1e-3, steps, params=p).x ** 2)

    jax.block_until_ready(jax.jit(jax.grad(loss))(z1.param_vector()))
    print("probe:", {k: dyn.report()[k] for k in ("mass_matrix", "inverse_dynamics")}, flush=True)
    if args.profile:
        return
    for batch in BATCHES:
        qb, vb = floating_states(robot, batch)
        for name, fn, call in (("M", dyn.mass_matrix, (qb,)), ("bias", dyn.inverse_dynamics, (qb, vb, 0 * vb))):
            _, median = median_call(fn, call)
            print(f"batch {batch} {name}: {1e9 * median / batch:.1f} ns per state, call {1e3 * median:.3f} ms",
                  flush=True)
    os.environ["JAXSKID_CUDA_TRIG"] = "library"
    library = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    for name, fn, call in (("M", library.mass_matrix, (q,)), ("bias", library.inverse_dynamics, (q, v, 0 * v))):
        first, median = median_call(fn, call, repeats=7)
        print(f"library trig, batch {BATCH} {name}: {1e9 * median / BATCH:.1f} ns per state, first call {first:.2f} s",
              flush=True)


if __name__ == "__main__":
    main()
