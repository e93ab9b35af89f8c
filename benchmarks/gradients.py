"""Gradients through rollouts: what a gradient costs against the loss, to run and to compile.

    python benchmarks/gradients.py [--robots z1,panda] [--steps 500,2000] [--batch 64] [--repeats 5] [--markdown PATH]
    python benchmarks/gradients.py --scenes [ur5_pd_gravity,ur5_pdgravity,panda_computed_torque,solo12_contact,four_bar]

For each robot (Unitree z1 and the Franka Panda with its fingers locked, from example-robot-data) and
horizon, a loss is the mean squared state of an RK4 rollout at 1 ms steps under open-loop sinusoidal
torques, as a function of all inertial parameters. The script times, each in a fresh process:

- the loss, its reverse-mode gradient (``jax.grad``, ``autodiff="reverse"``) and its forward-mode gradient
  (``jax.jacfwd``, ``autodiff="forward"``), medians over repeats, and the ratio gradient / loss;
- the first call (trace + compile + run) under ``jaxskid.jit`` and under plain ``jax.jit``, cold (an empty
  persistent compilation cache) and warm (a second process on the same cache); each jit has its own cache
  and processes, so neither finds the other's compiled program;
- the compiled program's memory (arguments, outputs and temporaries, from XLA's memory analysis);
- the same for a batch of rollouts (one parameter set, ``--batch`` initial states).

The generated modules are cached beforehand, so first calls measure compilation, not derivation.

``--scenes`` times closed-loop and constrained rollouts the same way (reverse mode only), with respect to all
inertial parameters, each gradient also checked against a central difference of the loss along a random
direction (the column "check": their relative difference):

- ``ur5_pd_gravity``: the UR5 tracking a reference for 1000 RK4 steps of 1 ms under a hand-written policy that
  closes over the parameters: PD plus gravity compensation ``dyn.gravity_torques(q, p)`` (adaptive control);
- ``ur5_pdgravity``: the same law as :class:`jaxskid.PDGravity`;
- ``panda_computed_torque``: the Panda (fingers locked) under :class:`jaxskid.ComputedTorque` whose model is the
  parameters (the plant keeps its defaults, so the loss measures the model's mismatch), 1000 steps;
- ``solo12_contact``: solo12 with a floating base dropped on :class:`jaxskid.GroundContact`, joints held by PD,
  500 steps of 0.5 ms, a batch of ``--batch`` drops;
- ``four_bar``: the four-bar loop (``robots/four_bar.yaml``, Baumgarte-stabilised), the crank driven by a torque
  sequence, 1000 steps of 1 ms.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import doc_tables  # benchmarks/doc_tables.py, beside this script

ROBOTS = {
    "z1": ("z1_description/urdf/z1.urdf", None),
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
}


def _measure(out: dict, name: str, fn, p0, jit_name: str, repeats: int):
    """Into ``out``: ``fn``'s first call under ``jit_name`` (``{name}_first_{jit_name}``); under jaxskid.jit also
    its median time over ``repeats`` calls (``{name}_time``) and its compiled program's memory
    (``{name}_memory``: arguments, outputs and temporaries). Returns the first call's value."""
    import jax
    import numpy as np

    import jaxskid

    f = (jaxskid.jit if jit_name == "jaxskid" else jax.jit)(fn)
    start = time.perf_counter()
    value = jax.block_until_ready(f(p0))
    out[f"{name}_first_{jit_name}"] = time.perf_counter() - start
    if jit_name == "jax":
        return value
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(f(p0))
        times.append(time.perf_counter() - start)
    out[f"{name}_time"] = float(np.median(times))
    memory = jax.jit(fn).lower(p0).compile().memory_analysis()
    if memory is not None:
        out[f"{name}_memory"] = int(memory.temp_size_in_bytes + memory.output_size_in_bytes
                                    + memory.argument_size_in_bytes)
    return value


def _case(robot: str, steps: int, batch: int, repeats: int, jit_name: str) -> dict:
    """One case, in this process: first calls under ``jit_name``; with jaxskid.jit also run times and memory."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    import pinocchio as pin

    import jaxskid

    erd = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
    path, lock = ROBOTS[robot]
    dyn = jaxskid.lower(jaxskid.load(erd / path, lock=lock), quantities=["forward_dynamics"])
    n, p0 = dyn.n_dof, dyn.param_vector()
    t = 1e-3 * np.arange(steps)[:, None]
    u = jnp.asarray(2.0 * np.sin(2 * np.pi * (1 + np.arange(n)) * t / (steps * 1e-3)))
    x0 = jnp.zeros((batch, 2 * n) if batch else (2 * n,)).at[..., :n].set(0.1)

    def loss(p, autodiff="reverse"):
        x = jaxskid.rollout(dyn, x0, u, 1e-3, steps, params=p, autodiff=autodiff).x
        return jnp.mean(x**2)

    fns = {
        "loss": loss,
        "reverse": jax.grad(loss),
        "forward": jax.jacfwd(lambda p: loss(p, "forward")),
    }
    out = {"robot": robot, "n_dof": n, "n_params": len(p0), "steps": steps, "batch": batch}
    for name, fn in fns.items():
        if name == "forward" and jit_name == "jax":
            continue
        _measure(out, name, fn, p0, jit_name, repeats)
    return out


SCENES = ("ur5_pd_gravity", "ur5_pdgravity", "panda_computed_torque", "solo12_contact", "four_bar")


def _scene(name: str, batch: int):
    """``(loss, p0, n_dof, n_params, steps, batch)`` of a closed-loop or constrained scene (module docstring)."""
    import jax
    import jax.numpy as jnp
    import numpy as np
    import pinocchio as pin

    import jaxskid

    erd = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
    if name.startswith("ur5") or name == "panda_computed_torque":
        if name == "panda_computed_torque":
            robot = jaxskid.load(erd / ROBOTS["panda"][0], lock=ROBOTS["panda"][1])
            dyn = jaxskid.lower(robot, ["forward_dynamics"])
        else:
            dyn = jaxskid.lower(jaxskid.load(erd / "ur_description/urdf/ur5_robot.urdf"),
                                ["forward_dynamics", "gravity_torques"])
        n, steps = dyn.n_dof, 1000
        home = jnp.linspace(-0.5, 0.5, n)

        def reference(t):
            return home + 0.3 * jnp.sin(2.0 * t + jnp.arange(n))

        x0 = jnp.concatenate([reference(0.0) + 0.1, jnp.zeros(n)])
        kp, kd = jnp.full(n, 100.0), jnp.full(n, 20.0)

        def loss(p):
            if name == "ur5_pd_gravity":
                def controls(t, x):
                    qr, vr, _ = jaxskid.reference_derivatives(reference, t)
                    return kp * (qr - x[:n]) + kd * (vr - x[n:]) + dyn.gravity_torques(x[:n], p)
            elif name == "ur5_pdgravity":
                controls = jaxskid.PDGravity(dyn, reference, kp, kd, params=p)
            else:  # the controller's model is p, the plant keeps the defaults: the loss measures the mismatch
                controls = jaxskid.ComputedTorque(dyn, reference, kp, kd, params=p)
            plant = None if name == "panda_computed_torque" else p
            traj = jaxskid.rollout(dyn, x0, controls, 1e-3, steps, params=plant)
            return jnp.mean((traj.q - jax.vmap(reference)(traj.t)) ** 2)

        return loss, dyn.param_vector(), n, len(dyn.parameters), steps, 1
    if name == "solo12_contact":
        robot = jaxskid.load(erd / "solo_description/robots/solo12.urdf", floating_base=True)
        from jaxskid.apps.simulation._contact import NEEDED

        dyn = jaxskid.lower(robot, ["forward_dynamics", *NEEDED])
        stand = jnp.asarray([0, 0.8, -1.6, 0, 0.8, -1.6, 0, -0.8, 1.6, 0, -0.8, 1.6])

        def hold(t, x):
            q, v = x[:robot.nq], x[robot.nq:]
            return jnp.concatenate([jnp.zeros(6), 20.0 * (stand - q[7:]) - 0.5 * v[6:]])

        contact = jaxskid.GroundContact(dyn, inner=hold)
        rng = np.random.default_rng(0)
        q = np.zeros((batch, robot.nq))
        q[:, 2], q[:, 6], q[:, 7:] = 0.24 + rng.uniform(0.0, 0.05, batch), 1.0, stand
        v = np.zeros((batch, robot.nv))
        v[:, :6] = rng.uniform(-0.3, 0.3, (batch, 6))
        x0 = jnp.asarray(np.concatenate([q, v], axis=1))

        def loss(p):
            traj = jaxskid.rollout(dyn, x0, contact, 5e-4, 500, params=p, saveat=jaxskid.SaveAt(every=10))
            return jnp.mean((traj.x[..., 2] - 0.22) ** 2) + jnp.mean(traj.x[..., robot.nq:] ** 2)

        return loss, dyn.param_vector(), robot.nv, len(dyn.parameters), 500, batch
    if name == "four_bar":
        root = Path(__file__).resolve().parents[1]
        dyn = jaxskid.lower(jaxskid.load(root / "robots" / "four_bar.yaml"),
                            ["mass_matrix", "inverse_dynamics", "constraint_jacobian", "constraint_drift",
                             "constraint_residual"])
        steps = 1000
        g = jnp.asarray([1.0, -1.0, 1.0])
        x0 = jnp.concatenate([0.9 * g, -0.5 * g])
        t = 1e-3 * jnp.arange(steps)
        u = jnp.stack([0.5 * jnp.sin(3.0 * t), jnp.zeros(steps), jnp.zeros(steps)], axis=1)

        def loss(p):
            traj = jaxskid.rollout(dyn, x0, u, 1e-3, steps, params=p)
            return jnp.mean(traj.x**2)

        return loss, dyn.param_vector(), dyn.n_dof, len(dyn.parameters), steps, 1
    raise SystemExit(f"unknown scene {name!r}; the scenes are {', '.join(SCENES)}")


def _scene_case(name: str, batch: int, repeats: int, jit_name: str) -> dict:
    """One scene in this process: first calls under ``jit_name``; with jaxskid.jit also run times, memory and
    the central-difference check."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    loss, p0, n, n_params, steps, batch = _scene(name, batch)
    out = {"scene": name, "n_dof": n, "n_params": n_params, "steps": steps, "batch": batch}
    for kind, fn in (("loss", loss), ("reverse", jax.grad(loss))):
        value = _measure(out, kind, fn, p0, jit_name, repeats)
        if kind == "reverse" and jit_name == "jaxskid":
            direction = np.random.default_rng(1).standard_normal(len(p0)) * np.maximum(np.abs(np.asarray(p0)), 1e-3)
            h = 1e-6
            central = (float(loss(p0 + h * direction)) - float(loss(p0 - h * direction))) / (2 * h)
            out["check"] = abs(float(np.asarray(value) @ direction) - central) / max(abs(central), 1e-300)
    return out


def _in_process(args: list[str], cache: str, flag: str = "--case") -> dict:
    env = dict(os.environ, JAX_COMPILATION_CACHE_DIR=cache, JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
               JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0")
    done = subprocess.run([sys.executable, __file__, flag, *args], env=env, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(done.stderr[-3000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def _scenes_table(names: list[str], batch: int, repeats: int, markdown) -> None:
    out = doc_tables.Lines()
    out("| scene | DOF, params | steps | batch | loss | grad | ratio | grad first call, jaxskid.jit: cold, warm "
          "| grad first call, jax.jit: cold, warm | memory loss / grad (MB) | check |")
    out("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        case = [name, str(batch), str(repeats)]
        with tempfile.TemporaryDirectory() as cache:
            cold, warm = (_in_process([*case, "jaxskid"], cache, "--scene-case") for _ in range(2))
        with tempfile.TemporaryDirectory() as cache:
            cold_jax, warm_jax = (_in_process([*case, "jax"], cache, "--scene-case") for _ in range(2))
        loss, grad = cold["loss_time"], cold["reverse_time"]
        out(f"| {name} | {cold['n_dof']}, {cold['n_params']} | {cold['steps']} | {cold['batch']} "
              f"| {1e3 * loss:.2f} ms | {1e3 * grad:.2f} ms | {grad / loss:.1f}x "
              f"| {cold['reverse_first_jaxskid']:.1f} s, {warm['reverse_first_jaxskid']:.1f} s "
              f"| {cold_jax['reverse_first_jax']:.1f} s, {warm_jax['reverse_first_jax']:.1f} s "
            f"| {_mb(cold.get('loss_memory'))} / {_mb(cold.get('reverse_memory'))} | {cold['check']:.1e} |")
    doc_tables.write(markdown, out, f"Closed-loop and constrained scenes, reverse mode, medians of {repeats}; first "
                     "calls in fresh processes, cold (empty compilation cache) and warm; check: the gradient against "
                     "a central difference along a random direction (relative difference).")


def _mb(x) -> str:
    return f"{x / 2**20:.1f}" if x is not None else "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", default="z1,panda")
    parser.add_argument("--steps", default="500,2000")
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scenes", nargs="?", const=",".join(SCENES), default=None,
                        help="closed-loop and constrained scenes instead of the open-loop robots")
    parser.add_argument("--case", nargs=5, help=argparse.SUPPRESS)
    parser.add_argument("--scene-case", nargs=4, help=argparse.SUPPRESS)
    doc_tables.add_option(parser)
    args = parser.parse_args()
    if args.scene_case:
        name, batch, repeats, jit_name = args.scene_case
        print(json.dumps(_scene_case(name, int(batch), int(repeats), jit_name)))
        return
    if args.scenes:
        _scenes_table(args.scenes.split(","), args.batch, args.repeats, args.markdown)
        return
    if args.case:
        robot, steps, batch, repeats, jit_name = args.case
        print(json.dumps(_case(robot, int(steps), int(batch), int(repeats), jit_name)))
        return
    out = doc_tables.Lines()
    out("| robot | steps | batch | loss | reverse grad | ratio | forward grad (jacfwd) | ratio "
          "| first call loss / grad, jaxskid.jit: cold, warm | grad first call, jax.jit: cold, warm "
          "| memory loss / grad (MB) |")
    out("|---|---|---|---|---|---|---|---|---|---|---|")
    for robot in args.robots.split(","):
        for steps in map(int, args.steps.split(",")):
            for batch in (0, args.batch):
                case = [robot, str(steps), str(batch), str(args.repeats)]
                with tempfile.TemporaryDirectory() as cache:
                    cold, warm = _in_process([*case, "jaxskid"], cache), _in_process([*case, "jaxskid"], cache)
                with tempfile.TemporaryDirectory() as cache:
                    cold_jax, warm_jax = _in_process([*case, "jax"], cache), _in_process([*case, "jax"], cache)
                loss, rev, fwd = cold["loss_time"], cold["reverse_time"], cold["forward_time"]
                out(
                    f"| {robot} ({cold['n_dof']}, {cold['n_params']} params) | {steps} | {batch or 1} "
                    f"| {1e3 * loss:.2f} ms | {1e3 * rev:.2f} ms | {rev / loss:.1f}x | {1e3 * fwd:.1f} ms "
                    f"| {fwd / loss:.0f}x "
                    f"| {cold['loss_first_jaxskid']:.1f} / {cold['reverse_first_jaxskid']:.1f} s, "
                    f"{warm['loss_first_jaxskid']:.1f} / {warm['reverse_first_jaxskid']:.1f} s "
                    f"| {cold_jax['reverse_first_jax']:.1f} s, {warm_jax['reverse_first_jax']:.1f} s "
                    f"| {_mb(cold.get('loss_memory'))} / {_mb(cold.get('reverse_memory'))} |"
                )
    doc_tables.write(args.markdown, out, f"RK4 at 1 ms, open-loop torques, gradients with respect to all inertial "
                     f"parameters; medians of {args.repeats}; first calls in fresh processes, cold (empty compilation "
                     "cache) and warm, each jit in its own processes and cache.")


if __name__ == "__main__":
    main()
