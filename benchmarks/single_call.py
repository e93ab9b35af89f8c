"""Single-call latency from Python, Panda (7 DOF, fingers locked), float64: the generated C through
jaxskid.compile_native (cffi and ctypes backends), a jitted JAX call of jaxskid.lower, and Pinocchio.

Every candidate is timed in the same run, interleaved (round-robin over repetitions), so that a loaded
machine slows them alike; the figures are medians of per-call means. Ratios are against Pinocchio's
function for the same quantity (rnea, crba, computeGeneralizedGravity, computeCoriolisMatrix).

    python benchmarks/single_call.py [--repeat 41] [--number 2000]
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import tempfile
import time

import jax
import numpy as np
import pinocchio as pin

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots")
PANDA = ROBOTS / "panda_description/urdf/panda.urdf"
FINGERS = ("panda_finger_joint1", "panda_finger_joint2")
QUANTITIES = ("inverse_dynamics", "mass_matrix", "gravity_torques", "coriolis_matrix")


def pinocchio_model():
    full = pin.buildModelFromUrdf(str(PANDA))
    model = pin.buildReducedModel(full, [full.getJointId(j) for j in FINGERS], pin.neutral(full))
    return model, model.createData()


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
    opts = ap.parse_args()
    os.environ.setdefault("JAXSKID_CACHE_DIR", tempfile.mkdtemp(prefix="jaxskid-bench-"))

    robot = jaxskid.load(PANDA, lock={j: 0.0 for j in FINGERS})
    t0 = time.perf_counter()
    eqs = jaxskid.derive(robot, QUANTITIES)
    t1 = time.perf_counter()
    natives = {b: jaxskid.compile_native(eqs, backend=b) for b in ("cffi", "ctypes")}
    t2 = time.perf_counter()
    dyn = jaxskid.lower(robot, QUANTITIES)
    model, data = pinocchio_model()
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.uniform(-1, 1, size=(3, 7))
    print(f"jaxskid {jaxskid.__version__}, jax {jax.__version__}, pinocchio {pin.__version__}; "
          f"derive {t1 - t0:.2f} s, compile C (both backends) {t2 - t1:.2f} s")

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
    for name, (state, pin_call, pin_name) in cases.items():
        jitted = getattr(dyn, name)
        jitted(*state).block_until_ready()
        cffi_fn = getattr(natives["cffi"], name)
        ctypes_fn = getattr(natives["ctypes"], name)
        candidates = {
            "generated C (cffi)": lambda: cffi_fn(*state),
            "generated C (ctypes)": lambda: ctypes_fn(*state),
            "jitted JAX": lambda: jitted(*state).block_until_ready(),
            f"Pinocchio {pin_name}": pin_call,
        }
        number = opts.number if name != "coriolis_matrix" else max(opts.number // 2, 1)
        times = timed(candidates, opts.repeat, number)
        base = times[f"Pinocchio {pin_name}"]
        outputs = {
            "generated C (cffi)": cffi_fn(*state),
            "generated C (ctypes)": ctypes_fn(*state),
            "jitted JAX": np.asarray(jitted(*state)),
        }
        for path, t in times.items():
            diff = f"{np.abs(outputs[path] - ref[name]).max():.1e}" if path in outputs else ""
            print(f"{name:<18} {path:<37} {t * 1e6:>8.2f} us {t / base:>12.2f}x {diff:>11}")
        print()


if __name__ == "__main__":
    main()
