"""Pinned to one core against free to use every core the process may: does a loaded machine oversubscribe?

    python benchmarks/threads.py [--tasks excitation,scaling] [--rounds 3] [--dispatch sync,async] [--busy 0]
                                 [--markdown PATH]

jaxskid's native kernels run their batches on XLA's own intra-op thread pool (``pool_threads`` in
``jaxskid/lowering/_ffi_batch.py``), which XLA sizes to the cores the process may run on (its affinity mask), so
the kernels and XLA's own work share one pool. Each task runs in fresh processes, under ``taskset -c 0`` and
without, each with JAX's asynchronous CPU dispatch (the default) and with the synchronous one
(``JAXSKID_SYNC_DISPATCH=1``), the variants alternated round by round (their order rotated every round) so
that the machine's other load hits all alike (``--busy N`` adds N busy-looping processes as load), after one
unmeasured run that fills jaxskid's cache (the generated module and native library); the table gives the
medians, the slowest runs and unpinned / pinned (the goal: at most 1.3):

- ``excitation``: ``design_excitation(dyn, 5, 10.0, 10, robot=robot, base=base, starts=8, steps=150)`` on
  example-robot-data's UR10 with drives (``regressor`` lowered beforehand, outside the time): the call's wall
  time, its compilation included (XLA's cache in a fresh folder per process);
- ``scaling``: ``benchmarks/scaling.py --robots ur5 --quantities inverse_dynamics,mass_matrix,regressor
  --no-floating``: the whole script's wall time, and the per-state times of its batched calls (batch 4096).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)

HERE = Path(__file__).resolve().parent
SCALING = [sys.executable, str(HERE / "scaling.py"), "--robots", "ur5", "--quantities",
           "inverse_dynamics,mass_matrix,regressor", "--repeats", "5", "--no-floating"]


def excitation_worker() -> None:
    """One timed ``design_excitation`` on the UR10 with drives; prints ``{"seconds": ..., "cpus": ...}``."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import pinocchio as pin

    import jaxskid

    urdf = Path(pin.__file__).parents[4] / "share/example-robot-data/robots/ur_description/urdf/ur10_robot.urdf"
    robot = jaxskid.load(urdf, drives=True)
    dyn = jaxskid.lower(robot, ["regressor"])
    base = jaxskid.base_parameters(dyn)
    jaxskid.compilation_cache(tempfile.mkdtemp(prefix="jaxskid-xla-"))  # compile as a first run does
    start = time.perf_counter()
    jaxskid.design_excitation(dyn, 5, 10.0, 10, robot=robot, base=base, starts=8, steps=150)
    print(json.dumps({"seconds": time.perf_counter() - start, "cpus": len(os.sched_getaffinity(0))}))


def run(task: str, pinned: bool, asynchronous: bool = False) -> dict:
    """One fresh process of ``task``, pinned to core 0 or not, with JAX's asynchronous CPU dispatch or without
    (jaxskid's default): its measured figures."""
    prefix = ["taskset", "-c", "0"] if pinned else []
    if task == "excitation":
        command = [*prefix, sys.executable, str(Path(__file__).resolve()), "--worker"]
    else:
        command = [*prefix, *SCALING, "--plot", str(Path(tempfile.mkdtemp()) / "scaling.png")]
    env = {**os.environ, "JAXSKID_SYNC_DISPATCH": "0" if asynchronous else "1"}
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, cwd=HERE.parent, check=True, env=env)
    wall = time.perf_counter() - start
    if task == "excitation":
        return json.loads(done.stdout.strip().splitlines()[-1])
    figures = {"seconds": wall}
    for row in done.stdout.splitlines():  # | UR5 | 6 | quantity | cold | per state | ...
        cells = [c.strip() for c in row.strip("|").split("|")]
        if len(cells) >= 5 and cells[2] in SCALING[5].split(","):
            figures[cells[2]] = _seconds(cells[4])
    return figures


def _seconds(text: str) -> float:
    """``"241 ns"``, ``"1.2 µs"``, ``"3 ms"`` or ``"2.1 s"`` in seconds."""
    value, unit = re.match(r"([\d.]+)\s*(\S+)", text).groups()
    return float(value) * {"ns": 1e-9, "µs": 1e-6, "us": 1e-6, "ms": 1e-3, "s": 1.0}[unit]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", default="excitation,scaling")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--dispatch", default="sync,async",
                        help="sync: JAXSKID_SYNC_DISPATCH=1; async: JAX's default, jaxskid's too")
    parser.add_argument("--busy", type=int, default=0, help="busy-looping processes to run beside, as other load")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    doc_tables.add_option(parser)
    args = parser.parse_args()
    if args.worker:
        excitation_worker()
        return
    if shutil.which("taskset") is None:
        parser.error("taskset (util-linux) is needed to pin a process to one core")
    print(f"{os.cpu_count()} cores, this process may use {len(os.sched_getaffinity(0))}; load average "
          f"{os.getloadavg()[0]:.2f}")
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)]
    try:
        out = measure(args.tasks.split(","), args.rounds, args.dispatch.split(","))
    finally:
        for process in busy:
            process.kill()
    doc_tables.write(args.markdown, out, f"Medians of {args.rounds} fresh processes each, the variants alternated "
                     f"(their order rotated every round); {args.busy} busy-looping processes beside them; load "
                     f"average at the end {os.getloadavg()[0]:.2f}.")


def measure(tasks: list[str], rounds: int, dispatches: list[str]) -> list[str]:
    """The table: per task and dispatch, the median figures pinned and unpinned."""
    out = doc_tables.Lines()
    out("| task | dispatch | figure | pinned (taskset -c 0): median (slowest) | unpinned: median (slowest) "
        "| unpinned / pinned (medians) |")
    out("|---|---|---|---|---|---|")
    variants = [(d, pinned) for d in dispatches for pinned in (True, False)]
    for task in tasks:
        run(task, False)  # unmeasured: writes the generated module and native library the others then find
        runs: dict[tuple, list[dict]] = {v: [] for v in variants}
        for r in range(rounds):
            for v in variants[r % len(variants):] + variants[:r % len(variants)]:
                runs[v].append(run(task, v[1], v[0] == "async"))
                print(f"{task} round {r} {v[0]} {'pinned' if v[1] else 'unpinned'}: {runs[v][-1]}", flush=True)
        for dispatch in dispatches:
            for figure in (f for f in runs[(dispatch, True)][0] if f != "cpus"):
                values = [[x[figure] for x in runs[(dispatch, p)]] for p in (True, False)]
                pinned, free = (float(np.median(v)) for v in values)
                label = "wall time" if figure == "seconds" else f"{figure} per state"
                shown = " | ".join(f"{doc_tables.duration(np.median(v))} ({doc_tables.duration(max(v))})"
                                   for v in values)
                out(f"| {task} | {dispatch} | {label} | {shown} | {free / pinned:.2f} |")
    return out


if __name__ == "__main__":
    main()
