"""Learn a UR5's PD gains by gradient descent through a 2 s rollout, written the natural way.

    python examples/learn_gains.py [OUT_DIR]           # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

The policy is a closure: it captures the gains being learnt (traced by ``jax.grad``) and reads the initial
state and the reference from this module. It tracks a reference from a displaced start with PD plus gravity
compensation computed from the model's parameters; the loss is the mean squared tracking error over the
rollout (RK4, 1 ms steps) plus a small torque penalty. optax's Adam updates the logarithms of the gains
(so they stay positive) with gradients from ``jaxskid.jit(jax.grad(loss))``. The script checks the first
gradient against central differences and reports the loss before and after.
"""

from __future__ import annotations

import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402
from _common import erd_urdf, output_dir  # noqa: E402  (examples/_common.py, beside this script)

DT, SECONDS = 1e-3, 2.0
STEPS = int(round(SECONDS / DT))
X0 = jnp.concatenate([jnp.asarray([0.3, -1.2, 1.0, -0.5, 0.4, 0.2]), jnp.zeros(6)])  # displaced, at rest


def reference(t):
    """The joint positions to track: a slow sine about a home pose."""
    home = jnp.asarray([0.0, -1.0, 1.2, -0.6, 0.5, 0.0])
    return home + 0.2 * jnp.sin(2.0 * t) * jnp.asarray([1.0, 0.5, -0.5, 1.0, 0.5, 1.0])


def make_loss(dyn):
    n = dyn.n_dof

    def loss(log_gains):
        kp, kd = jnp.exp(log_gains[:n]), jnp.exp(log_gains[n:])

        def policy(t, x):  # closes over kp, kd (traced) and the module's reference
            q, qd = x[:n], x[n:]
            qr, vr, _ = jaxskid.reference_derivatives(reference, t)
            return kp * (qr - q) + kd * (vr - qd) + dyn.gravity_torques(q)

        traj = jaxskid.rollout(dyn, X0, policy, DT, STEPS)
        error = traj.q - jax.vmap(reference)(traj.t)[..., :n]
        return jnp.mean(error**2) + 1e-7 * jnp.mean(traj.tau**2)

    return loss


def main(out_dir=None, iterations=40):
    start = time.perf_counter()
    ur5 = jaxskid.load(erd_urdf("ur_description/urdf/ur5_robot.urdf"))
    dyn = jaxskid.lower(ur5, ["forward_dynamics", "gravity_torques"])
    n = dyn.n_dof
    loss = make_loss(dyn)
    value_and_grad = jaxskid.jit(jax.value_and_grad(loss))

    log_gains = jnp.concatenate([jnp.full(n, np.log(20.0)), jnp.full(n, np.log(2.0))])
    first_loss, first_grad = value_and_grad(log_gains)
    # the first gradient against central differences along a random direction
    direction = jnp.asarray(np.random.default_rng(0).standard_normal(2 * n))
    h = 1e-5
    central = (loss(log_gains + h * direction) - loss(log_gains - h * direction)) / (2 * h)
    gradient_error = abs(float(first_grad @ direction) - float(central)) / abs(float(central))

    optimizer = optax.adam(0.1)
    state = optimizer.init(log_gains)
    losses = [float(first_loss)]
    for _ in range(iterations):
        value, grad = value_and_grad(log_gains)
        updates, state = optimizer.update(grad, state)
        log_gains = optax.apply_updates(log_gains, updates)
        losses.append(float(value))
    losses[-1] = float(loss(log_gains))
    kp, kd = np.exp(np.asarray(log_gains[:n])), np.exp(np.asarray(log_gains[n:]))
    out_path = output_dir(out_dir) / "learned_gains.npz"
    np.savez(out_path, kp=kp, kd=kd, losses=np.asarray(losses))
    return {"losses": losses, "gradient_error": gradient_error, "kp": kp, "kd": kd, "file": out_path,
            "seconds": time.perf_counter() - start}


if __name__ == "__main__":
    out = main(sys.argv[1] if len(sys.argv) > 1 else None)
    print(f"loss {out['losses'][0]:.3e} -> {out['losses'][-1]:.3e} in {len(out['losses']) - 1} Adam steps "
          f"({out['seconds']:.1f} s); first gradient against central differences: {out['gradient_error']:.1e}")
    print("kp", np.array2string(out["kp"], precision=1), "kd", np.array2string(out["kd"], precision=2))
    print("saved", out["file"])
