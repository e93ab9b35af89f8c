"""``dyn.raw`` in a hand-written loop against the public functions and against Pinocchio.

    python benchmarks/raw_loop.py [--robots panda,solo12] [--batch 256] [--steps 200] [--repeats 15] [--markdown PATH]

The documentation's advice for your own loops (docs/quantities.md) is ``jax.vmap(dyn.raw(name))``. Here a
user's RK4 rollout, written by hand as ``lax.scan`` over ``jax.vmap`` of the accelerations, runs four ways: with
``dyn.raw("forward_dynamics")`` or with the public ``dyn.forward_dynamics`` (which maps a batch itself),
each under ``jaxskid.jit`` and under a plain ``jax.jit``. Robots from example-robot-data: the Panda (7 DOF,
fingers locked) and solo12 (12 DOF), float64, RK4 at 1 ms with random torques. Printed: compile time and
the median time per evaluation of the accelerations (4 per step and rollout), and for scale Pinocchio's
``aba`` per call from Python on the same states.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp
import numpy as np
import pinocchio as pin

import jaxskid
import doc_tables  # benchmarks/doc_tables.py, beside this script

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from helpers import users_rk4  # noqa: E402  (tests/helpers.py: the loop tests/test_forward_dynamics.py checks)

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
ROBOTS = {
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "solo12": ("solo_description/robots/solo12.urdf", None),
    "z1": ("z1_description/urdf/z1.urdf", None),
}


def positions(accel):
    """The user's RK4 rollout at 1 ms (``users_rk4``) of a batch, returning the joint positions after each step."""
    rollout = users_rk4(accel, 1e-3)
    return lambda q, qd, u, p: rollout(q, qd, u, p)[0]


def pinocchio_aba(path: Path, lock, q, qd, tau) -> float:
    model = pin.buildModelFromUrdf(str(path))
    if lock:
        model = pin.buildReducedModel(model, [model.getJointId(k) for k in lock], pin.neutral(model))
    data = model.createData()
    times = []
    for _ in range(5):
        start = time.perf_counter()
        for k in range(len(q)):
            pin.aba(model, data, q[k], qd[k], tau[k])
        times.append((time.perf_counter() - start) / len(q))
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="panda,solo12")
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=15)
    doc_tables.add_option(ap)
    args = ap.parse_args()
    notes = (f"Batch {args.batch}, {args.steps} RK4 steps at 1 ms, float64; time per evaluation of the accelerations "
             f"(4 per step and rollout), medians of {args.repeats} interleaved repeats; Pinocchio's `aba` per call "
             "from Python on the same kind of states.")
    print(notes)
    out = doc_tables.Lines()
    out("| robot | variant | compile | per evaluation | Pinocchio aba per call | ratio |")
    out("|---|---|---|---|---|---|")
    for name in args.robots.split(","):
        path, lock = ROBOTS[name]
        dyn = jaxskid.lower(jaxskid.load(ERD / path, lock=lock), quantities=["forward_dynamics"])
        n, b, steps = dyn.n_dof, args.batch, args.steps
        rng = np.random.default_rng(0)
        q0, qd0 = jnp.asarray(rng.uniform(-1, 1, (b, n))), jnp.zeros((b, n))
        u = jnp.asarray(0.1 * rng.normal(size=(steps, b, n)))
        p = dyn.param_vector()
        raw = jax.vmap(dyn.raw("forward_dynamics"), in_axes=(0, 0, 0, None))
        public = dyn.forward_dynamics
        calls = {
            "dyn.raw, jaxskid.jit": jaxskid.jit(positions(raw)),
            "dyn.raw, jax.jit": jax.jit(positions(raw)),
            "dyn.forward_dynamics, jaxskid.jit": jaxskid.jit(positions(public)),
            "dyn.forward_dynamics, jax.jit": jax.jit(positions(public)),
        }
        compile_s = {}
        for label, fn in calls.items():
            start = time.perf_counter()
            jax.block_until_ready(fn(q0, qd0, u, p))
            compile_s[label] = time.perf_counter() - start
        times = {k: [] for k in calls}
        for _ in range(args.repeats):
            for label, fn in calls.items():
                start = time.perf_counter()
                jax.block_until_ready(fn(q0, qd0, u, p))
                times[label].append((time.perf_counter() - start) / (b * steps * 4))
        states = rng.uniform(-1, 1, (3, 200, n))
        pin_call = pinocchio_aba(ERD / path, lock, *states)
        for label in calls:
            per = float(np.median(times[label]))
            out(f"| {name} ({n}) | `{label}` | {compile_s[label]:.1f} s | {per * 1e6:.3f} µs "
                f"| {pin_call * 1e6:.2f} µs | {pin_call / per:.0f}x |")
    doc_tables.write(args.markdown, out, notes)


if __name__ == "__main__":
    main()
