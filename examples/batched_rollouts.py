"""4096 rollouts of the 3-DOF anthropomorphic arm with randomised masses, in one batched call.

    python examples/batched_rollouts.py [OUT_DIR]      # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

A PD + gravity-compensation controller built on the *nominal* model drives the arm to a set-point while
each of the 4096 simulated arms has its own link masses (+-30 %) and initial state. The steady-state
error comes from the gravity-model mismatch: at rest kp (q_d - q) + Q_grav,nominal(q) = Q_grav,true(q),
which the example checks on the final states; it plots trajectories and the spread of the final errors.
The batch is vmapped, and split across devices when there are several (``jax.devices()``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402
from _common import output_dir, save_figure  # noqa: E402  (examples/_common.py, beside this script)

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "arm_3dof.yaml"


def main(out_dir=None, batch=4096, steps=1500, dt=2e-3, seed=0):
    rng = np.random.default_rng(seed)
    robot = jaxskid.load(ROBOT)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "gravity_torques"])
    nominal = robot.default_params()
    masses = ("m1", "m2", "m3")
    params = {k: np.full(batch, v) for k, v in nominal.items()}
    for k in masses:
        params[k] = nominal[k] * rng.uniform(0.7, 1.3, size=batch)
    goal = jnp.array([0.5, 0.6, -0.9])
    kp, kd = jnp.array([40.0, 40.0, 5.0]), jnp.array([8.0, 8.0, 0.8])  # the forearm is light
    controller = jaxskid.PDGravity(dyn, goal, kp, kd, params=nominal)
    x0 = np.concatenate([rng.uniform(-0.5, 0.5, size=(batch, 3)), np.zeros((batch, 3))], axis=1)

    start = time.perf_counter()
    traj = jaxskid.rollout(dyn, x0, controller, dt, steps, jaxskid.RK4(), params)
    jax.block_until_ready(traj.x)
    elapsed = time.perf_counter() - start  # compilation included: see benchmarks/rollouts.py for warm figures

    final = np.asarray(traj.q[:, -1])
    error = final - np.asarray(goal)
    # at rest, kp (q_d - q) + Q_grav,nominal(q) = Q_grav,true(q): the statics the rollouts must end in
    pvec = jnp.stack([jnp.asarray(params[k]) for k in dyn.parameters], axis=-1)
    true_gravity = jax.vmap(lambda q, p: dyn.gravity_torques(q, p))(jnp.asarray(final), pvec)
    residual = kp[None] * (goal[None] - final) + dyn.gravity_torques(final, nominal) - true_gravity
    equilibrium = float(jnp.abs(residual).max())
    speed = float(jnp.abs(traj.qd[:, -1]).max())

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(traj.t)  # shared by the rollouts (one dt): (steps + 1,)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for i in range(40):
        for j in range(3):
            axes[0].plot(t, np.asarray(traj.q[i, :, j]), color=f"C{j}", lw=0.6, alpha=0.5)
    for j in range(3):
        axes[0].axhline(float(goal[j]), color=f"C{j}", ls="--", lw=1.5, label=f"q{j + 1} set-point")
    axes[0].set(xlabel="t [s]", ylabel="q [rad]", title="40 of the rollouts")
    axes[0].legend(fontsize=8)
    for j in (1, 2):  # the waist carries no gravity load: its error is zero
        axes[1].hist(error[:, j], bins=60, alpha=0.5, color=f"C{j}", label=f"joint {j + 1}")
    axes[1].set(xlabel="final error q - q_d [rad]", ylabel="rollouts",
                title=f"{batch} arms, masses +-30 %, nominal gravity compensation")
    axes[1].legend(fontsize=8)
    figure = save_figure(fig, output_dir(out_dir) / "batched_rollouts.png")

    state_steps = batch * steps
    result = {
        "batch": batch,
        "steps": steps,
        "seconds": elapsed,
        "ns_per_state_step": elapsed / state_steps * 1e9,
        "mean_abs_error": np.abs(error).mean(axis=0),
        "max_abs_error": np.abs(error).max(axis=0),
        "equilibrium_residual": equilibrium,
        "max_final_speed": speed,
        "devices": len(jax.devices()),
        "figure": figure,
    }
    print(f"{batch} rollouts x {steps} RK4 steps of {dt} s on {len(jax.devices())} device(s)")
    print(f"{elapsed:.1f} s with compilation: {result['ns_per_state_step']:.0f} ns per state and step")
    print(f"final |q - q_d| mean {np.round(result['mean_abs_error'], 4).tolist()}, max "
          f"{np.round(result['max_abs_error'], 4).tolist()} rad")
    print(f"at rest (max |qd| {speed:.1e} rad/s), statics kp (q_d - q) + g_nominal(q) = g_true(q) holds to "
          f"{equilibrium:.1e} Nm")
    print(f"figure {figure}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
