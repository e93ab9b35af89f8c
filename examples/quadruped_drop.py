"""Drop a floating-base quadruped onto the ground, pushed, and let it settle: 1024 rollouts in one call.

    python examples/quadruped_drop.py [OUT_DIR]     # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

The robot is example-robot-data's solo12 with a free-flyer base (``jaxskid.load(path, floating_base=True)``:
``q = (p, quat, 12 joints)``, ``qd = (omega, v, 12 joint rates)``). Its joints hold a standing pose by PD
control; its four feet meet the ground through :class:`jaxskid.GroundContact` (spring-damper normal force,
regularised Coulomb friction). Each of the 1024 rollouts starts 2-10 cm higher than standing height with a random
push (base velocity up to 0.5 m/s and 1 rad/s), and RK4 at 0.5 ms runs 3 s. The script reports how many came to
rest standing (the normal forces carry the weight, every speed small), the spread of the final base height, the
quaternion norm after 6000 steps, and saves a figure: base height over time, and the final normal force per foot
against the quarter weight. It also checks that the step integrates the drops stably: the mechanical energy
(kinetic, gravitational, the contact springs' and the joint PD springs') can only fall once the feet touch, as
every force but gravity and the springs dissipates, and rollout's own check (:class:`jaxskid.RolloutWarning`)
says nothing.
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
from jaxskid.apps.simulation._contact import NEEDED  # noqa: E402
from _common import erd_urdf, output_dir, save_figure  # noqa: E402  (examples/_common.py, beside this script)

STAND = np.array([0, 0.8, -1.6, 0, 0.8, -1.6, 0, -0.8, 1.6, 0, -0.8, 1.6])  # hip, thigh, knee per leg [rad]
KP, KD = 20.0, 0.5  # joint PD [N m/rad], [N m s/rad]
DT, SECONDS = 5e-4, 3.0


def initial_states(robot, batch: int, rng) -> np.ndarray:
    """Standing pose 2-10 cm above standing height (0.22 m), pushed: (batch, nq + nv)."""
    q = np.zeros((batch, robot.nq))
    q[:, 2] = 0.22 + rng.uniform(0.02, 0.10, batch)
    q[:, 6] = 1.0
    q[:, 7:] = STAND
    v = np.zeros((batch, robot.nv))
    v[:, :3] = rng.uniform(-1.0, 1.0, (batch, 3))  # base angular velocity [rad/s]
    v[:, 3:6] = rng.uniform(-0.5, 0.5, (batch, 3))  # base linear velocity [m/s]
    return np.concatenate([q, v], axis=1)


def mechanical_energy(dyn, robot, contact, x) -> tuple[np.ndarray, np.ndarray]:
    """``(E, touched)`` at the saved states ``x (batch, saved, nq + nv)``: kinetic + gravitational energy + the
    contact springs' ``k d^2 / 2`` + the joint springs' ``KP |STAND - q|^2 / 2``, and whether a foot has touched
    the ground by then."""
    q, v = x[..., :robot.nq], x[..., robot.nq:]
    depth = jax.vmap(jax.vmap(lambda q: contact.height - contact.forces(q, jnp.zeros(robot.nv))[0][:, 2]))(q)
    springs = 0.5 * contact.k * jnp.sum(jnp.maximum(depth, 0.0) ** 2, axis=-1)
    joints = 0.5 * KP * jnp.sum((STAND - q[..., 7:]) ** 2, axis=-1)
    energy = dyn.kinetic_energy(q, v) + dyn.potential_energy(q) + springs + joints
    touched = np.maximum.accumulate(np.asarray(depth.max(axis=-1)) > 0, axis=1)
    return np.asarray(energy), touched


def plot(path: Path, t, height, forces, weight) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    for lo, hi, alpha in ((0, 100, 0.15), (10, 90, 0.3), (25, 75, 0.5)):
        a.fill_between(t, np.percentile(height, lo, axis=0), np.percentile(height, hi, axis=0), color="C0",
                       alpha=alpha, lw=0)
    a.plot(t, np.median(height, axis=0), color="C0", lw=1.2, label="median (bands: 50, 80, 100 %)")
    a.set(xlabel="t [s]", ylabel="base height [m]", title=f"{height.shape[0]} pushed drops")
    a.legend(fontsize=8)
    b.hist(100 * (forces.ravel() / (weight / 4) - 1), bins=40, color="C1")
    b.set(xlabel="final normal force against a quarter of the weight [%]", ylabel="feet",
          title="load per foot at t = 3 s")
    return save_figure(fig, path)


def main(out_dir=None, batch=1024, seed=0) -> dict:
    start = time.perf_counter()
    robot = jaxskid.load(erd_urdf("solo_description/robots/solo12.urdf"), floating_base=True)
    dyn = jaxskid.lower(robot, ["forward_dynamics", "kinetic_energy", "potential_energy", *NEEDED])
    weight = 9.81 * sum(v for k, v in robot.default_params().items() if k.endswith("_m"))

    def stand(t, x):
        q, v = x[:robot.nq], x[robot.nq:]
        return jnp.concatenate([jnp.zeros(6), KP * (STAND - q[7:]) - KD * v[6:]])

    contact = jaxskid.GroundContact(dyn, inner=stand)  # the four feet: the URDF's leaf links
    x0 = initial_states(robot, batch, np.random.default_rng(seed))
    steps = int(round(SECONDS / DT))
    compiled = time.perf_counter()
    traj = jaxskid.rollout(dyn, x0, contact, DT, steps, saveat=jaxskid.SaveAt(every=20))
    x = np.asarray(traj.x)
    elapsed = time.perf_counter() - compiled
    qf, vf = x[:, -1, :robot.nq], x[:, -1, robot.nq:]
    forces = np.asarray(jax.vmap(lambda q, v: contact.forces(q, v)[1][:, 2])(qf, vf))
    settled = (np.abs(forces.sum(axis=1) - weight) <= 0.01 * weight) & (np.abs(vf).max(axis=1) <= 1e-2)
    settled &= (forces > 0).all(axis=1)
    quat = np.abs(np.linalg.norm(x[..., 3:7], axis=-1) - 1).max()
    energy, touching = mechanical_energy(dyn, robot, contact, x)
    rise = np.where(touching[:, :-1], np.diff(energy, axis=1), -np.inf).max() / (weight * 0.1)
    figure = plot(output_dir(out_dir) / "quadruped_drop.png", np.asarray(traj.t), x[..., 2], forces, weight)
    print(f"solo12 with a floating base: nq {robot.nq}, nv {robot.nv}, feet {', '.join(dyn.end_effectors)}")
    print(f"{batch} pushed drops, {steps} RK4 steps of {DT * 1e3:.1f} ms: {elapsed:.1f} s "
          f"({elapsed / (batch * steps) * 1e6:.2f} us per rollout-step, compile included)")
    print(f"settled standing (normal forces = weight within 1 %, speeds < 0.01): {settled.sum()} of {batch}")
    print(f"final base height {np.median(qf[:, 2]):.4f} m (spread {np.ptp(qf[:, 2]) * 1e3:.2f} mm); "
          f"max | |quat| - 1 | {quat:.1e}")
    print(f"largest rise of the mechanical energy after touchdown: {rise:.1e} of weight x 10 cm")
    print(f"done in {time.perf_counter() - start:.1f} s; figure {figure}")
    return {"settled": int(settled.sum()), "batch": batch, "quaternion_error": float(quat),
            "load_error": float(np.abs(forces.sum(axis=1) / weight - 1).max()),
            "height_spread": float(np.ptp(qf[:, 2])), "energy_rise": float(rise), "seconds": elapsed,
            "figure": figure}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
