"""Batched forward dynamics and rollout throughput for the Panda, and the cost of identification gradients.

    python benchmarks/rollouts.py [--batches 1,1024,16384] [--steps 100] [--repeats 5] [--peer auto|pinocchio|mjx]

Figures are medians over repeats, per state (forward dynamics) or per state and step (rollouts), float64,
measured in this run. Forward dynamics is timed through the closed-form quantity ``forward_dynamics`` and
through the numeric route (lowered M and bias, unrolled L D L^T); rollouts use the closed form. Peers: Pinocchio's ``aba`` called from Python per state, and MuJoCo MJX
(``mujoco-mjx``, the same URDF through ``mujoco``, vmapped ``mjx.forward``, batches 1 and 64 only: it
takes milliseconds per state on CPU) when it is importable.
Gradient cost: ``jax.grad`` of a least-squares loss over 256 states with respect to the 70 inertial
parameters, relative to the loss itself, through ``inverse_dynamics`` and through the regressor.
"""

from __future__ import annotations

import argparse
import re
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
PANDA = ERD / "panda_description/urdf/panda.urdf"
LOCK = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}


def median_time(fn, repeats: int) -> float:
    jax.block_until_ready(fn())
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def pinocchio_aba(states, repeats):
    model = pin.buildModelFromUrdf(str(PANDA))
    model = pin.buildReducedModel(model, [model.getJointId(k) for k in LOCK], pin.neutral(model))
    data = model.createData()
    q, qd, tau = states

    def loop():
        for k in range(len(q)):
            pin.aba(model, data, q[k], qd[k], tau[k])

    return median_time(loop, repeats) / len(q)


def mjx_forward(batches, repeats):
    """Per-state seconds of vmapped ``mjx.forward`` at each batch size, or None if MJX is unavailable."""
    try:
        import mujoco
        from mujoco import mjx
    except ImportError:
        return None
    text = PANDA.read_text()
    text = re.sub(r"<visual>.*?</visual>|<collision>.*?</collision>", "", text, flags=re.S)
    for joint in LOCK:  # lock the fingers, as jaxskid's model does
        text = re.sub(rf'(<joint name="{joint}" type=")prismatic', r"\1fixed", text)
    model = mujoco.MjModel.from_xml_string(text)
    mx = mjx.put_model(model)
    out = {}
    for b in batches:
        rng = np.random.default_rng(0)
        data = jax.vmap(lambda q, v, f: mjx.make_data(mx).replace(qpos=q, qvel=v, qfrc_applied=f))(
            *(jnp.asarray(rng.normal(size=(b, model.nv))) for _ in range(3)))
        step = jax.jit(jax.vmap(lambda d: mjx.forward(mx, d).qacc))
        out[b] = median_time(lambda: step(data), repeats) / b
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", default="1,1024,16384")
    ap.add_argument("--steps", type=int, default=100, help="rollout length (RK4 steps of 1 ms)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--peer", choices=("auto", "pinocchio", "mjx"), default="auto")
    args = ap.parse_args(argv)
    batches = [int(b) for b in args.batches.split(",")]
    robot = jaxskid.load(PANDA, lock=LOCK)
    rng = np.random.default_rng(0)
    print(f"jax {jax.__version__}, {jax.devices()[0].platform} x {len(jax.devices())}, float64, Panda {robot.n_dof} DOF")

    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "regressor", "forward_dynamics"],
                            cache_dir=cache)
        # the same lowered M and bias, without the closed-form quantity: the numeric L D L^T route
        numeric = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"], cache_dir=cache)
        print(f"derive + lower: {time.perf_counter() - t0:.2f} s")

        print("\nforward dynamics, qdd = M^-1 (tau - C qd - Q_grav)  [per state]")
        fd = {}
        for label, model in (("closed form", dyn), ("M + bias, L D L^T", numeric)):
            for b in batches:
                q, qd, tau = (jnp.asarray(rng.normal(size=(b, 7))) for _ in range(3))
                if b == 1:
                    q, qd, tau = q[0], qd[0], tau[0]
                t0 = time.perf_counter()
                jax.block_until_ready(jaxskid.forward_dynamics(model, q, qd, tau))
                compile_s = time.perf_counter() - t0
                fd[b] = median_time(lambda: jaxskid.forward_dynamics(model, q, qd, tau), args.repeats) / b
                print(f"  {label:<18} batch {b:>6}: {fd[b] * 1e9:9.0f} ns/state   (first call {compile_s:.2f} s)")
        states = tuple(rng.normal(size=(256, 7)) for _ in range(3))
        t_pin = pinocchio_aba(states, args.repeats)
        print(f"  Pinocchio aba, per call from Python: {t_pin * 1e9:.0f} ns")
        if args.peer in ("auto", "mjx"):
            # milliseconds per state on CPU: small batches only, to keep the run short
            mjx_times = mjx_forward([b for b in (1, 64) if b <= max(batches)], args.repeats)
            if mjx_times is None:
                print("  MuJoCo MJX: not importable (pip install mujoco-mjx)")
            else:
                for b, t in mjx_times.items():
                    print(f"  MJX mjx.forward batch {b:>6}: {t * 1e9:9.0f} ns/state")

        print(f"\nrollouts, {args.steps} RK4 steps of 1 ms, zero torque  [per state and step]")
        for b in batches:
            x0 = jnp.asarray(np.concatenate([rng.uniform(-1, 1, (b, 7)), np.zeros((b, 7))], axis=1))
            x0 = x0[0] if b == 1 else x0
            controls = np.zeros((args.steps, 7))
            run = lambda: jaxskid.rollout(dyn, x0, controls, 1e-3, args.steps).x  # noqa: E731  (closed form)
            t = median_time(run, args.repeats) / (b * args.steps)
            print(f"  batch {b:>6}: {t * 1e9:9.0f} ns/state/step  ({t / 4 * 1e9:.0f} ns per forward-dynamics stage)")

        print("\nidentification loss over 256 states, gradient w.r.t. the 70 inertial parameters")
        q, qd, qdd = (jnp.asarray(x) for x in states)
        p0 = dyn.param_vector()
        tau = dyn.inverse_dynamics(q, qd, qdd, p0 * 1.1)

        def loss_tau(p):
            r = dyn.inverse_dynamics(q, qd, qdd, p) - tau
            return jnp.sum(r * r)

        order = [dyn.parameters.index(k) for k in _standard_names(robot)]
        y = dyn.regressor(q, qd, qdd)

        def loss_reg(p):
            r = jnp.einsum("snp,p->sn", y, p[jnp.asarray(order)]) - tau
            return jnp.sum(r * r)

        for label, loss in (("through inverse_dynamics", loss_tau), ("through the regressor", loss_reg)):
            f, g = jaxskid.jit(loss), jaxskid.jit(jax.grad(loss))
            t0 = time.perf_counter()
            jax.block_until_ready(g(p0))
            compile_s = time.perf_counter() - t0
            t_loss = median_time(lambda: f(p0), args.repeats * 4)
            t_grad = median_time(lambda: g(p0), args.repeats * 4)
            print(f"  {label:<25} loss {t_loss * 1e6:8.1f} us, gradient {t_grad * 1e6:8.1f} us, "
                  f"ratio {t_grad / t_loss:5.2f}  (gradient compile {compile_s:.2f} s)")


def _standard_names(robot):
    """The URDF parameter names in the regressor's column order ({link}_m, {link}_mcx, ...)."""
    return [f"{name.replace('.', '_')}" for name in jaxskid.standard_parameter_names(robot)]


if __name__ == "__main__":
    main()
