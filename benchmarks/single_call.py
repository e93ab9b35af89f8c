"""Single-call latency from Python, float64: the generated C through jaxskid.compile_native (its capi, cffi
and ctypes backends), a jitted JAX call of jaxskid.lower, and Pinocchio; on the 3-DOF hopping leg and the 12-DOF
quadruped of robots/ (Pinocchio models built from the same descriptions) and the Panda (7 DOF, fingers locked,
Pinocchio's own URDF parser).

Every candidate is timed in the same run, interleaved (round-robin over repetitions), so that a loaded
machine slows them alike; the figures are medians of per-call means. Ratios are Pinocchio's time for the same
quantity (rnea, crba, computeGeneralizedGravity, computeCoriolisMatrix) over the candidate's: > 1 is faster.

    python benchmarks/single_call.py [--repeat 41] [--number 2000] [--robots hopping_leg,quadruped_12dof,panda]
    python benchmarks/single_call.py --markdown docs/performance/single_call.md   # also the documentation's table
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np
import pinocchio as pin

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)

ERD = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots")
ROOT = Path(__file__).resolve().parents[1]
PANDA = ERD / "panda_description/urdf/panda.urdf"
FINGERS = ("panda_finger_joint1", "panda_finger_joint2")
ROBOTS = ("hopping_leg", "quadruped_12dof", "panda")
QUANTITIES = ("inverse_dynamics", "mass_matrix", "gravity_torques", "coriolis_matrix")
BACKENDS = ("capi", "cffi", "ctypes")


def robot_and_model(key: str):
    """The robot and a Pinocchio model of it with its data."""
    if key == "panda":
        robot = jaxskid.load(PANDA, lock={j: 0.0 for j in FINGERS})
        full = pin.buildModelFromUrdf(str(PANDA))
        model = pin.buildReducedModel(full, [full.getJointId(j) for j in FINGERS], pin.neutral(full))
    else:
        robot = jaxskid.load(ROOT / "robots" / f"{key}.yaml")
        sys.path.insert(0, str(ROOT / "tests"))
        from pinref import to_pinocchio

        model, _ = to_pinocchio(robot, robot.default_params())
    return robot, model, model.createData()


def timed(candidates: dict, repeat: int, number: int) -> dict[str, float]:
    """Median over ``repeat`` rounds of the mean time per call (seconds), candidates interleaved."""
    samples: dict[str, list[float]] = {k: [] for k in candidates}
    for fn in candidates.values():  # warm up
        for _ in range(200):
            fn()
    for _ in range(repeat):
        for name, fn in candidates.items():
            t0 = time.perf_counter()
            for _ in range(number):
                fn()
            samples[name].append((time.perf_counter() - t0) / number)
    return {k: float(np.median(v)) for k, v in samples.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=41)
    ap.add_argument("--number", type=int, default=2000)
    ap.add_argument("--robots", default=",".join(ROBOTS))
    doc_tables.add_option(ap)
    opts = ap.parse_args()
    os.environ.setdefault("JAXSKID_CACHE_DIR", tempfile.mkdtemp(prefix="jaxskid-bench-"))
    print(f"jaxskid {jaxskid.__version__}, jax {jax.__version__}, pinocchio {pin.__version__}")
    summary, rows = [], []
    for key in opts.robots.split(","):
        summary += robot_calls(key, opts, rows)
    print("fastest jaxskid path against Pinocchio (ratio > 1: faster than Pinocchio):")
    for line in summary:
        print("  " + line)
    header = ["robot (DOF)", "quantity", *(f"C ({b})" for b in BACKENDS), "jitted JAX", "Pinocchio", "fastest / Pinocchio"]
    doc_tables.write(opts.markdown, doc_tables.table(header, rows),
                     f"One state per call from Python, float64; medians over {opts.repeat} rounds of the mean of "
                     f"{opts.number} calls, every candidate interleaved. The ratio is Pinocchio's time over the fastest "
                     "path's (> 1: faster than Pinocchio).")


def robot_calls(key: str, opts, rows: list) -> list[str]:
    robot, model, data = robot_and_model(key)
    n = robot.n_dof
    t0 = time.perf_counter()
    eqs = jaxskid.derive(robot, QUANTITIES)
    t1 = time.perf_counter()
    natives = {b: jaxskid.compile_native(eqs, backend=b) for b in BACKENDS}
    t2 = time.perf_counter()
    dyn = jaxskid.lower(robot, QUANTITIES)
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.uniform(-1, 1, size=(3, n))
    print(f"\n{key} ({n} DOF): derive {t1 - t0:.2f} s, compile C ({', '.join(BACKENDS)}) {t2 - t1:.2f} s")

    cases = {
        "inverse_dynamics": ((q, qd, qdd), lambda: pin.rnea(model, data, q, qd, qdd), "rnea"),
        "mass_matrix": ((q,), lambda: pin.crba(model, data, q), "crba"),
        "gravity_torques": ((q,), lambda: pin.computeGeneralizedGravity(model, data, q), "computeGeneralizedGravity"),
        "coriolis_matrix": ((q, qd), lambda: pin.computeCoriolisMatrix(model, data, q, qd), "computeCoriolisMatrix"),
    }
    ref = {
        "inverse_dynamics": pin.rnea(model, data, q, qd, qdd).copy(),
        "mass_matrix": np.triu(pin.crba(model, data, q)) + np.triu(pin.crba(model, data, q), 1).T,
        "gravity_torques": pin.computeGeneralizedGravity(model, data, q).copy(),
        "coriolis_matrix": pin.computeCoriolisMatrix(model, data, q, qd).copy(),
    }
    header = f"{'quantity':<18} {'path':<37} {'per call':>10} {'vs Pinocchio':>13} {'max |diff|':>11}"
    print(header)
    print("-" * len(header))
    summary = []
    for name, (state, pin_call, pin_name) in cases.items():
        jitted = getattr(dyn, name)
        jitted(*state).block_until_ready()
        calls = {f"generated C ({b})": getattr(natives[b], name) for b in BACKENDS}
        candidates = {path: (lambda f=f: f(*state)) for path, f in calls.items()}
        candidates["jitted JAX"] = lambda: jitted(*state).block_until_ready()
        candidates[f"Pinocchio {pin_name}"] = pin_call
        number = opts.number if name != "coriolis_matrix" else max(opts.number // 2, 1)
        times = timed(candidates, opts.repeat, number)
        base = times[f"Pinocchio {pin_name}"]
        outputs = {path: f(*state) for path, f in calls.items()}
        outputs["jitted JAX"] = np.asarray(jitted(*state))
        for path, t in times.items():
            diff = f"{np.abs(outputs[path] - ref[name]).max():.1e}" if path in outputs else ""
            print(f"{name:<18} {path:<37} {t * 1e6:>8.2f} us {base / t:>12.2f}x {diff:>11}")
        best = min(calls, key=times.__getitem__)
        rows.append([f"{key} ({n})", f"`{name}`", *(f"{times[p] * 1e6:.2f} µs" for p in calls),
                     f"{times['jitted JAX'] * 1e6:.1f} µs", f"{base * 1e6:.2f} µs (`{pin_name}`)",
                     f"{base / times[best]:.1f}x"])
        summary.append(f"{key} ({n} DOF) {name}: {best} {times[best] * 1e6:.2f} us, Pinocchio {pin_name} "
                       f"{base * 1e6:.2f} us: {base / times[best]:.2f}x")
        print()
    return summary


if __name__ == "__main__":
    main()
