"""Slotine-Li adaptive tracking on the planar 2R arm: the tracking error and the parameter errors vanish.

    python examples/adaptive_2r.py [OUT_DIR]           # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

The controller starts knowing nothing about the arm's inertia (estimates zero) and adapts the arm's six
base parameters online, with the update law d pi_hat/dt = -gamma Y^T s built on the regressor. The
Lyapunov function V = 1/2 s^T M s + 1/2 (pi_hat - pi)^T gamma^-1 (pi_hat - pi), evaluated with the true
model, must never increase; the example reports its largest increase along the simulation.
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

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "arm_2r.yaml"


def reference(t):
    """A persistently exciting reference: two incommensurate sines per joint."""
    return jnp.stack([0.8 * jnp.sin(1.1 * t) + 0.5 * jnp.sin(2.9 * t), 1.0 * jnp.cos(1.7 * t) + 0.4 * jnp.sin(3.7 * t)])


def main(out_dir=None, seconds=40.0, dt=2e-3):
    start = time.perf_counter()
    robot = jaxskid.load(ROBOT)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "regressor"])
    base = jaxskid.base_parameters(dyn, names=jaxskid.standard_parameter_names(robot))
    truth = base.project(jaxskid.standard_params(robot))

    # adaptation gains balanced by the regressor's column sizes along the reference
    ts = jnp.linspace(0.0, 20.0, 501)
    q, v, a = jax.vmap(lambda t: jaxskid.reference_derivatives(reference, t))(ts)
    y = np.asarray(base.reduce(dyn.regressor(q, v, a)))
    kd, lam = 20.0, 10.0
    gamma = kd / np.mean(np.sum(y * y, axis=1), axis=0)
    controller = jaxskid.SlotineLi(dyn, reference, jnp.zeros(base.n_base), lam=lam, kd=kd, gamma=gamma, base=base)

    steps = int(round(seconds / dt))
    x0 = jnp.concatenate([reference(0.0) + 0.2, jnp.zeros(2)])
    traj = jaxskid.rollout(dyn, x0, controller, dt, steps)
    t = np.asarray(traj.t)
    error = np.abs(np.asarray(traj.q) - np.asarray(jax.vmap(reference)(traj.t))).max(axis=1)
    estimates = np.asarray(traj.z)

    def lyapunov(t, x, z):
        _, s = controller.regressor(t, x)
        return 0.5 * s @ dyn.mass_matrix(x[:2]) @ s + 0.5 * jnp.sum((z - truth) ** 2 / gamma)

    lyap = np.asarray(jax.vmap(lyapunov)(traj.t, traj.x, traj.z))
    per_5s = error[:-1].reshape(-1, int(round(5.0 / dt))).max(axis=1)
    elapsed = time.perf_counter() - start

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    axes[0].semilogy(t, error, label="max |q - q_d| [rad]")
    axes[0].semilogy(t, lyap, label="Lyapunov function V")
    axes[0].set(xlabel="t [s]", title="Slotine-Li on the 2R arm, estimates start at zero")
    axes[0].legend()
    labels = base.describe(3)
    for k in range(base.n_base):
        axes[1].plot(t, estimates[:, k], color=f"C{k}", label=labels[k])
        axes[1].axhline(truth[k], color=f"C{k}", ls="--", lw=0.8)
    axes[1].set(xlabel="t [s]", ylabel="estimate", title="base parameters (dashed: true values)")
    axes[1].legend(fontsize=7)
    figure = save_figure(fig, output_dir(out_dir) / "adaptive_2r.png")

    result = {
        "error_per_5s": per_5s,
        "final_error": float(per_5s[-1]),
        "parameter_error": np.abs(estimates[-1] - truth),
        "lyapunov_max_increase": float(np.diff(lyap).max()),
        "lyapunov_start": float(lyap[0]),
        "seconds": elapsed,
        "figure": figure,
    }
    print(f"{base.n_base} base parameters: {', '.join(labels)}")
    print(f"max tracking error per 5 s window [rad]: {np.array2string(per_5s, precision=2)}")
    print(f"final parameter errors: {np.array2string(result['parameter_error'], precision=4)} "
          f"(true values {np.array2string(truth, precision=3)})")
    print(f"Lyapunov function: {lyap[0]:.3g} -> {lyap[-1]:.3g}, largest step increase {result['lyapunov_max_increase']:.1e}")
    print(f"done in {elapsed:.1f} s; figure {figure}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
