"""Closed-loop rollouts and their gradients on whatever JAX's default device is (prepared for a GPU machine).

    JAXSKID_CACHE_DIR=... python benchmarks/gpu_rollouts.py [--budget 480] [--out results.jsonl]

Derive on a CPU machine first (``--derive-only`` with the same ``JAXSKID_CACHE_DIR``): the script then spends its
time on XLA's compile and the runs. Each result is printed as one JSON line as soon as it is measured, and
appended to ``--out``; every section checks the time left (``--budget`` seconds) and skips what would not fit.

Sections:

- ``composition``: a policy that closes over traced gains (the 2R arm of ``robots/``, 100 RK4 steps), under
  ``jax.grad``, ``jax.jit(jax.grad)``, ``jaxskid.jit(jax.grad)``, ``jax.jacfwd`` and ``jax.hessian``, each against
  a central difference of the loss computed on the same device;
- ``checks``: NaN in a device array refused by a top-level call, naming the index;
- ``closed_loop``: the UR5 tracking a reference under hand-written PD + gravity compensation from the
  parameters being differentiated, and ``open_loop``: the UR5 under a torque sequence; 1000 RK4 steps of 1 ms,
  batch 1 and 1024: loss and gradient times (medians), first calls, the gradient against a central
  difference; each ``one call`` (the steps of :mod:`jaxskid.runtime._rk4`: the native kernel on CPU, the
  same recursion in JAX elsewhere) and ``stage by stage`` (every stage differentiated by JAX).
"""

from __future__ import annotations

import argparse
import json
import os
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

UR5 = os.environ.get("JAXSKID_UR5_URDF", "")
START = time.perf_counter()


def left(budget: float) -> float:
    return budget - (time.perf_counter() - START)


def emit(out: Path | None, **row) -> None:
    row = {"device": str(jax.devices()[0]), **row}
    line = json.dumps(row)
    print(line, flush=True)
    if out is not None:
        with out.open("a") as f:
            f.write(line + "\n")


def timed(fn, *args, repeats: int = 5) -> tuple[float, float]:
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return first, float(np.median(times))


def composition(out) -> None:
    dyn = jaxskid.lower(jaxskid.load(ROOT / "robots/arm_2r.yaml"), ["forward_dynamics", "gravity_torques"])
    n, x0, kd = dyn.n_dof, jnp.asarray([0.4, -0.3, 0.0, 0.0]), jnp.asarray([4.0, 3.0])

    def loss(theta):
        kp = jnp.asarray([30.0, 20.0]) * (1 + theta)
        traj = jaxskid.rollout(dyn, x0, lambda t, x: -kp * x[:n] - kd * x[n:] + dyn.gravity_torques(x[:n]),
                               2e-3, 100)
        return jnp.sum(traj.q[-1] ** 2) + jnp.mean(traj.qd**2)

    theta, h1, h2 = 0.05, 1e-5, 1e-3
    first = float((loss(theta + h1) - loss(theta - h1)) / (2 * h1))
    second = float((loss(theta + h2) - 2 * loss(theta) + loss(theta - h2)) / h2**2)
    for name, fn, want in (("grad", jax.grad(loss), first), ("jit(grad)", jax.jit(jax.grad(loss)), first),
                           ("jaxskid.jit(grad)", jaxskid.jit(jax.grad(loss)), first),
                           ("jacfwd", jax.jacfwd(loss), first), ("hessian", jax.hessian(loss), second)):
        try:
            got = float(fn(jnp.asarray(theta)))
            emit(out, section="composition", transform=name, value=got, reference=want,
                 rel_error=abs(got - want) / abs(want))
        except Exception as exc:  # a failure is a result here
            emit(out, section="composition", transform=name, error=f"{type(exc).__name__}: {str(exc)[:300]}")


def checks(out) -> None:
    dyn = jaxskid.lower(jaxskid.load(ROOT / "robots/arm_2r.yaml"), ["mass_matrix"])
    q = jnp.zeros((8, dyn.n_dof)).at[5, 1].set(jnp.nan)
    try:
        dyn.mass_matrix(q)
        emit(out, section="checks", error="no error for NaN")
    except jaxskid.InputError as exc:
        emit(out, section="checks", message=str(exc))


def rollouts(out, budget: float, batches) -> None:
    from jaxskid.apps.simulation import _rollout

    dyn = jaxskid.lower(jaxskid.load(UR5), ["forward_dynamics", "gravity_torques"])
    n, p0 = dyn.n_dof, dyn.param_vector()
    home = jnp.linspace(-0.5, 0.5, n)

    def reference(t):
        return home + 0.3 * jnp.sin(2.0 * t + jnp.arange(n))

    kp, kd = jnp.full(n, 100.0), jnp.full(n, 20.0)
    u = jnp.asarray(np.sin(np.arange(1000)[:, None] * 1e-3 * (1 + np.arange(n))))
    for section in ("closed_loop", "open_loop"):
        for batch in batches:
            x0 = jnp.concatenate([reference(0.0) + 0.1, jnp.zeros(n)])
            if batch > 1:
                x0 = x0 + 0.05 * jnp.asarray(np.random.default_rng(0).standard_normal((batch, 2 * n)))

            def loss(p, x0=x0, section=section):
                def policy(t, x):
                    qr, vr, _ = jaxskid.reference_derivatives(reference, t)
                    return kp * (qr - x[:n]) + kd * (vr - x[n:]) + dyn.gravity_torques(x[:n], p)

                traj = jaxskid.rollout(dyn, x0, policy if section == "closed_loop" else u, 1e-3, 1000, params=p)
                return jnp.mean((traj.q - jax.vmap(reference)(traj.t)) ** 2)

            for mode in ("one call", "stage by stage"):
                if left(budget) < 90:
                    emit(out, section=section, batch=batch, mode=mode, skipped="budget")
                    continue
                steps = (_rollout.feedback_rk4, _rollout.held_torque_rk4)
                jax.clear_caches()  # the rollout's jit would reuse the other mode's program
                if mode == "stage by stage":
                    _rollout.feedback_rk4 = _rollout.held_torque_rk4 = lambda dyn, batched: None
                try:
                    loss_first, loss_time = timed(jax.jit(loss), p0)
                    grad = jax.jit(jax.grad(loss))
                    grad_first, grad_time = timed(grad, p0)
                    g = np.asarray(grad(p0))
                    d = np.random.default_rng(1).standard_normal(len(p0)) * np.maximum(np.abs(np.asarray(p0)), 1e-3)
                    h = 1e-6
                    central = (float(loss(p0 + h * d)) - float(loss(p0 - h * d))) / (2 * h)
                    emit(out, section=section, robot="ur5", steps=1000, batch=batch, mode=mode,
                         loss_ms=1e3 * loss_time, grad_ms=1e3 * grad_time, ratio=grad_time / loss_time,
                         loss_first_s=loss_first, grad_first_s=grad_first,
                         check=abs(float(g @ d) - central) / abs(central))
                except Exception as exc:
                    emit(out, section=section, batch=batch, mode=mode, error=f"{type(exc).__name__}: {str(exc)[:300]}")
                finally:
                    _rollout.feedback_rk4, _rollout.held_torque_rk4 = steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--budget", type=float, default=480.0)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--batches", default="1,1024")
    parser.add_argument("--derive-only", action="store_true")
    parser.add_argument("--skip", default="", help="sections to leave out, comma-separated")
    args = parser.parse_args()
    if args.derive_only:
        jaxskid.lower(jaxskid.load(ROOT / "robots/arm_2r.yaml"), ["forward_dynamics", "gravity_torques"])
        jaxskid.lower(jaxskid.load(ROOT / "robots/arm_2r.yaml"), ["mass_matrix"])
        jaxskid.lower(jaxskid.load(UR5), ["forward_dynamics", "gravity_torques"])
        return
    emit(args.out, section="start", jax=jax.__version__, backend=jax.default_backend())
    if "composition" not in args.skip:
        composition(args.out)
    if "checks" not in args.skip:
        checks(args.out)
    rollouts(args.out, args.budget, [int(b) for b in args.batches.split(",")])
    emit(args.out, section="end", seconds=time.perf_counter() - START)


if __name__ == "__main__":
    main()
