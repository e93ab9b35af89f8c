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
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp
import numpy as np
import pinocchio as pin

import jaxskid
import doc_tables  # benchmarks/doc_tables.py, beside this script

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
ROBOTS = {
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "solo12": ("solo_description/robots/solo12.urdf", None),
    "z1": ("z1_description/urdf/z1.urdf", None),
}


def users_rollout(accel, dt: float):
    """A hand-written RK4 rollout over a batch, as the documentation suggests writing one."""

    def rollout(q, qd, u, p):
        def deriv(x, tau):
            return x[1], accel(x[0], x[1], tau, p)

        def step(x, tau):
            k1 = deriv(x, tau)
            k2 = deriv([a + dt / 2 * k for a, k in zip(x, k1)], tau)
            k3 = deriv([a + dt / 2 * k for a, k in zip(x, k2)], tau)
            k4 = deriv([a + dt * k for a, k in zip(x, k3)], tau)
            x = [a + dt / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]
            return x, x[0]

        return jax.lax.scan(step, [q, qd], u)[1]

    return rollout


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
            "dyn.raw, jaxskid.jit": jaxskid.jit(users_rollout(raw, 1e-3)),
            "dyn.raw, jax.jit": jax.jit(users_rollout(raw, 1e-3)),
            "dyn.forward_dynamics, jaxskid.jit": jaxskid.jit(users_rollout(public, 1e-3)),
            "dyn.forward_dynamics, jax.jit": jax.jit(users_rollout(public, 1e-3)),
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
